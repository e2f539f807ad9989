"""One online point of the 3D lap joint (issue 17): the cost of one Newton iteration (the HBM
residual with its Jacobian, then the solve of the Newton system) of the penalty ROM, Craig-Bampton
and the exact condensation, at a stick-slip state, on one model given by its element sizes.

    .venv/bin/python benchmarks/online_point.py --size 0.02 --size-normal 0.003 --size-joint 0.005 \
        --json r.json [--methods penalty,cb,exact] [--share 0.3] [-H 3] [-N 256] [--exact-path schur|lu]

The state: the stuck linear response at omega = 1690 rad/s (just below the stuck 2nd bending mode,
1706 rad/s on the demo's mesh), scaled so that ``--share`` of the pairs break the stuck law
(|t| > mu N, or N < 0) at some sample; the penalty ROM's active set is the components that break
there (what its after_converge hook would activate).  The same physical state for every method:
each method's own linear solution, scaled alike.  Each timing is the median of ``--repeat`` runs at
omega moved by 1e-6 rad/s each time, so that no method reuses a factorisation of the last omega
(the exact condensation factors one matrix per harmonic per omega, as along a branch).

Writes one JSON: DOFs, pairs, the pairs that break, and per method the unknowns (the size of the
system Newton solves), the offline seconds, and the seconds of the residual with its Jacobian, of
the Newton solve, and of the point (their sum).  Called by benchmarks/online_scaling.py.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

OMEGA = 1690.0  # rad/s


def breaking_pairs(problem, U) -> np.ndarray:
    """Per physical pair of the penalty ROM's problem: does its stuck linear force break the law at
    some sample for the coefficients U (the components' _linear_breaks, any per pair)?"""
    bad = problem._linear_breaks(U)
    return np.array([bad[p.comps].any() for p in problem.pairs])


def scale_for_share(problem, U, share: float) -> float:
    """The factor s for which ``share`` of the pairs break the law at s U (bisection in log s: the
    breaking set grows with s, each sample's condition being s (kt |g_t| - mu kn g_n) > mu N0)."""
    lo, hi = 1e-6, 1e6
    if breaking_pairs(problem, hi * U).mean() < share:
        raise RuntimeError(f"fewer than {share:.0%} of the pairs break even at 1e6 times the unit-force response")
    for _ in range(60):
        mid = np.sqrt(lo * hi)
        if breaking_pairs(problem, mid * U).mean() >= share:
            hi = mid
        else:
            lo = mid
        if hi / lo < 1.001:
            break
    return hi


def solve_time(J, R) -> float:
    t0 = time.perf_counter()
    if sp.issparse(J):
        spla.splu(sp.csc_matrix(J)).solve(R)
    else:
        sla.lu_solve(sla.lu_factor(J, check_finite=False), R, check_finite=False)
    return time.perf_counter() - t0


def time_point(problem, U, repeat: int) -> dict:
    """Median seconds of evaluate(jacobian=True) and of the Newton solve, at omega moved each run."""
    problem.evaluate(U, OMEGA - 1e-3, jacobian=True)  # warm-up: numba's compilation, the operators' caches
    ev_s, solve_s = [], []
    for k in range(repeat):
        t0 = time.perf_counter()
        ev = problem.evaluate(U, OMEGA + 1e-6 * (k + 1), jacobian=True)
        ev_s.append(time.perf_counter() - t0)
        if not (np.all(np.isfinite(ev.R)) and ev.J is not None):
            raise RuntimeError(f"{type(problem).__name__}: the residual is not finite at the stick-slip state")
        solve_s.append(solve_time(ev.J, ev.R))
    e, s = float(np.median(ev_s)), float(np.median(solve_s))
    return {"unknowns": int(problem.num_unknowns), "residual_jacobian_s": e, "solve_s": s, "point_s": e + s,
            "jacobian": "sparse" if sp.issparse(ev.J) else "dense"}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=0.02, help="element size along x and z, m")
    ap.add_argument("--size-normal", type=float, default=0.003)
    ap.add_argument("--size-joint", type=float, default=None, help="element size over the joint, m (sets the pairs)")
    ap.add_argument("--modes", type=int, default=20)
    ap.add_argument("--methods", default="penalty,cb,exact")
    ap.add_argument("--share", type=float, default=0.3, help="share of the pairs that break the stuck law")
    ap.add_argument("-H", type=int, default=3)
    ap.add_argument("-N", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--exact-path", choices=("auto", "schur", "lu"), default="auto",
                    help="the exact condensation's sparse path where the modal one is not taken (auto: schur where "
                         "MUMPS can be called directly)")
    ap.add_argument("--json", required=True)
    args = ap.parse_args(argv)
    from mpi4py import MPI

    from jointfem.analysis.frf import create_problem
    from jointfem.fem.continuum import ContinuumSpec, create_continuum
    from jointfem.harmonics import Harmonics
    from jointfem.rom.common import ExactModel, RomOptions
    from jointfem.rom.reductors import build_rom

    comm = MPI.COMM_WORLD
    # demos/lap3d.toml's joint, damping and force point
    spec = ContinuumSpec(geometry="lap", dim=3, size=args.size, size_normal=args.size_normal, degree=2,
                         size_joint=args.size_joint, kt_total=3e4, kn=2e11, mu=0.3, pressure=8e4,
                         rayleigh_alpha=4.391, rayleigh_beta=4.368e-6)
    t0 = time.perf_counter()
    s = create_continuum(spec, comm)
    model_s = time.perf_counter() - t0
    h = Harmonics(args.H, args.N)
    methods = [m for m in args.methods.split(",") if m]
    # the state, from the penalty ROM (its stuck linear response is the full model's, on its basis)
    t0 = time.perf_counter()
    pen = build_rom(s, "penalty", RomOptions(modes=args.modes))
    pen_offline = time.perf_counter() - t0
    pp = create_problem(pen, h)
    U1 = pp.initial_guess(OMEGA)
    scale = scale_for_share(pp, U1, args.share)
    breaks = breaking_pairs(pp, scale * U1)
    if "penalty" not in methods:  # its basis is not needed any more: memory for the other methods
        pen = pp = None
    out = {"ranks": comm.size, "dofs": s.num_dofs, "pairs": s.num_pairs, "size": args.size,
           "size_normal": args.size_normal, "size_joint": args.size_joint, "H": args.H, "N": args.N,
           "omega": OMEGA, "share_asked": args.share, "pairs_breaking": int(breaks.sum()),
           "force_scale_N": scale, "model_s": model_s, "methods": {}}
    for method in methods:
        if method == "penalty":
            rom, offline, problem = pen, pen_offline, pp
            # the stuck state, then the set grown by the components that break there (their p = 0
            # in it), as the after_converge hook grows it
            U = scale * U1
            problem.restore(problem.mask | problem._linear_breaks(U))
        else:
            t0 = time.perf_counter()
            if method == "exact" and args.exact_path != "auto":
                rom = ExactModel(s, sparse=args.exact_path)
            else:
                rom = build_rom(s, method, RomOptions(modes=args.modes))
            offline = time.perf_counter() - t0
            problem = create_problem(rom, h)
            U = scale * problem.initial_guess(OMEGA)
        row = time_point(problem, U, args.repeat)
        row["offline_s"] = offline
        if method == "exact":
            row["path"] = rom.info.get("condensation")
        out["methods"][method] = row
        del rom, problem
    if comm.rank == 0:
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
