"""What SuperLU's ordering costs a full-order sweep (issue 50, item 16): the 2D lap joint
(demos/lap2d.toml, full order, H = 3, N = 512, stability off), its first ``--points`` points, with
the column ordering SuperLU takes by default (COLAMD) and with the minimum degree ordering on the
pattern of A + A^T that jointfem.linalg.sparse_lu now uses.  Per ordering, in one process, one after
the other (the same machine state): the continuation's seconds, the seconds in SuperLU's
factorisation, the number of factorisations, and the points; then the fill and the factorisation
time of the last Jacobian solved, with each ordering.

    OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/lu_ordering.py --out docs/benchmarks_lu_ordering.md
"""
from __future__ import annotations

import argparse
import datetime
import platform
import subprocess
import time
from pathlib import Path

import numpy as np
import scipy.sparse.linalg as spla

ROOT = Path(__file__).resolve().parents[1]
ORDERINGS = ("COLAMD", "MMD_AT_PLUS_A")


def sweep(points: int, spec: str) -> dict:
    """The lap joint's first ``points`` points with SuperLU ordered by ``spec``."""
    import jointfem.continuation.arclength as arclength
    from jointfem.app import override, solve_scene
    from jointfem.scene import load_scene

    calls = {"n": 0, "s": 0.0, "last": None}

    def lu(A):
        A = A.tocsc()
        t0 = time.perf_counter()
        out = spla.splu(A, permc_spec=spec)
        calls["s"] += time.perf_counter() - t0
        calls["n"] += 1
        calls["last"] = A
        return out

    kept = arclength.sparse_lu
    arclength.sparse_lu = lu
    try:
        scene = override(load_scene(ROOT / "demos" / "lap2d.toml"), [f"solver.max_points={points}",
                                                                      'solver.stability="off"'])
        t0 = time.perf_counter()
        sol = solve_scene(scene, keep_incomplete=True)
        wall = time.perf_counter() - t0
    finally:
        arclength.sparse_lu = kept
    return {"wall": wall, "lu_s": calls["s"], "lu_n": calls["n"], "points": sol.frf.num_points,
            "omega_end": float(sol.frf.omega[-1]), "last": calls["last"]}


def _cpu() -> str:
    try:
        return next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name"))
    except (OSError, StopIteration):
        return platform.processor() or "cpu"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=40)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    sweep(4, ORDERINGS[-1])  # warm-up: imports, meshing, numba's kernels
    runs = {spec: sweep(args.points, spec) for spec in ORDERINGS}
    A = runs[ORDERINGS[-1]]["last"]
    fill = {}
    for spec in ORDERINGS:
        t0 = time.perf_counter()
        f = spla.splu(A, permc_spec=spec)
        fill[spec] = (f.L.nnz + f.U.nnz, time.perf_counter() - t0)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    lines = [
        "# SuperLU's ordering on a full-order sweep (the 2D lap joint)", "",
        f"Made by `OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/lu_ordering.py "
        f"--points {args.points}` ({datetime.date.today()}, jointfem {commit}, {platform.machine()}, "
        f"{_cpu()}; one process, the orderings one after the other after a warm-up).", "",
        f"demos/lap2d.toml at full order (H = 3, N = 512, stability off), its first {args.points} points.", "",
        "| SuperLU ordering | continuation + peaks [s] | in SuperLU's factorisation [s] | factorisations | points | last omega [rad/s] |",
        "|---|---|---|---|---|---|",
    ]
    for spec, r in runs.items():
        lines.append(f"| {spec} | {r['wall']:.1f} | {r['lu_s']:.1f} | {r['lu_n']} | {r['points']} | {r['omega_end']:.3f} |")
    a, b = (runs[s] for s in ORDERINGS)
    lines += ["", f"{ORDERINGS[1]} / {ORDERINGS[0]}: {b['wall'] / a['wall']:.2f} of the time, "
                  f"{b['lu_s'] / a['lu_s']:.2f} of the factorisations' time.", "",
              f"The last Jacobian solved ({A.shape[0]} unknowns, {A.nnz} nonzeros), factorised once more:", "",
              "| SuperLU ordering | nonzeros of L + U | factorisation [s] |", "|---|---|---|"]
    for spec, (nnz, s) in fill.items():
        lines.append(f"| {spec} | {nnz} | {s:.3f} |")
    lines += ["", "The two runs' points are not the same points: the factors' round-off differs, and with it "
                  "which steps are refused at the sampled law's kinks (the last omega above)."]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out is not None:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
