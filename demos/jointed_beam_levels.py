"""Jointed beam (paper Sec. 5) at full order near its second bending mode, three forcing levels.

    python demos/jointed_beam_levels.py [--out DIR] [--coarse]

Runs demos/beam2d.toml at forcing levels set from the stuck linear model: F_sep is the force
at which the normal load of the worst pair first reaches zero at the stuck resonance.  The joint
1. sticks everywhere at 0.4 F_sep,
2. sticks and slips, without opening, at 0.98 F_sep (the friction limit mu N(t) falls below the
   small tangential force, about 1 % of the normal load swing, just before N reaches zero),
3. opens (separation) at 1.3 F_sep.
and checks itself: the stuck level must equal the stuck linear FRF, the stick-slip
level must slip and never separate, and the separating level must separate.
Writes one result folder per level (frf.csv, branch.npz, summary.json, frf.png),
levels.png (receptance of b1.mid.uy for the three levels) and levels.json.
``--coarse`` uses H = 3 and N = 256 (what the test runs).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

from jointfem.app import solve_scene
from jointfem.contact.jenkins import SEPARATED, SLIP
from jointfem.plots import plot_frf, plot_levels
from jointfem.results import save_frf
from jointfem.scene import create_structure, load_scene

HERE = Path(__file__).resolve().parent
LEVELS = (("stuck", 0.4), ("stick-slip", 0.98), ("separation", 1.3))  # x F_sep


def separation_force(scene) -> float:
    """Force (N) at which the first pair's normal load reaches zero on the stuck linear FRF."""
    unit = create_structure(dataclasses.replace(scene, model=dataclasses.replace(scene.model, force=1.0)))
    g = unit.contacts[0]
    w = np.linspace(scene.solver.omega_min, scene.solver.omega_max, 2001)
    gaps = (g.gap @ unit.linear_response(w).T).reshape(g.pairs.num_pairs, g.pairs.num_comp, w.size)
    swing = np.abs(gaps[:, -1, :]) * g.pairs.kn[:, None]  # normal load amplitude per N of force
    return float(np.min(g.pairs.N0 / swing.max(axis=1)))


def run(out: Path, *, coarse: bool = False, progress: bool = True) -> dict:
    base = load_scene(HERE / "beam2d.toml")
    if coarse:
        base = dataclasses.replace(
            base,
            solver=dataclasses.replace(base.solver, harmonics=3, samples=256))
    f_sep = separation_force(base)
    report, curves = {"F_sep_N": f_sep}, []
    for label, factor in LEVELS:
        force = factor * f_sep
        scene = dataclasses.replace(base, name=f"beam2d_{label}",
                                    model=dataclasses.replace(base.model, force=force))
        sol = solve_scene(scene, progress=progress)
        structure, frf = sol.structure, sol.frf
        folder = out / label.replace("-", "_")
        summary = save_frf(frf, folder, summary={"scene": str(scene.path), "level": label, "force_N": force,
                                                 "method": "full", "num_dofs": structure.num_dofs})
        plot_frf(frf, folder / "frf.png", title=f"jointed beam, {label}, F = {force} N")
        dof = structure.outputs["b1.mid.uy"]
        lin = np.abs(structure.linear_response(frf.omega)[:, dof])
        report[label] = {
            "force_N": force, "points": int(frf.num_points),
            "newton_iterations": int(frf.iterations.sum()),
            "peak_Hz": summary["peaks"]["b1.mid.uy"]["freq_Hz"],
            "peak_amp1_m": summary["peaks"]["b1.mid.uy"]["amp1_m"],
            "slip_share_max": float((frf.states == SLIP).mean(axis=(1, 2)).max()),
            "separated_share_max": float((frf.states == SEPARATED).mean(axis=(1, 2)).max()),
            "max_rel_diff_to_stuck_linear": float(np.max(np.abs(frf.amplitude(dof) - lin) / lin)),
            "wall_s": frf.info["time_online_s"],
        }
        curves.append((f"{label}, F = {force:.3f} N", dataclasses.replace(frf, U=frf.U / force)))
    plot_levels(curves, "b1.mid.uy", out / "levels.png", title="jointed beam, full order, 2nd bending mode")
    (out / "levels.json").write_text(json.dumps(report, indent=2))
    # The demo checks itself.
    assert report["stuck"]["slip_share_max"] == 0 and report["stuck"]["separated_share_max"] == 0
    assert report["stuck"]["max_rel_diff_to_stuck_linear"] < 1e-8
    assert report["stick-slip"]["slip_share_max"] > 0 and report["stick-slip"]["separated_share_max"] == 0
    assert report["separation"]["separated_share_max"] > 0
    return report


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results/beam2d_levels")
    ap.add_argument("--coarse", action="store_true")
    args = ap.parse_args(argv)
    report = run(Path(args.out), coarse=args.coarse)
    for label, r in report.items():
        if label == "F_sep_N":
            print(f"F_sep = {r:.4f} N")
            continue
        print(f"{label:>11}: F = {r['force_N']:.4f} N, peak {r['peak_amp1_m']:.4e} m at {r['peak_Hz']:.3f} Hz, "
              f"slip share {r['slip_share_max']:.3f}, separated share {r['separated_share_max']:.3f}, "
              f"{r['points']} points, {r['wall_s']:.1f} s")
    print(f"wrote {args.out}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
