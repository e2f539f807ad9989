"""Jointed beam (paper Sec. 5) near its second bending mode, three forcing levels, converged in H.

    python demos/jointed_beam_levels.py [--out DIR] [--coarse] [--scene TOML]

Runs demos/beam2d_friction.toml (the paper's beam with kt = 1e6 N/m per pair, so that friction
matters before the joint opens) at forcing levels set from the stuck linear model:
F_slip is the force above which the worst pair cannot stay stuck in steady state (slip_force), and
F_sep the force at which its normal load first reaches zero, both on the stuck linear FRF over
the scene's range.  The joint
1. sticks everywhere at 0.5 F_slip,
2. sticks and slips, without opening, at 2 F_slip (which must stay below F_sep),
3. opens (separation) at 1.6 F_sep (friction damping keeps it shut at 1.4 F_sep).
and checks itself: the stuck level must equal the stuck linear FRF, the stick-slip
level must slip for at least 5 % of the pair-time and never separate, and the separating level
must separate.  (On the paper's own beam, kt = 1e4 N/m, F_slip = F_sep = 2.347 N: it can slip in
steady state only where the normal load reaches zero, so it has no stick-slip level; the script
then stops with that message, `--scene demos/beam2d.toml`.)
Each level is solved converged (CONVERGED: H chosen along the branch to 0.5 % of the amplitude, the
exact condensation, the event-accurate AFT, every point's stability), as `make demo` runs it.
Writes one result folder per level (frf.csv, branch.npz, summary.json, frf.png),
levels.png (receptance of b1.mid.uy for the three levels) and levels.json.
``--coarse`` uses the scene as it is at H = 3 and N = 256 (what the test runs: its answer is not
converged, and its pictures say so).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from jointfem.app import override, solve_scene
from jointfem.contact.jenkins import SEPARATED, SLIP
from jointfem.plots import plot_frf, plot_levels
from jointfem.results import save_frf
from jointfem.scene import create_structure, load_scene

HERE = Path(__file__).resolve().parent
LEVELS = (("stuck", 0.5, "F_slip"), ("stick-slip", 2.0, "F_slip"), ("separation", 1.6, "F_sep"))
MIN_SLIP_SHARE = 0.05  # of the pair-time, at the stick-slip level's most slipping point


def _unit_gaps(scene, num_omega=2001):
    """The contact group and its complex gap amplitudes per N of force, (P, m, num_omega), on the
    stuck linear FRF over the scene's range."""
    unit = create_structure(dataclasses.replace(scene, model=dataclasses.replace(scene.model, force=1.0)))
    g = unit.contacts[0]
    w = np.linspace(scene.solver.omega_min, scene.solver.omega_max, num_omega)
    return g.pairs, (g.gap @ unit.linear_response(w).T).reshape(g.pairs.num_pairs, g.pairs.num_comp, w.size)


def separation_force(scene) -> float:
    """Force (N) at which the first pair's normal load reaches zero on the stuck linear FRF."""
    pairs, gaps = _unit_gaps(scene)
    swing = np.abs(gaps[:, -1, :]) * pairs.kn[:, None]  # normal load amplitude per N of force
    return float(np.min(pairs.N0 / swing.max(axis=1)))


def slip_force(scene, num_tau=512) -> float:
    """Force (N) above which the first pair cannot stay stuck in steady state, on the stuck linear
    FRF (min over omega and pairs).

    Stuck all period needs one slider position w with |kt (g_t(t) - w)| <= mu N(t) at every t,
    N = N0 + kn g_n: a Jenkins slider that slips in its transient shakes down to any such w (the
    AFT's steady state does).  With T = F kt g_t and L = mu (N0 + F kn g_n) per N of force F, that
    is max_t (T - L) <= min_t (T + L), so F_slip = 2 mu N0 / (max_t a - min_t b) with
    a = kt g_t - mu kn g_n and b = kt g_t + mu kn g_n (where positive).  It is above the force at
    which |kt g_t| first reaches mu N from w = 0 whenever N varies."""
    pairs, gaps = _unit_gaps(scene)
    tau = np.linspace(0.0, 2 * np.pi, num_tau, endpoint=False)
    g_t = np.real(gaps[:, 0, :, None] * np.exp(1j * tau))  # (P, omega, tau) per N
    g_n = np.real(gaps[:, -1, :, None] * np.exp(1j * tau))
    kt, kn, mu = (v[:, None, None] for v in (pairs.kt, pairs.kn, pairs.mu))
    spread = (kt * g_t - mu * kn * g_n).max(axis=2) - (kt * g_t + mu * kn * g_n).min(axis=2)  # (P, omega)
    pos = spread > 0
    return float(np.min(2 * (pairs.mu * pairs.N0)[:, None] / np.where(pos, spread, 1.0), where=pos,
                        initial=np.inf))


# The converged answer (as demos/beam2d_converged.toml): H chosen along each branch until every point
# solved at H + 2 lies within 0.5 % of the largest amplitude or 0.05 % of omega, on the exact
# condensation (the full model's equations condensed on the joint's gaps) with the event-accurate
# AFT, and every point's stability.  At the scene's fixed H = 5 the separating level's loop and
# peak are truncation artefacts that more harmonics move (docs/theory.md).
CONVERGED = ['solver.harmonics="auto"', "solver.harmonics_max=41", "solver.samples=1024", 'solver.aft="events"',
             'solver.stability="on"', 'reduction.method="exact"']


def run(out: Path, *, coarse: bool = False, progress: bool = True, scene: Path = HERE / "beam2d_friction.toml") -> dict:
    base = load_scene(scene)
    if coarse:  # the scene at H = 3, N = 256 (what the test runs)
        base = dataclasses.replace(
            base,
            solver=dataclasses.replace(base.solver, harmonics=3, samples=256))
    else:
        base = override(base, CONVERGED)
    thresholds = {"F_slip": slip_force(base), "F_sep": separation_force(base)}
    if LEVELS[1][1] * thresholds["F_slip"] >= thresholds["F_sep"]:
        raise SystemExit(f"{scene}: F_slip = {thresholds['F_slip']:.4g} N and F_sep = {thresholds['F_sep']:.4g} N: "
                         f"the joint opens before it slips at {LEVELS[1][1]:g} F_slip, so this scene has no "
                         "stick-slip level (raise kt or N0)")
    report, curves = {"F_slip_N": thresholds["F_slip"], "F_sep_N": thresholds["F_sep"]}, []
    for label, factor, basis in LEVELS:
        force = factor * thresholds[basis]
        scene = dataclasses.replace(base, name=f"beam2d_{label}",
                                    model=dataclasses.replace(base.model, force=force))
        sol = solve_scene(scene, progress=progress)
        structure, frf = sol.structure, sol.frf
        folder = out / label.replace("-", "_")
        summary = save_frf(frf, folder, summary={"scene": str(scene.path), "level": label, "force_N": force,
                                                 "method": scene.reduction.method, "num_dofs": structure.num_dofs})
        plot_frf(frf, folder / "frf.png", title=f"jointed beam, {label}, F = {force:.4g} N")
        dof = structure.outputs["b1.mid.uy"]
        lin = np.abs(structure.linear_response(frf.omega)[:, dof])
        report[label] = {
            "force_N": force, "points": int(frf.num_points),
            "newton_iterations": int(frf.iterations.sum()),
            "peak_Hz": summary["peaks"]["b1.mid.uy"]["freq_Hz"],
            "peak_amp1_m": summary["peaks"]["b1.mid.uy"]["amp1_m"],
            "slip_share_max": float((frf.states == SLIP).mean(axis=(1, 2)).max()),
            "separated_share_max": float((frf.states == SEPARATED).mean(axis=(1, 2)).max()),
            "max_rel_diff_to_stuck_linear": float(np.max(np.abs(frf.amplitude(frf.outputs["b1.mid.uy"]) - lin) / lin)),
            "wall_s": frf.info["time_online_s"],
            # what is known of the orbits drawn: the largest harmonic truncation estimate on the branch
            # (docs/theory.md), and the number of points found unstable (None: not computed, as
            # with --stability off)
            "harmonic_error_max": float(np.max(frf.info["arrays"]["harmonic_error"])),
            "unstable_points": None if frf.stable is None else int((~np.asarray(frf.stable)).sum()),
        }
        curves.append((f"{label}, F = {force:.3f} N", dataclasses.replace(frf, U=frf.U / force)))
    how = (f"H = {base.solver.harmonics}" if not base.solver.harmonics_auto else
           f"H chosen along each branch to {base.solver.amplitude_tol:.1%} of the amplitude")
    plot_levels(curves, "b1.mid.uy", out / "levels.png",
                title=f"jointed beam, 2nd bending mode\n{how}, {base.reduction.method}")
    (out / "levels.json").write_text(json.dumps(report, indent=2))
    # The demo checks itself.
    assert report["stuck"]["slip_share_max"] == 0 and report["stuck"]["separated_share_max"] == 0
    # (the outputs are unknowns solved to the Newton tolerance, 1e-10 of the residual's scale: the
    # exact condensation's stuck level is 1.9e-8 from the linear FRF, the full model's below 1e-8)
    assert report["stuck"]["max_rel_diff_to_stuck_linear"] < 1e-7
    assert report["stick-slip"]["slip_share_max"] > MIN_SLIP_SHARE and report["stick-slip"]["separated_share_max"] == 0
    assert report["separation"]["separated_share_max"] > 0
    return report


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/beam2d_levels")
    ap.add_argument("--coarse", action="store_true")
    ap.add_argument("--scene", type=Path, default=HERE / "beam2d_friction.toml")
    args = ap.parse_args(argv)
    report = run(Path(args.out), coarse=args.coarse, scene=args.scene)
    for label, r in report.items():
        if label.endswith("_N"):
            print(f"{label[:-2]} = {r:.4f} N")
            continue
        print(f"{label:>11}: F = {r['force_N']:.4f} N, peak {r['peak_amp1_m']:.4e} m at {r['peak_Hz']:.3f} Hz, "
              f"slip share {r['slip_share_max']:.3f}, separated share {r['separated_share_max']:.3f}, "
              f"truncation estimate <= {r['harmonic_error_max']:.3f}, "
              f"{r['points']} points ({'stability not computed' if r['unstable_points'] is None else str(r['unstable_points']) + ' unstable'}), "
              f"{r['wall_s']:.1f} s")
    print(f"wrote {args.out}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
