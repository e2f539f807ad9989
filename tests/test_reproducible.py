"""The same input gives the same points, whatever ran before in the process and whatever the
thread count (issue 50, item 17).

A sweep's path is decided point by point (step control, corner steps, relaxed kink tolerances),
so a last-bit difference in one residual can send two runs down different paths: the 9-pair lap
joint at 5 N once took 100 s alone and over 15 minutes inside the suite.  These tests pin the
inputs that could differ: the work done before in the same process (a continuum built by gmsh and
dolfinx with PETSc and MPI initialised, a sweep with Hill's stability, the numba kernels' thread
pools started), and the BLAS and numba thread counts (1 and 2, in fresh processes): bit for bit.  The case is a Jenkins chain swept across its stick-slip kinks
(8 masses, H = 5, N = 128).
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys

import numpy as np

from conftest import ROOT

SCRIPT = r"""
import sys
import numpy as np
sys.path.insert(0, {tests!r})
from test_reproducible import sweep
omega, U = sweep()
np.savez({out!r} + ".npz", omega=omega, U=U)
"""


def sweep():
    """(omega, U) of the chain's sweep, as contiguous float64 arrays."""
    from jointfem.analysis.frf import SweepOptions, compute_frf
    from jointfem.continuation.arclength import ContinuationOptions
    from jointfem.harmonics import Harmonics
    from jointfem.models.lumped import create_lumped
    from test_stability import jenkins_chain

    frf = compute_frf(create_lumped(jenkins_chain(8, 0.3)),
                      SweepOptions(0.3, 1.0, Harmonics(5, 128), ContinuationOptions(ds_max=0.05), stability="off"))
    return np.ascontiguousarray(frf.omega, dtype=float), np.ascontiguousarray(frf.U, dtype=float)


def _digest(omega, U) -> str:
    return hashlib.sha1(omega.tobytes() + U.tobytes()).hexdigest()


def test_a_sweep_is_the_same_after_other_work_in_the_process():
    from jointfem.analysis.frf import SweepOptions, compute_frf
    from jointfem.fem.continuum import ContinuumSpec, create_continuum
    from jointfem.harmonics import Harmonics
    from jointfem.models.lumped import create_lumped
    from conftest import sdof

    omega, U = sweep()
    assert omega.size > 30 and np.ptp(omega) > 0.69  # across the range, through its kinks
    create_continuum(ContinuumSpec(geometry="lap", dim=2, size=0.01, size_normal=0.006, kt_total=3e4, kn=2e11,
                                   pressure=8e4))
    compute_frf(create_lumped(sdof(0.5)), SweepOptions(1.0, 1.6, Harmonics(7, 256), stability="on"))
    again = sweep()
    assert _digest(*again) == _digest(omega, U)  # bit for bit


def test_a_sweep_is_the_same_with_one_and_two_threads(tmp_path):
    """In fresh processes with OpenBLAS and numba at one and two threads: bit for bit.  OpenBLAS's
    threads change the last bits (measured on this chain before sweeps ran BLAS on one thread:
    4.4e-16 in omega and 3.9e-15 of max |U| with 2 against 1; on the lap2d penalty ROM another
    path, 1014 points against 1064, benchmarks/blas_threads.py); numba's count changes nothing
    (each of its threads evaluates whole pairs).  A sweep now runs BLAS on one thread whatever
    OPENBLAS_NUM_THREADS says (linalg.sweep_blas)."""
    out = {}
    for n in ("1", "2"):
        env = dict(os.environ, OPENBLAS_NUM_THREADS=n, OMP_NUM_THREADS=n, NUMBA_NUM_THREADS=n)
        env.pop("JOINTFEM_BLAS_THREADS", None)
        r = subprocess.run([sys.executable, "-c", SCRIPT.format(tests=str(ROOT / "tests"), out=str(tmp_path / n))],
                           env=env, capture_output=True, text=True, cwd=tmp_path)
        assert r.returncode == 0, r.stderr
        with np.load(tmp_path / f"{n}.npz") as z:
            out[n] = (z["omega"], z["U"])
    assert _digest(*out["1"]) == _digest(*out["2"])


def test_sweeps_run_blas_on_the_threads_jointfem_blas_threads_gives(monkeypatch):
    """Inside a sweep BLAS runs on one thread by default and on JOINTFEM_BLAS_THREADS if given
    (threadpoolctl); outside, as it was; a count that is not a whole number >= 1 is refused by name."""
    import pytest
    from threadpoolctl import threadpool_info

    from jointfem.linalg import LinAlgError, sweep_blas

    def blas_threads():
        return {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}

    before = blas_threads()
    monkeypatch.delenv("JOINTFEM_BLAS_THREADS", raising=False)
    with sweep_blas():
        assert blas_threads() == {1}
    assert blas_threads() == before
    monkeypatch.setenv("JOINTFEM_BLAS_THREADS", "2")
    with sweep_blas():
        assert blas_threads() == {2}
    for bad in ("0", "two"):
        monkeypatch.setenv("JOINTFEM_BLAS_THREADS", bad)
        with pytest.raises(LinAlgError, match=f"JOINTFEM_BLAS_THREADS={bad!r}"):
            with sweep_blas():
                pass
