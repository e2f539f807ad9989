"""MPI awareness without forcing MPI on serial runs.

Under ``mpirun`` every rank builds the model (assembly, eigen and static solves are
distributed inside jointfem.fem and jointfem.linalg), every rank then runs the same small
reduced HBM problem on bitwise-identical data, and only rank 0 writes files and prints.
mpi4py is imported only when the process was started by an MPI launcher.
"""
from __future__ import annotations

import os

_LAUNCHER_VARS = ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "MPI_LOCALNRANKS")


def launched() -> bool:
    return any(v in os.environ for v in _LAUNCHER_VARS)


def comm():
    """MPI.COMM_WORLD under a launcher, else None."""
    if not launched():
        return None
    from mpi4py import MPI

    return MPI.COMM_WORLD


def rank() -> int:
    c = comm()
    return 0 if c is None else c.rank


def size() -> int:
    c = comm()
    return 1 if c is None else c.size


def is_root() -> bool:
    return rank() == 0
