"""Offline stages of a 3D lap joint, per stage, serial or under MPI.

    python benchmarks/offline_stages.py --size 0.004 --json out.json
    mpirun -n 2 python benchmarks/offline_stages.py --size 0.004 --json out.json

Stages: mesh (gmsh + distribution), assembly (dolfinx), gather (canonical scipy on every
rank, areas, normals), contact pairs, 20 modes (SLEPc shift-invert, MUMPS), static modes
(MUMPS, one per contact component), projection (the penalty ROM's reduced K_lin and M on
[modes, static modes], as rom.penalty forms them).  Per stage also the peak resident memory of the
largest rank so far (getrusage ru_maxrss).  Rank 0 writes the JSON.

--distributed: the distributed offline stage instead (jointfem.fem.distributed and the penalty
ROM's row blocks, issue 17): no gather stage; contact includes K_lin; static and projection as
PenaltyROM times them (the static modes with the contact stiffness, the projection also of M and
the gap rows); --static-solver petsc solves the static modes by PETSc's MatMatSolve instead of
MUMPS called directly (jointfem.mumps), to set the two side by side.  bench.py runs it serial and on
2 ranks and records the speed-up per stage; scaling.py runs it over mesh sizes and pair counts.
"""
from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=0.004, help="element size along x and z, m")
    ap.add_argument("--size-normal", type=float, default=0.003)
    ap.add_argument("--size-joint", type=float, default=None,
                    help="element size over the joint along x and along z, m (sets the pair count; default --size)")
    ap.add_argument("--modes", type=int, default=20)
    ap.add_argument("--json", required=True)
    ap.add_argument("--distributed", action="store_true", help="the distributed offline stage (no gather)")
    ap.add_argument("--static-solver", choices=("direct", "petsc"), default="direct",
                    help="distributed stage's static modes: MUMPS called directly with sparse right-hand sides "
                         "(jointfem.mumps, the default) or PETSc's MatMatSolve with dense ones (JOINTFEM_MUMPS=petsc)")
    args = ap.parse_args(argv)
    if args.static_solver == "petsc":
        import os

        os.environ["JOINTFEM_MUMPS"] = "petsc"
    from mpi4py import MPI

    from jointfem import linalg
    from jointfem.fem.continuum import ContinuumSpec, create_continuum

    comm = MPI.COMM_WORLD
    spec = ContinuumSpec(geometry="lap", dim=3, size=args.size, size_normal=args.size_normal, degree=2,
                         size_joint=args.size_joint, kt_total=3e4, kn=2e11, pressure=8e4)
    peak = {}

    def mark(stage):  # the largest rank's peak resident memory so far, GB (ru_maxrss is in kB on Linux)
        comm.Barrier()
        peak[stage] = max(comm.allgather(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)) / 1e6
        return time.perf_counter()

    t0 = mark("start")
    if args.distributed:
        return _distributed(args, spec, comm, mark, t0, peak)
    s = create_continuum(spec, comm)
    t1 = mark("model_total")
    Kl = s.K_lin
    _, Phi = linalg.eigen(Kl, s.M, args.modes)
    t2 = mark("eigen")
    G = s.contacts[0].gap
    Psi = linalg.Factorized(Kl).solve(G.T.toarray())
    t3 = mark("static")
    T = np.hstack([Phi, Psi])
    del Psi
    Kr, Mr = T.T @ (Kl @ T), T.T @ (s.M @ T)
    t4 = mark("projection")
    if comm.rank == 0:
        tm = s.info["timings"]
        out = {"ranks": comm.size, "dofs": s.num_dofs, "pairs": s.num_pairs, "backend": linalg.backend(s.num_dofs),
               "size": args.size, "size_normal": args.size_normal, "size_joint": args.size_joint,
               "reduced": int(Kr.shape[0]), "finite": bool(np.isfinite(Kr).all() and np.isfinite(Mr).all()),
               "stages_s": {"mesh": tm["mesh_s"], "assembly": tm["assembly_s"], "gather": tm["gather_s"],
                            "contact": tm["contact_s"], "model_total": t1 - t0, f"eigen_{args.modes}_modes": t2 - t1,
                            f"static_{G.shape[0]}_solves": t3 - t2, "projection": t4 - t3, "offline_total": t4 - t0},
               "peak_gb_per_rank": peak}
        Path(args.json).write_text(json.dumps(out, indent=1))


def _distributed(args, spec, comm, mark, t0, peak):
    from jointfem.fem.distributed import create_distributed
    from jointfem.rom.common import RomOptions
    from jointfem.rom.penalty import PenaltyROM

    model = create_distributed(spec, comm)
    t1 = mark("model_total")
    rom = PenaltyROM(None, RomOptions(modes=args.modes), distributed=model)
    t2 = mark("offline_total")
    if comm.rank == 0:
        tm, to = model.info["timings"], rom.info["offline_timings"]
        out = {"ranks": comm.size, "dofs": model.num_dofs, "pairs": int(model.info["num_pairs"]), "backend": "petsc",
               "offline": "distributed", "static_solver": args.static_solver, "size": args.size, "size_normal": args.size_normal,
               "size_joint": args.size_joint, "reduced": int(rom.K.shape[0]),
               "finite": bool(np.isfinite(rom.K).all() and np.isfinite(rom.M).all()),
               "stages_s": {"mesh": tm["mesh_s"], "assembly": tm["assembly_s"], "gather": 0.0,
                            "contact": tm["contact_s"], "model_total": t1 - t0,
                            f"eigen_{args.modes}_modes": to["eigen_s"], f"static_{rom.num_comp}_solves": to["static_s"],
                            "projection": to["projection_s"], "offline_total": t2 - t0},
               "peak_gb_per_rank": peak}
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
