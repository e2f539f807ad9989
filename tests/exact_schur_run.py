"""Run under `mpirun -n 2` by tests/test_exact_schur.py: the 2D lap joint's exact condensation on
the Schur path (MUMPS distributed over the ranks), Newton at 1700 rad/s; rank 0 writes the solution
and the full field it recovers."""
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main(out: str) -> None:
    from mpi4py import MPI

    sys.path.insert(0, str(ROOT / "tests"))
    from test_exact_schur import W, _lap2d, _newton

    from jointfem.analysis.frf import create_problem
    from jointfem.harmonics import Harmonics
    from jointfem.rom import ExactModel

    ex = create_problem(ExactModel(_lap2d(), modal=False), Harmonics(3, 256))
    Y = _newton(ex)
    U = ex.full_coefficients(Y, W)
    if MPI.COMM_WORLD.rank == 0:
        np.savez(out, Y=Y, U=U, ranks=MPI.COMM_WORLD.size, path=ex.branch_info()["condensation"])


if __name__ == "__main__":
    main(sys.argv[1])
