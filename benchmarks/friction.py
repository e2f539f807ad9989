"""Speed against accuracy where friction dominates (issue 13): the 3D lap joint of
demos/lap3d_friction.toml (25 pairs at 1 MPa: they slip widely and never open), every ROM against
the exact condensation in one run, and the energy dissipated per cycle against the forcing.

    .venv/bin/python benchmarks/friction.py --out docs/benchmarks_friction.md   (make bench-friction)

1. FRF at the scene's 3 N: `analysis.compare` with the exact condensation as reference (swept
   with ds_max = 0.03 so that its polyline is dense), online times the median of ``--repeats``
   sweeps.  The trade: the penalty ROM's online time over each Craig-Bampton ROM's whose curve
   error is not smaller than the penalty ROM's.
2. Energy per cycle against force: continuation in the force scale (analysis.force) at the
   reference's located 3 N peak frequency, stretch by stretch from 0.01 to 10 times the scene's
   force (each its own branch, so that the points spread evenly on a log axis), with the
   penalty ROM and the exact condensation; a log-log picture.
"""
from __future__ import annotations

import argparse
import datetime
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "demos" / "lap3d_friction.toml"
OUTPUT = "a_mid.uy"
METHODS = ["penalty:10:3", "penalty:10", "cb:10", "cb:20"]
PENALTY = "penalty:10+3tvd"
DECADES = [(0.01, 0.1), (0.1, 0.3), (0.3, 1.0), (1.0, 3.0), (3.0, 10.0)]  # force scales, a branch each


def solved_curve_error(frf, problem, ref) -> float:
    """The largest |A_rom - A_ref| at the ROM's points over the reference's peak amplitude, with
    A_ref solved by the reference ``problem`` at each of the ROM's omegas (Newton from the
    reference branch interpolated there; the branch must be a graph over omega), so that no chord
    of the reference's polyline enters the error."""
    from jointfem.analysis.peaks import output_amplitude
    from jointfem.continuation.arclength import NewtonOptions, solve_newton
    from jointfem.hbm.problem import newton_system

    w, U = ref.omega, ref.U
    if np.any(np.diff(w) <= 0):
        raise ValueError("the reference branch folds: solved curve errors need a graph over omega")
    peak = ref.amplitude(ref.outputs[OUTPUT]).max()
    amp = frf.amplitude(frf.outputs[OUTPUT])
    sc = problem.scales(w[0], w[-1])
    opts = NewtonOptions(tol=max(1e-10, problem.tol_floor))
    err = 0.0
    for wi, ai in zip(frf.omega, amp):
        if not w[0] <= wi <= w[-1]:
            continue
        k = min(int(np.searchsorted(w, wi)), w.size - 1)
        t = 0.0 if k == 0 else (wi - w[k - 1]) / (w[k] - w[k - 1])
        guess = U[k] if k == 0 else (1 - t) * U[k - 1] + t * U[k]
        x, _ = solve_newton(newton_system(problem), guess, float(wi), x_scale=sc.x, r_scale=sc.r, options=opts,
                            select=problem.unknowns())
        err = max(err, abs(ai - output_amplitude(x, ref.outputs[OUTPUT], problem.harmonics)) / peak)
    return err


def energy_branch(model, omega, harmonics, force):
    """(force N, energy J summed over the pairs, slip share) along decades of the force scale."""
    from jointfem.analysis.force import compute_force_response
    from jointfem.contact.jenkins import SLIP
    from jointfem.continuation.arclength import ContinuationOptions

    F, E, slip, t = [], [], [], time.perf_counter()
    for a, b in DECADES:
        r = compute_force_response(model, omega, harmonics, a, b, ContinuationOptions(ds_max=0.05, time_limit=900))
        F.append(r.scale * force)
        E.append(r.info["arrays"]["pair_energy_J"].sum(axis=1))
        slip.append((r.states == SLIP).mean(axis=(1, 2)))
    return np.concatenate(F), np.concatenate(E), np.concatenate(slip), time.perf_counter() - t


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "benchmarks_friction.md"))
    ap.add_argument("--repeats", type=int, default=3, help="sweeps per ROM for its online time (median)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    img = out.parent / "img"
    img.mkdir(parents=True, exist_ok=True)
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from bench import machine

    from jointfem.analysis.compare import chord_error_estimate, compare, parse_method, to_markdown
    from jointfem.app import sweep_options
    from jointfem.contact.jenkins import SEPARATED, SLIP
    from jointfem.plots import plot_compare, pyplot
    from jointfem.rom import RomOptions, build_rom
    from jointfem.scene import create_structure, load_scene

    t0 = time.perf_counter()
    scene = load_scene(SCENE)
    structure = create_structure(scene)
    sweep = sweep_options(scene, stability="off")
    specs = [parse_method(m, RomOptions()) for m in METHODS]
    results = compare(structure, specs, sweep, output=OUTPUT, reference="exact", repeats=args.repeats,
                      reference_ds_max=0.03, progress=lambda m: print(f"friction: {m}", flush=True))
    plot_compare(results, OUTPUT, img / "compare_frf_lap3d_friction.png", img / "pareto_lap3d_friction.png",
                 title="3D lap joint, friction-dominated (1 MPa, 3 N): error against online time")
    ref = results[0]
    by = {r.spec.label: r for r in results}
    pen = by[PENALTY]
    from jointfem.analysis.frf import create_problem
    exact = create_problem(build_rom(structure, "exact"), sweep.harmonics)
    solved = {}
    for r in results[1:]:
        if not r.failure:
            print(f"friction: solved curve error of {r.spec.label}", flush=True)
            solved[r.spec.label] = 100.0 * solved_curve_error(r.frf, exact, ref.frf)
    trade = []
    for r in results[1:]:
        if r.spec.method != "cb" or r.failure or pen.failure:
            continue
        trade.append((r.spec.label, pen.online_s / r.online_s, solved[PENALTY] <= solved[r.spec.label],
                      abs(pen.peak_amp_err_pct) <= abs(r.peak_amp_err_pct)))
    st = ref.frf.states
    shares = ((st == SLIP).mean(axis=(1, 2)).max(), (st == SEPARATED).mean(axis=(1, 2)).max())

    # energy against force at the reference's 3 N resonance
    omega = float(ref.frf.info["peaks"][OUTPUT].omega)
    h = sweep.harmonics
    force = float(scene.data["force"]["amplitude"])
    curves = {}
    for label, model in (("exact", build_rom(structure, "exact")),
                         (PENALTY, build_rom(structure, "penalty", RomOptions(modes=10, tvd=3)))):
        print(f"friction: energy against force, {label}", flush=True)
        curves[label] = energy_branch(model, omega, h, force)
    Fe, Ee, Se, te = curves["exact"]
    Fp, Ep, Sp, tp = curves[PENALTY]
    big = Ee > 1e-6 * Ee.max()  # where friction dissipates (below: stuck, round-off)
    pos = Ep > 1e-9 * Ee.max()
    Ep_at = np.exp(np.interp(np.log(Fe[big]), np.log(Fp[pos]), np.log(Ep[pos])))
    e_rel = np.abs(Ep_at / Ee[big] - 1)
    e_err = float(e_rel.max())
    e_err_main = float(e_rel[Ee[big] > 1e-3 * Ee.max()].max())  # where the dissipation matters
    growth = float(Ee.max() / Ee[big].min())
    plt = pyplot()
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7.0, 6.0), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    # below 1e-9 of the largest energy every pair sticks and the value is round-off (|E| ~ 1e-24 J)
    floor = 1e-9 * Ee.max()
    ax.loglog(Fe[Ee > floor], Ee[Ee > floor], "k-", lw=2.2, label="exact condensation")
    ax.loglog(Fp[Ep > floor], Ep[Ep > floor], "o", ms=3, color="C1", label=f"{PENALTY}")
    stuck = Fe[(Ee <= floor)]
    if stuck.size:
        ax.axvspan(Fe.min(), stuck.max(), color="0.9", zorder=0, label="every pair stuck (no dissipation)")
    ax.set_ylabel("energy dissipated per cycle [J]")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(f"3D lap joint, 25 pairs at 1 MPa, omega = {omega:.2f} rad/s ({omega / (2 * np.pi):.2f} Hz)")
    ax2.semilogx(Fe, Se, "k-", lw=2.2)
    ax2.semilogx(Fp, Sp, "o", ms=3, color="C1")
    ax2.set_ylabel("slip share")
    ax2.set_xlabel("force amplitude [N]")
    ax2.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(img / "friction_energy_lap3d.png", dpi=120)
    plt.close(fig)

    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    m = machine()
    minutes = (time.perf_counter() - t0) / 60
    lines = [
        "# Speed against accuracy where friction dominates",
        "",
        f"Regenerated by `make bench-friction` (`python benchmarks/friction.py`) on "
        f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC at commit {commit}, "
        f"{minutes:.0f} min on {m.get('cores')} cores ({platform.processor() or platform.machine()}), nothing else "
        "running.  Online times are medians of "
        f"{args.repeats} sweeps in one process after a warm-up; ratios are taken within this run.",
        "",
        f"Scene: demos/lap3d_friction.toml: the lap joint of demos/lap3d.toml with stiff contact (kt = kn = "
        f"2e11 N/m^3) and a 1 MPa preload on the 15 mm mesh: {structure.num_dofs} DOFs, {structure.num_pairs} pairs, "
        f"H = {h.H}, N = {h.N}, {force:g} N at the middle of bar A.  On the reference branch the largest share of "
        f"pair-samples slipping is {shares[0]:.2f} and separated {shares[1]:.2f}: friction, not clapping.",
        "",
        "## FRF: every ROM against the exact condensation",
        "",
        to_markdown(results),
        f"The reference is swept with ds_max = 0.03 (the ROMs with the scene's "
        f"{sweep.continuation.ds_max}); its chord error is about "
        f"{100 * chord_error_estimate(ref.frf, OUTPUT):.3f} % of the peak, so the table's curve errors (distance "
        "from the reference's polyline) below that are not resolved.  The **solved curve error** is free of "
        "chords: at every point of a ROM, the exact condensation is solved at the same omega (Newton from its "
        "branch), and the largest amplitude difference taken, in % of the reference peak.  Sizes count the "
        "unknowns per harmonic coefficient Newton solves (the penalty ROM's grows and shrinks with its active "
        "set).",
        "",
        "| method | solved curve error % | peak amp err % | online s |",
        "|---|---|---|---|",
        *[f"| {r.spec.label} | {solved[r.spec.label]:.4f} | {r.peak_amp_err_pct:+.4f} | {r.online_s:.2f} |"
          for r in results[1:] if not r.failure],
        "",
        "![FRFs](img/compare_frf_lap3d_friction.png)",
        "![Pareto](img/pareto_lap3d_friction.png)",
        "",
        f"**The trade** ({PENALTY}'s online time over each Craig-Bampton ROM's, and whether its errors are not "
        "larger):",
        "",
        "| against | time ratio | solved curve error not larger | peak amplitude error not larger |",
        "|---|---|---|---|",
    ]
    for label, ratio, ce, pe in trade:
        lines.append(f"| {label} | {ratio:.3f} | {'yes' if ce else 'no'} | {'yes' if pe else 'no'} |")
    lines += [
        "",
        "## Energy dissipated per cycle against the forcing",
        "",
        f"At the reference's located 3 N peak, omega = {omega:.4f} rad/s, continuation in the force scale from "
        f"0.01 to 10 times {force:g} N, one branch per stretch (scales {', '.join(f'{a:g}' for a, _ in DECADES)} to 10).  The dissipation grows by a factor of "
        f"{growth:.3g} from the first force where it exceeds 1e-6 of its largest value to the largest force "
        f"(microslip to macroslip: the slip share goes from {Se[big].min():.3f} to {Se.max():.3f}).  "
        f"{PENALTY} against the exact condensation, interpolated in log-log at the reference's forces: the "
        f"largest relative difference in energy is {e_err:.2e} over every force where it exceeds 1e-6 of its "
        f"largest value, {e_err_main:.2e} where it exceeds 1e-3 of it.  Time: exact {te:.0f} s, "
        f"penalty {tp:.1f} s.",
        "",
        "![energy against force](img/friction_energy_lap3d.png)",
        "",
    ]
    out.write_text("\n".join(lines))
    print(out.read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
