"""What locating the peaks costs beside the sweep (issue 46, item 5): the 20-mass Jenkins chain
(tests/test_stability.py jenkins_chain: kt = 1, slip force 0.5, F = 0.3, 0.9 -> 1.2 rad/s,
ds_max = 0.05, H = 5, N = 128) and the 25-pair lap joint's exact condensation (demos/lap3d_friction.toml,
H = 3, N = 256), stability off.  Per case, the sweep's own time and the peak search's
(compute_frf's info time_online_s - time_peaks_s and time_peaks_s, in the same call), after one
warm-up sweep, for the default search (to a tenth of each peak's error bar) and, where the tree has
it, the search to 1e-8 in omega (peak_share = 0).  Runs on a tree without peak_share too (the search
before issue 46's item 5): point PYTHONPATH at it.

    OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/peak_cost.py --out docs/benchmarks_peak_cost.md
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import platform
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def chain():
    sys.path.insert(0, str(ROOT / "tests"))
    from test_stability import jenkins_chain

    from jointfem.analysis.frf import SweepOptions
    from jointfem.continuation.arclength import ContinuationOptions
    from jointfem.harmonics import Harmonics
    from jointfem.models.lumped import create_lumped
    return (create_lumped(jenkins_chain()),
            SweepOptions(0.9, 1.2, Harmonics(5, 128), ContinuationOptions(ds_max=0.05), stability=False))


def lap3d():
    from jointfem.app import sweep_options
    from jointfem.rom.reductors import build_rom
    from jointfem.scene import create_structure, load_scene
    sc = load_scene(ROOT / "demos" / "lap3d_friction.toml")
    return build_rom(create_structure(sc), "exact"), replace(sweep_options(sc, stability="off"), stability=False)


CASES = {"chain": ("20-mass Jenkins chain, full order, H = 5, N = 128", chain),
         "lap3d": ("25-pair lap joint (lap3d_friction), exact condensation, H = 3, N = 256", lap3d)}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--out")
    args = ap.parse_args()
    import jointfem
    from jointfem.analysis.frf import SweepOptions, compute_frf

    has_share = "peak_share" in {f.name for f in dataclasses.fields(SweepOptions)}
    rows = []
    for name in args.cases:
        title, make = CASES[name]
        model, opts = make()
        compute_frf(model, replace(opts, locate_peaks=False))  # warm-up: numba, caches
        for label, o in ([("default", opts)] + ([("peak_share = 0", replace(opts, peak_share=0.0))] if has_share else [])):
            t0 = time.perf_counter()
            frf = compute_frf(model, o)
            wall = time.perf_counter() - t0
            info = frf.info
            sweep = info["time_online_s"] - info["time_peaks_s"]
            for out, pk in info["peaks"].items():
                tol = getattr(pk, "tolerance", 0.0)
                rows.append(f"| {title} | {label} | {frf.num_points} | {sweep:.2f} | {info['time_peaks_s']:.2f} | "
                            f"{info['time_peaks_s'] / sweep:.2f} | {out} | {pk.solves} | {pk.omega:.9g} | "
                            f"{pk.amplitude:.9e} | {tol:.2g} |")
                print(rows[-1], flush=True)
            print(f"({name}, {label}: {wall:.1f} s in all)", flush=True)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=Path(jointfem.__file__).parent).stdout.strip()
    text = (f"# What locating the peaks costs beside the sweep\n\nMade by `benchmarks/peak_cost.py` on "
            f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC with jointfem from "
            f"{Path(jointfem.__file__).parent} (commit {commit}), {platform.processor() or platform.machine()}, "
            "OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1.  Sweep and peak search timed in the same call; ratio = "
            "peak search / sweep; solves: the output's corrector solves (shared points are counted once, by the "
            "first output that asks); tolerance: the share of its amplitude the top may exceed the located peak by "
            "(0: searched to 1e-8 in omega).\n\n"
            "| case | search | points | sweep [s] | peaks [s] | ratio | output | solves | omega [rad/s] | amplitude [m] | tolerance |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n")
    if args.out:
        Path(args.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
