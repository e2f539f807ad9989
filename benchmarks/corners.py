"""Sweeps at strong separation (issue 14): the stalls of docs/theory.md "Known limits", run to the
end with the continuation's corner steps and secants on kinks, and the same sweeps with them off
(the continuation before them: steps only shrink at a corner), each under a time budget.

Per sweep: status, points, refused steps, corners passed, online seconds, the largest accepted
residual (max|R| / max|F|) and the located peak.  Writes a Markdown table.

    .venv/bin/python benchmarks/corners.py --out docs/benchmarks_corners.md [--jobs 2] [--quick]
    .venv/bin/python benchmarks/corners.py --case 'lap3d 3 N, exact' --budget 900   (one row, printed)
    .venv/bin/python benchmarks/corners.py --case 'lap3d 3 N, penalty:10' --budget 1200 --max-points 20000 \
        --log /tmp/penalty.log                      (one row, with the continuation's debug log)

Each sweep runs in its own process (``--jobs`` at a time), through jointfem.app.solve_scene as
`jointfem frf` does, with stability off (it is not what is measured here).
"""
from __future__ import annotations

import argparse
import datetime
import json
import multiprocessing as mp
import platform
import signal
import subprocess
import sys
import tempfile
import time
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

# (label, scene, method, modes, force N, H, N, budget s[, scene overrides as --set takes them])
# Every sweep runs on the scene's defaults but H, N and the time budget: the band a branch may fold
# into (an octave each side of the window; lap3d's loop at 5 N folds at 1290 rad/s) and the points
# (20000; the beam at H = 15, N = 4096 takes 13308) held them all since 2026-12-05; until then the
# 5 N and H = 15 rows set [solver] omega_limits and max_points by hand.
CASES = [
    ("lap3d 3 N, penalty:10", "demos/lap3d.toml", "penalty", 10, 3.0, 3, 256, 900),
    ("lap3d 5 N, penalty:10", "demos/lap3d.toml", "penalty", 10, 5.0, 3, 256, 2400),
    ("lap3d 3 N, exact", "demos/lap3d.toml", "exact", 0, 3.0, 3, 256, 900),
    ("lap3d 5 N, exact", "demos/lap3d.toml", "exact", 0, 5.0, 3, 256, 2400),
    ("lap2d 3 N, full", "demos/lap2d.toml", "full", 0, 3.0, 3, 512, 900),
    ("beam 3 N, H = 5", "demos/beam2d.toml", "full", 0, 3.0, 5, 1024, 600),
    ("beam 3 N, H = 7", "demos/beam2d.toml", "full", 0, 3.0, 7, 1024, 600),
    ("beam 3 N, H = 9", "demos/beam2d.toml", "full", 0, 3.0, 9, 1024, 600),
    ("beam 3 N, H = 11", "demos/beam2d.toml", "full", 0, 3.0, 11, 1024, 600),
    ("beam 3 N, H = 15", "demos/beam2d.toml", "full", 0, 3.0, 15, 1024, 1500),
    ("beam 3 N, H = 15, N = 4096", "demos/beam2d.toml", "full", 0, 3.0, 15, 4096, 2400),
]
QUICK = {"beam 3 N, H = 11", "lap2d 3 N, full"}
OLD = dict(corner_steps=False, secant_on_kinks=False, kink_lam_steps=False,
           corrector_max_iter=40)  # the continuation before


def scene_at_force(path: Path, force: float, tmp: Path) -> Path:
    """The scene with [force] amplitude set (paths in it made absolute)."""
    text = path.read_text()
    data = tomllib.loads(text)
    out = []
    section = None
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("["):
            section = s.strip("[]").strip()
        if section == "force" and s.startswith("amplitude"):
            line = f"amplitude = {force}"
        if section == "mesh" and s.startswith("file"):
            line = f'file = "{(path.parent / data["mesh"]["file"]).resolve().as_posix()}"'
        out.append(line)
    p = tmp / f"{path.stem}_{force:g}N.toml"
    p.write_text("\n".join(out) + "\n")
    return p


def run(case_variant, max_points=None):
    (label, scene, method, modes, force, H, N, budget, *sets), variant = case_variant
    from jointfem.analysis.frf import compute_frf
    from jointfem.app import override, override_harmonics, sweep_options
    from jointfem.continuation.arclength import ContinuationError
    from jointfem.rom.common import RomOptions
    from jointfem.rom.reductors import build_rom
    from jointfem.scene import create_structure, load_scene

    with tempfile.TemporaryDirectory() as tmp:
        sc = override_harmonics(override(load_scene(scene_at_force(ROOT / scene, force, Path(tmp))),
                                         list(sets[0]) if sets else []), H, N)
        opts = sweep_options(sc, stability="off", peak_share=0.0)
        cont = replace(opts.continuation, time_limit=budget, **(OLD if variant == "before" else {}),
                       **({"max_points": max_points} if max_points else {}))
        opts = replace(opts, continuation=cont)
        st = create_structure(sc)
        model = st if method == "full" else build_rom(st, method, RomOptions(modes=modes or 20))
        t0 = time.perf_counter()
        row = {"case": label, "variant": variant, "unknowns": None}
        try:
            frf = compute_frf(model, opts)
            row["status"] = "complete"
            row["points"] = frf.num_points
            row["residual_max"] = float(frf.info["arrays"]["residual"].max())
            row.update(frf.info["continuation"])
            row["unknowns"] = frf.info["num_unknowns"]
            name = next(iter(frf.outputs))
            w, a = frf.peak(name)
            row["peak"] = f"{a:.5e} m at {w:.3f} rad/s"
            row["omega_min"] = float(frf.omega.min())
        except ContinuationError as exc:
            row["status"] = "stopped: " + str(exc).split("refused steps: ", 1)[-1][:120]
            row["points"] = len(exc.points)
            row["residual_max"] = max((p.residual for p in exc.points), default=float("nan"))
            row["reached"] = f"{exc.points[-1].lam:.2f}" if exc.points else "-"
        row["online_s"] = time.perf_counter() - t0
    return row


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="docs/benchmarks_corners.md")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help=f"only {sorted(QUICK)}")
    ap.add_argument("--skip-before", action="store_true", help="only the current continuation")
    ap.add_argument("--case", action="append", default=[], metavar="LABEL",
                    help="only this case (repeatable), e.g. 'lap3d 3 N, exact'; prints its row, writes no table")
    ap.add_argument("--budget", type=float, help="with --case: its time budget in s instead of the table's")
    ap.add_argument("--max-points", type=int, help="with --case: the sweep's point limit instead of the default")
    ap.add_argument("--log", metavar="FILE", help="with --case: write the continuation's debug log (every point, "
                                                  "refused step and corner) to FILE")
    args = ap.parse_args()
    if args.case:
        if args.log:
            import logging

            logging.basicConfig(filename=args.log, level=logging.WARNING,
                                format="%(relativeCreated)d %(name)s %(message)s")
            logging.getLogger("jointfem.continuation").setLevel(logging.DEBUG)
        unknown = sorted(set(args.case) - {c[0] for c in CASES})
        if unknown:
            ap.error(f"--case {unknown}: not among {[c[0] for c in CASES]}")
        for c in CASES:
            if c[0] in args.case:
                c = c[:7] + ((args.budget,) if args.budget else c[7:8]) + c[8:]
                print(json.dumps(run((c, "now"), args.max_points)), flush=True)
        return
    cases = [c for c in CASES if not args.quick or c[0] in QUICK]
    work = [(c, "now") for c in cases] + ([] if args.skip_before else [(c, "before") for c in cases])
    t0 = time.time()
    # a SIGTERM (kill, pkill) leaves the pool's context, which terminates its workers: without this
    # they ran on as orphans after their parent was killed
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    with mp.get_context("spawn").Pool(args.jobs) as pool:
        rows = []
        # the longest budgets first, so that no long sweep starts last (the table keeps CASES' order);
        # chunksize 1: each sweep goes to the next free process
        for row in pool.imap_unordered(run, sorted(work, key=lambda w: -w[0][7]), chunksize=1):
            rows.append(row)
            print(json.dumps(row), flush=True)
    order = {(c[0], v): i for i, (c, v) in enumerate(work)}
    rows.sort(key=lambda r: order[(r["case"], r["variant"])])
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    lines = [
        "# Sweeps at strong separation: corner steps against shrinking steps",
        "",
        f"Recorded {datetime.date.today()} at commit {commit} on {platform.node()} ({platform.processor() or 'x86_64'}, "
        f"{mp.cpu_count()} cores, {args.jobs} sweeps at a time) in {(time.time() - t0) / 60:.1f} min by",
        "",
        f"    .venv/bin/python benchmarks/corners.py --out {args.out} --jobs {args.jobs}"
        + (" --quick" if args.quick else "") + (" --skip-before" if args.skip_before else ""),
        "",
        "\"now\": the continuation with corner steps, secants on kinks and steps over kinks at fixed omega "
        "(docs/theory.md, Continuation). \"before\": the same sweep with all three off and 40 corrector "
        "iterations, as before issue 14. "
        "Each sweep has the budget in the table (`[solver] time_limit`). Residual: the largest accepted "
        "max|R| / max|F| over the points. Peak: the first output's located peak (first harmonic).",
        "",
        "| sweep | continuation | status | points | refused | corners (sharp) | kinks crossed | online [s] | max residual | peak |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        budget = next(c[7] for c in CASES if c[0] == r["case"])
        status = r["status"] if r["status"] == "complete" else f"{r['status']} (at {r.get('reached', '-')} rad/s)"
        lines.append(f"| {r['case']} (budget {budget} s) | {r['variant']} | {status} | {r['points']} | "
                     f"{r.get('refused_steps', '-')} | {r.get('corners_passed', '-')} ({r.get('sharp_corners', '-')}) | "
                     f"{r.get('kinks_crossed', '-')} | "
                     f"{r['online_s']:.0f} | "
                     f"{r['residual_max']:.1e} | {r.get('peak', '-')} |")
    Path(args.out).write_text("\n".join(lines) + "\n")
    print("wrote", args.out)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
