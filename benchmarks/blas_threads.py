"""What OpenBLAS's threads do to a sweep: its time and its points, 1 thread against 2, measured as
ratios in one process (issue 50, items 16-17).

    python benchmarks/blas_threads.py demos/beam2d.toml full [demos/lap2d.toml exact ...]

Each scene's sweep runs with BLAS at 1 and at 2 threads (JOINTFEM_BLAS_THREADS, which sweeps hand
to threadpoolctl; linalg.sweep_blas), twice each, interleaved so that they share the machine's load.
Recorded in docs/benchmarks_blas_threads.md.  Prints the online times, the ratio, the point
counts and how far the two thread counts' points are apart (omega and coefficients, relative).
"""
import argparse
import os

import numpy as np

from jointfem.app import solve_scene
from jointfem.rom import METHODS
from jointfem.scene import load_scene


class _Runs(argparse.Action):
    """SCENE METHOD pairs, refused while parsing (a lone scene, a method misspelt), not after the first
    scene's sweeps."""

    def __call__(self, parser, namespace, values, option_string=None):
        if len(values) % 2:
            parser.error(f"runs: SCENE METHOD pairs, got {len(values)} words")
        for method in values[1::2]:
            if method not in METHODS:
                parser.error(f"runs: method {method!r} is not one of {', '.join(METHODS)}")
        setattr(namespace, self.dest, list(zip(values[::2], values[1::2])))


def main(argv=None):
    ap = argparse.ArgumentParser(description="What OpenBLAS's threads do to a sweep: 1 thread against 2.")
    ap.add_argument("runs", nargs="+", action=_Runs, metavar="SCENE METHOD",
                    help="a scene file and the method to sweep it with, as many pairs as wanted")
    for path, method in ap.parse_args(argv).runs:
        scene = load_scene(path)
        times, last = {1: [], 2: []}, {}
        for rep in range(2):
            for n in (1, 2):
                os.environ["JOINTFEM_BLAS_THREADS"] = str(n)
                frf = solve_scene(scene, method=method).frf
                times[n].append(frf.info["time_online_s"])
                last[n] = frf
                print(f"{path} {method} rep {rep} blas threads {n}: online {frf.info['time_online_s']:.1f} s, "
                      f"{frf.omega.size} points", flush=True)
        a, b = last[1], last[2]
        same = a.omega.size == b.omega.size
        apart = (f"omega {np.abs(a.omega - b.omega).max() / np.abs(a.omega).max():.1e}, U "
                 f"{np.abs(a.U - b.U).max() / np.abs(a.U).max():.1e}") if same else "different paths"
        print(f"{path} {method}: 2 threads / 1 thread online time {np.mean(times[2]) / np.mean(times[1]):.2f}; "
              f"points {a.omega.size} and {b.omega.size}; apart: {apart}", flush=True)


if __name__ == "__main__":
    main()
