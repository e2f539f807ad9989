"""The paper's beam at 3 N (strong separation) against the number of harmonics (issue 14): the
located peak, the harmonic truncation estimate and the cost of each sweep, up to convergence.

Every sweep solves the exact harmonic condensation on the joint's gaps (--method exact: the full
model's solution, 8 coordinates per harmonic instead of 120) with the event-accurate AFT
([solver] aft = "events": the Jenkins law integrated in continuous time, no sampling kinks).
Two cross-checks are in the same run: full order with the same law at one H (the condensation is
exact, so the peaks agree to the Newton tolerance), and the highest H with twice the samples.

    .venv/bin/python benchmarks/harmonics.py --out docs/benchmarks_harmonics.md [--jobs 2]   (make bench-harmonics)

or only the time integration, on a sweep made apart with the top row's settings:

    jointfem frf demos/beam2d.toml --method exact --harmonics 41 --samples 1024 --set solver.aft='"events"' --out DIR
    .venv/bin/python benchmarks/harmonics.py --out docs/benchmarks_harmonics.md --timeint-from DIR

Each sweep runs in its own process (``--jobs`` at a time) with stability off, under a time budget.
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import multiprocessing as mp
import platform
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENE = "demos/beam2d.toml"
FORCE = 3.0  # N: the scene's own level (separation)
BUDGET = 900  # s per sweep
# (method, H, N, AFT law)
SERIES = [("exact", H, 1024, "events") for H in (3, 5, 7, 9, 11, 13, 15, 17, 21, 25, 31, 41)]
CHECKS = [("full", 9, 1024, "events"), ("exact", 41, 2048, "events"), ("exact", 11, 1024, "sampled")]
QUICK = [("exact", 5, 256, "events"), ("exact", 21, 256, "events")]
TOP = SERIES[-1]
# Newmark from rest at the top H's peak frequency (400 periods were not enough: the last still changed by 6e-5)
TIMEINT = dict(periods=1200, steps=(2000, 4000))


def scene_at(H: int, N: int, law: str):
    """The beam scene at H harmonics, N samples and the AFT ``law`` ("sampled" or "events")."""
    from jointfem.app import override_harmonics
    from jointfem.scene import load_scene
    sc = override_harmonics(load_scene(ROOT / SCENE), H, N)
    assert sc.data["force"]["amplitude"] == FORCE, sc.data["force"]
    return dataclasses.replace(sc, solver=dataclasses.replace(sc.solver, aft=law))


def timeint_check(omega_branch: np.ndarray, U: np.ndarray, omega: float, H: int, N: int) -> dict:
    """Where the top H's branch has several solutions at its peak frequency, which one is the
    steady state that time integration reaches from rest?  Every HBM solution at that omega is
    solved (Newton from each branch point within 0.2 rad/s, distinct to 1e-6), then the implicit
    Newmark integration of demos/beam_timeint_check.py (its own contact law, no shared code with
    the AFT) runs from rest for ``periods`` periods, and its last period's first harmonic is
    compared with each solution."""
    import sys
    sys.path.insert(0, str(ROOT / "demos"))
    from beam_timeint_check import integrate
    from jointfem.analysis.frf import solve_at
    from jointfem.harmonics import Harmonics
    from jointfem.rom.reductors import build_rom
    from jointfem.scene import create_structure
    st = create_structure(scene_at(H, N, "events"))
    ex = build_rom(st, "exact")
    sols = []
    for i in np.flatnonzero(np.abs(omega_branch - omega) < 0.2):
        a = solve_at(ex, omega, Harmonics(H, N), guess=U[i]).amplitudes["b1.mid.uy"]
        if all(abs(a / b - 1) > 1e-6 for b in sols):
            sols.append(a)
    out = {"omega_rad_s": omega, "hbm_solutions_m": sorted(sols), "timeint": []}
    dof, n = st.outputs["b1.mid.uy"], st.num_dofs
    for steps in TIMEINT["steps"]:
        t0 = time.perf_counter()
        y = integrate(st, np.zeros(3 * n), omega, np.zeros(st.contacts[0].pairs.num_pairs),
                      periods=TIMEINT["periods"], steps=steps, dof=dof)
        a1 = [float(abs(np.fft.rfft(part)[1]) * 2 / steps) for part in (y[:steps], y[steps:])]
        out["timeint"].append({"steps": steps, "first_harmonic_m": a1[1], "last_period_change": a1[1] / a1[0] - 1,
                               "s": time.perf_counter() - t0})
    return out


def run(case):
    method, H, N, law = case
    from jointfem.analysis.frf import compute_frf
    from jointfem.app import sweep_options
    from jointfem.continuation.arclength import ContinuationError
    from jointfem.rom.reductors import build_rom
    from jointfem.scene import create_structure
    sc = scene_at(H, N, law)
    opts = sweep_options(sc, stability="off", peak_share=0.0)
    opts = replace(opts, continuation=replace(opts.continuation, time_limit=BUDGET))
    st = create_structure(sc)
    model = st if method == "full" else build_rom(st, method)
    t0 = time.perf_counter()
    row = {"method": method, "H": H, "N": N, "law": law}
    try:
        frf = compute_frf(model, opts)
        name = "b1.mid.uy"
        w, a = frf.peak(name)
        he = frf.info["arrays"]["harmonic_error"]
        if case == TOP:  # its branch, for the time integration at its peak
            row["_branch"] = (frf.omega, frf.U)
        row.update(status="complete", points=frf.num_points, unknowns=frf.info["num_unknowns"],
                   residual_max=float(frf.info["arrays"]["residual"].max()), peak_m=a, peak_rad_s=w,
                   located=bool(frf.info["peaks"][name].located), trunc_max=float(he.max()),
                   trunc_at_peak=float(he[int(np.argmin(np.abs(frf.omega - w)))]),
                   omega_min=float(frf.omega.min()))
    except ContinuationError as exc:
        row.update(status="stopped: " + str(exc).split("refused steps: ", 1)[-1][:120], points=len(exc.points),
                   reached=exc.points[-1].lam if exc.points else None)

    row["online_s"] = time.perf_counter() - t0
    return row


def timeint_lines(ti: dict, how: str) -> list[str]:
    sols = ti["hbm_solutions_m"]
    out = ["## Time integration at the top H's peak frequency", "",
           f"At omega = {ti['omega_rad_s']:.4f} rad/s (the located peak of H = {TOP[1]}), {how}: the HBM has "
           f"{len(sols)} solutions there, first-harmonic amplitudes {', '.join(f'{a:.6e}' for a in sols)} m. "
           f"Newmark (demos/beam_timeint_check.py's integrator, its own contact law) from rest, "
           f"{TIMEINT['periods']} periods; its last period's first harmonic against the nearest HBM solution:", "",
           "| steps per period | first harmonic [m] | change over the last period | nearest HBM solution | difference | s |",
           "|---|---|---|---|---|---|"]
    for t in ti["timeint"]:
        a = t["first_harmonic_m"]
        near = min(sols, key=lambda b: abs(a - b))
        out.append(f"| {t['steps']} | {a:.6e} | {t['last_period_change']:+.1e} | {near:.6e} | {a / near - 1:+.3%} | "
                   f"{t['s']:.0f} |")
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="docs/benchmarks_harmonics.md")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="two coarse sweeps (H = 5, 21 at N = 256)")
    ap.add_argument("--timeint-from", type=Path, metavar="DIR",
                    help="only the time integration, on the branch of a `jointfem frf` folder made with the top "
                         "row's settings; appended to --out")
    args = ap.parse_args()
    if args.timeint_from is not None:
        d = np.load(args.timeint_from / "branch.npz", allow_pickle=True)
        summary = json.loads((args.timeint_from / "summary.json").read_text())
        method, H, N, law = TOP
        assert (summary["method"], summary["harmonics"], summary["samples"]) == (method, H, N), summary
        ti = timeint_check(d["omega"], d["U"], float(summary["peaks"]["b1.mid.uy"]["omega_rad_s"]), H, N)
        print(json.dumps(ti))
        with open(args.out, "a") as f:
            f.write("\n" + "\n".join(timeint_lines(ti, f"--timeint-from {args.timeint_from}")) + "\n")
        return
    work = QUICK if args.quick else SERIES + CHECKS
    t0 = time.time()
    rows = []
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # (so that a kill also ends the pool's workers)
    with mp.get_context("spawn").Pool(args.jobs) as pool:
        for row in pool.imap_unordered(run, sorted(work, key=lambda c: -c[1])):  # the long ones first
            rows.append(row)
            print(json.dumps(row), flush=True)
    key = {c: i for i, c in enumerate(work)}
    rows.sort(key=lambda r: key[(r["method"], r["H"], r["N"], r["law"])])
    series = [r for r in rows if (r["method"], r["H"], r["N"], r["law"]) in set(SERIES if not args.quick else QUICK)]
    done = [r for r in series if r["status"] == "complete"]
    top = done[-1] if done else None
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    lines = [
        "# The beam at 3 N against the number of harmonics",
        "",
        f"Recorded {datetime.date.today()} at commit {commit} on {platform.node()} ({mp.cpu_count()} cores, "
        f"{args.jobs} sweeps at a time) in {(time.time() - t0) / 60:.1f} min by",
        "",
        f"    .venv/bin/python benchmarks/harmonics.py --out {args.out} --jobs {args.jobs}"
        + (" --quick" if args.quick else ""),
        "",
        f"{SCENE} at {FORCE:g} N (pairs separate), the whole sweep {1570}–{1760} rad/s, each under a "
        f"{BUDGET} s budget, stability off. `exact`: the exact harmonic condensation on the joint's gaps (the "
        "full model's solution); `events`: the event-accurate Jenkins AFT (docs/theory.md). Peak: the "
        "located first-harmonic peak of b1.mid.uy (to the Newton tolerance). Truncation: the share of the "
        "contact force in the two top harmonics (docs/theory.md, \"Harmonic truncation\"), its largest over "
        "the branch and at the peak. Change: the peak amplitude against the previous row and against the "
        "highest H of the series.",
        "",
        "| method | H | N | law | status | points | unknowns | online [s] | max residual | truncation max | "
        "truncation at peak | peak [m] | at [rad/s] | change vs previous | change vs top H |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    prev = None
    for r in rows:
        if r["status"] != "complete":
            lines.append(f"| {r['method']} | {r['H']} | {r['N']} | {r['law']} | {r['status']} (at "
                         f"{r.get('reached') or float('nan'):.2f} rad/s) | {r['points']} | - | {r['online_s']:.0f} | "
                         f"- | - | - | - | - | - | - |")
            continue
        in_series = r in series
        dprev = f"{r['peak_m'] / prev['peak_m'] - 1:+.3%}" if in_series and prev is not None else "-"
        dtop = f"{r['peak_m'] / top['peak_m'] - 1:+.3%}" if top is not None else "-"
        lines.append(f"| {r['method']} | {r['H']} | {r['N']} | {r['law']} | complete | {r['points']} | {r['unknowns']} | "
                     f"{r['online_s']:.0f} | {r['residual_max']:.1e} | {r['trunc_max']:.3f} | {r['trunc_at_peak']:.4f} | "
                     f"{r['peak_m']:.6e} | {r['peak_rad_s']:.4f} | {dprev} | {dtop} |")
        if in_series:
            prev = r
    branch = next((r.pop("_branch") for r in rows if "_branch" in r), None)
    if branch is not None:
        top_row = next(r for r in rows if (r["method"], r["H"], r["N"], r["law"]) == TOP)
        lines += [""] + timeint_lines(timeint_check(*branch, top_row["peak_rad_s"], TOP[1], TOP[2]), "(this run)")
    Path(args.out).write_text("\n".join(lines) + "\n")
    Path(args.out).with_suffix(".json").write_text(json.dumps(rows, indent=1))
    print("wrote", args.out)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
