"""The same input gives the same points, whatever ran before in the process and whatever the
thread count (issue 50, item 17).

A sweep's path is decided point by point (step control, corner steps, relaxed kink tolerances),
so a last-bit difference in one residual can send two runs down different paths: the 9-pair lap
joint at 5 N once took 100 s alone and over 15 minutes inside the suite.  These tests pin the
inputs that could differ: the work done before in the same process (a continuum built by gmsh and
dolfinx with PETSc and MPI initialised, a sweep with Hill's stability, the numba kernels' thread
pools started): bit for bit; and the BLAS and numba thread counts (1 and 2, in fresh processes):
to round-off, on the same path.  The case is a Jenkins chain swept across its stick-slip kinks
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
    """In fresh processes with OpenBLAS and numba at one and two threads: the same path (the same
    points, the same count) and the same numbers to round-off.  Not bit for bit: OpenBLAS's threads
    change the last bits (measured on this chain: 4.4e-16 in omega and 3.9e-15 of max |U| with 2
    threads against 1, whatever numba's count, which changes nothing: each numba thread evaluates
    whole pairs); 1e-12 is allowed, a thousand times that and far below any path's difference."""
    out = {}
    for n in ("1", "2"):
        env = dict(os.environ, OPENBLAS_NUM_THREADS=n, OMP_NUM_THREADS=n, NUMBA_NUM_THREADS=n)
        r = subprocess.run([sys.executable, "-c", SCRIPT.format(tests=str(ROOT / "tests"), out=str(tmp_path / n))],
                           env=env, capture_output=True, text=True, cwd=tmp_path)
        assert r.returncode == 0, r.stderr
        with np.load(tmp_path / f"{n}.npz") as z:
            out[n] = (z["omega"], z["U"])
    (o1, U1), (o2, U2) = out["1"], out["2"]
    assert o1.size == o2.size
    assert np.abs(o1 - o2).max() <= 1e-12 * np.abs(o1).max()
    assert np.abs(U1 - U2).max() <= 1e-12 * np.abs(U1).max()
