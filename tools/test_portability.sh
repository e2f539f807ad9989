#!/usr/bin/env bash
# The precision-sensitive tests under what another user's machine may have (issue 51): OpenBLAS's
# kernels for other CPU families (OPENBLAS_CORETYPE) and one BLAS thread. A kernel is forced only
# where this CPU can run it (Haswell needs AVX2, SkylakeX AVX-512; Sandybridge runs on any AVX
# host), and K's entries perturbed by 1e-15 of themselves (tests/conftest.py).
# `tools/test_portability.sh --all` runs the whole suite under each setting instead.
set -uo pipefail
cd "$(dirname "$0")/.."
PY=.venv/bin/python
# the tests that compare two solutions of the same equations to round-off, the sweeps whose path
# goes through kinks, and the peak search's round-off test
TESTS="tests/test_continuum.py tests/test_exact_schur.py tests/test_preload.py tests/test_continuation.py
       tests/test_corners.py tests/test_peaks.py tests/test_brb.py::test_brb_peak_does_not_depend_on_round_off_in_K"
[ "${1:-}" = "--all" ] && TESTS=tests
flags=$(grep -m1 '^flags' /proc/cpuinfo 2>/dev/null || true)
settings=()
[[ $flags == *" avx "* ]] && settings+=("OPENBLAS_CORETYPE=Sandybridge")
[[ $flags == *" avx2 "* ]] && settings+=("OPENBLAS_CORETYPE=Haswell")
[[ $flags == *" avx512f "* ]] && settings+=("OPENBLAS_CORETYPE=SkylakeX")
settings+=("OPENBLAS_NUM_THREADS=1" "JOINTFEM_TEST_PERTURB_K=1")
status=0
for s in "${settings[@]}"; do
  echo "== $s"
  env "$s" $PY -m pytest -q -p no:cacheprovider $TESTS || status=1
done
exit $status
