"""Which threading layer runs the kernels' ``prange`` loops.

numba prefers TBB when it is installed.  A whole test suite here once hung at exit in numba's
``unload_tbb`` -> ``tbb::finalize`` with a TBB worker still alive (numba 0.68.1, libtbb12 2021.8;
numba issue #10556 reports the same deadlock), so OpenMP comes first.  GNU OpenMP is not fork-safe,
which is why the only child processes jointfem starts (viz's VTK pictures) are spawned, not forked.
A user's ``NUMBA_THREADING_LAYER`` or ``NUMBA_THREADING_LAYER_PRIORITY`` still decides.
"""
from __future__ import annotations

import os

import numba

PRIORITY = ["omp", "tbb", "workqueue"]

if "NUMBA_THREADING_LAYER" not in os.environ and "NUMBA_THREADING_LAYER_PRIORITY" not in os.environ:
    # in the environment as well: numba reads its configuration again (config.reload_config) when
    # a NUMBA_ variable changes, which would put its own order back
    os.environ["NUMBA_THREADING_LAYER_PRIORITY"] = " ".join(PRIORITY)
    numba.config.THREADING_LAYER_PRIORITY = PRIORITY
