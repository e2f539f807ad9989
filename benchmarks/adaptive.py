"""harmonics = "auto" on the paper's beam at 3 N (demos/beam2d.toml; exact condensation, event-
accurate AFT, N = 1024, harmonics_max = 41): H chosen along the branch (this code) against the
whole sweep restarted at H = 3, 5, 7, ... until the largest estimate meets the target (the code of
an earlier commit, by default 8d7cb86), one after the other on the same machine (issue 46, item 2).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/adaptive.py --out docs/benchmarks_adaptive.md

Each run is the command line's `jointfem frf ... --method exact --harmonics auto` (the earlier
commit's from a git worktree on PYTHONPATH), timed from outside.  The reference: the sweep at H = 41
(docs/benchmarks_harmonics.md, peak 2.908435e-4 m at 1693.638 rad/s).  An artefact loop is a
stretch after the peak where the branch runs back below the peak's omega by more than 1 rad/s
(the loops of H = 5 to 17 run back to 1634 rad/s and lower; H = 41's top folds over 0.5 rad/s).
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
REF_AMP, REF_OMEGA = 2.908435e-4, 1693.638  # H = 41 (docs/benchmarks_harmonics.md)
SETS = ['solver.aft="events"', "solver.harmonics_max=41", "solver.samples=1024"]


def run(label: str, out: Path, tree: Path | None, extra: list[str]) -> dict:
    """One run of `jointfem frf`: this checkout's, or (``tree``) a worktree's code, run from it
    (``python -m`` puts the working directory first on sys.path)."""
    env = dict(os.environ)
    if tree is not None:
        env["PYTHONPATH"] = str(tree)
    args = [sys.executable, "-m", "jointfem", "frf", "demos/beam2d.toml", "--method", "exact", "--out", str(out),
            "--quiet"] + [a for s in SETS + extra for a in ("--set", s)]
    t = time.perf_counter()
    r = subprocess.run(args, cwd=tree or ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if r.returncode not in (0, 3):
        raise SystemExit(f"{label}: exit {r.returncode}: {r.stderr[-2000:]}")
    s = json.loads((out / "summary.json").read_text())
    b = np.load(out / "branch.npz")
    pk = s["peaks"]["b1.mid.uy"]
    omega = b["omega"]
    i = int(np.argmin(np.abs(omega - pk["omega_rad_s"])))
    back = float(omega[i:].min())
    row = {"label": label, "wall_s": wall, "status": s["status"], "points": int(omega.size), "H": s["harmonics"],
           "peak": pk["amp1_m"], "omega": pk["omega_rad_s"], "back_to": back,
           "loop": back < pk["omega_rad_s"] - 1.0,
           "per_H": s.get("harmonics_adaptive", {}).get("points_per_H"),
           "attempts": [a["H"] for a in s.get("harmonics_auto", {}).get("attempts", [])]}
    print(json.dumps(row), flush=True)
    return row


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--out")
    ap.add_argument("--before", default="8d7cb86", help="the commit of the restart-from-scratch auto")
    ap.add_argument("--skip-before", action="store_true")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        rows.append(run("along the branch (this code)", tmp / "new", None, ['solver.harmonics="auto"']))
        if not args.skip_before:
            old = tmp / "old_tree"
            subprocess.run(["git", "worktree", "add", "--detach", str(old), args.before], cwd=ROOT, check=True,
                           capture_output=True)
            try:
                rows.append(run(f"restarted at every H ({args.before})", tmp / "old", old,
                                ['solver.harmonics="auto"']))
            finally:
                subprocess.run(["git", "worktree", "remove", "--force", str(old)], cwd=ROOT, capture_output=True)
    lines = [
        "# harmonics = \"auto\" on the paper's beam at 3 N: along the branch against restarted", "",
        f"Recorded {datetime.date.today()} at commit "
        f"{subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=ROOT, capture_output=True, text=True).stdout.strip()}"
        f" on {platform.node()} ({platform.processor() or platform.machine()}) in "
        f"{(time.perf_counter() - t0) / 60:.1f} min by", "",
        "    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/adaptive.py --out docs/benchmarks_adaptive.md", "",
        "demos/beam2d.toml at 3 N, `--method exact` (the full model's equations condensed on the joint's "
        "gaps), `aft = \"events\"`, N = 1024, harmonics_max = 41, the default targets (estimate 0.05, "
        "amplitude_tol 5e-3). Reference: the sweep at H = 41, peak 2.908435e-4 m at 1693.638 rad/s "
        "(docs/benchmarks_harmonics.md). *Back to*: the lowest omega of the branch after its located "
        "peak (an artefact loop runs back more than 1 rad/s below the peak).", "",
        "| auto | wall [s] | status | points | largest H | points per H (or H tried) | peak [m] | "
        "against H = 41 | at [rad/s] | against H = 41 | back to [rad/s] | artefact loop |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        per = (", ".join(f"{k}: {v}" for k, v in r["per_H"].items()) if r["per_H"]
               else "H = " + ", ".join(map(str, r["attempts"])))
        lines.append(f"| {r['label']} | {r['wall_s']:.0f} | {r['status']} | {r['points']} | {r['H']} | {per} | "
                     f"{r['peak']:.6e} | {100 * (r['peak'] / REF_AMP - 1):+.4f} % | {r['omega']:.4f} | "
                     f"{100 * (r['omega'] / REF_OMEGA - 1):+.5f} % | {r['back_to']:.2f} | "
                     f"{'yes' if r['loop'] else 'no'} |")
    if len(rows) == 2:
        lines += ["", f"Wall time, along the branch over restarted: {rows[0]['wall_s'] / rows[1]['wall_s']:.2f}."]
    text = "\n".join(lines) + "\n"
    if args.out:
        Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
