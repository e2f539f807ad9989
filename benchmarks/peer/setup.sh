#!/usr/bin/env bash
# The peer's own venv: pyHarm needs newer numpy/scipy (and jax) than the system FEniCSx stack, so it
# never shares jointfem's .venv.  Idempotent; pinned to the version the benchmark was written for.
set -euo pipefail
cd "$(dirname "$0")"
if [ ! -x .venv-pyharm/bin/python ] || ! .venv-pyharm/bin/python -c "import pyHarm" 2>/dev/null; then
  echo "peer: creating benchmarks/peer/.venv-pyharm with pyharm-os==1.2.2"
  /usr/bin/python3 -m venv .venv-pyharm
  .venv-pyharm/bin/python -m pip install -q "pyharm-os==1.2.2"
fi
