"""What locating peaks and computing stability add to a sweep (issue 14): the SDOF Jenkins
oscillator of tests/test_peaks.py (m = k = kt = Fs = 1, c = 0.02, H = 7, N = 128), the default
sweep 0.5 -> 2.0 rad/s, median wall time of ``--repeats`` runs after a warm-up, with and without
each.  Writes a Markdown table.

    .venv/bin/python benchmarks/peaks_cost.py --out docs/benchmarks_peaks.md
"""
from __future__ import annotations

import argparse
import datetime
import platform
import subprocess
import time
from pathlib import Path

import numpy as np

from jointfem.analysis.frf import SweepOptions, compute_frf
from jointfem.harmonics import Harmonics
from jointfem.models.lumped import ForceSpec, JenkinsSpec, LinkSpec, LumpedSpec, MassSpec, create_lumped


def sdof(F):
    return create_lumped(LumpedSpec(
        masses=(MassSpec("m", 1.0),), springs=(LinkSpec("m.x", "ground", 1.0),),
        dampers=(LinkSpec("m.x", "ground", 0.02),),
        jenkins=(JenkinsSpec("m", "ground", ("x",), None, kt=1.0, kn=0.0, mu=1.0, N0=1.0),),
        forces=(ForceSpec("m.x", F),), outputs=("m.x",)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="docs/benchmarks_peaks.md")
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    variants = {"points only (before issue 14)": dict(locate_peaks=False, stability=False),
                "+ located peaks": dict(locate_peaks=True, stability=False),
                "+ stability": dict(locate_peaks=False, stability=True),
                "default (both)": dict()}
    rows = []
    for F in (0.05, 0.2, 0.5):
        s = sdof(F)
        times = {}
        for name, kw in variants.items():
            opts = SweepOptions(0.5, 2.0, Harmonics(7, 128), **kw)
            compute_frf(s, opts)  # warm-up
            ts = []
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                frf = compute_frf(s, opts)
                ts.append(time.perf_counter() - t0)
            times[name] = float(np.median(ts))
            if kw.get("locate_peaks", True):
                solves = frf.info["peaks"]["m.x"].solves
        base = times["points only (before issue 14)"]
        rows.append(f"| {F} | {frf.num_points} | {solves} | " + " | ".join(
            f"{t * 1e3:.0f} ms ({t / base:.2f}x)" for t in times.values()) + " |")
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    text = (f"# Cost of located peaks and stability\n\nMade by `.venv/bin/python benchmarks/peaks_cost.py` on "
            f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, commit {commit} (plus the "
            f"working tree), {platform.processor() or platform.machine()}, median of {args.repeats} runs after a "
            f"warm-up.  SDOF Jenkins oscillator, H = 7, N = 128, 0.5 -> 2.0 rad/s, default continuation.\n\n"
            "| F [N] | points | peak solves | " + " | ".join(variants) + " |\n|" + "---|" * (3 + len(variants)) + "\n"
            + "\n".join(rows) + "\n")
    Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
