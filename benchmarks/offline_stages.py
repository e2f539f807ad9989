"""Offline stages of a 3D lap joint, per stage, serial or under MPI.

    python benchmarks/offline_stages.py --size 0.004 --json out.json
    mpirun -n 2 python benchmarks/offline_stages.py --size 0.004 --json out.json

Stages: mesh (gmsh + distribution), assembly (dolfinx), gather (canonical scipy on every
rank, areas, normals), contact pairs, 20 modes (SLEPc shift-invert, MUMPS), static modes
(MUMPS, one per contact component).  Rank 0 writes the JSON.  bench.py runs it serial and on
2 ranks and records the speed-up per stage.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=float, default=0.004, help="element size along x and z, m")
    ap.add_argument("--size-normal", type=float, default=0.003)
    ap.add_argument("--modes", type=int, default=20)
    ap.add_argument("--json", required=True)
    args = ap.parse_args(argv)
    from mpi4py import MPI

    from jointfem import linalg
    from jointfem.fem.continuum import ContinuumSpec, create_continuum

    comm = MPI.COMM_WORLD
    spec = ContinuumSpec(geometry="lap", dim=3, size=args.size, size_normal=args.size_normal, degree=2,
                         kt_total=3e4, kn=2e11, pressure=8e4)
    comm.Barrier()
    t0 = time.perf_counter()
    s = create_continuum(spec, comm)
    comm.Barrier()
    t1 = time.perf_counter()
    linalg.eigen(s.K_lin, s.M, args.modes)
    comm.Barrier()
    t2 = time.perf_counter()
    G = s.contacts[0].gap
    linalg.Factorized(s.K_lin).solve(G.T.toarray())
    comm.Barrier()
    t3 = time.perf_counter()
    if comm.rank == 0:
        tm = s.info["timings"]
        out = {"ranks": comm.size, "dofs": s.num_dofs, "pairs": s.num_pairs, "backend": linalg.backend(s.num_dofs),
               "stages_s": {"mesh": tm["mesh_s"], "assembly": tm["assembly_s"], "gather": tm["gather_s"],
                            "contact": tm["contact_s"], "model_total": t1 - t0, f"eigen_{args.modes}_modes": t2 - t1,
                            f"static_{G.shape[0]}_solves": t3 - t2, "offline_total": t3 - t0}}
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
