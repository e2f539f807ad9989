# jointfem: `make demo` and `make test` each do the whole set-up first (idempotent).
PY := .venv/bin/python
MPIRUN := mpirun $(if $(filter 0,$(shell id -u)),--allow-run-as-root) --oversubscribe

.PHONY: setup demo test test-fast bench clean

setup:
	@bash tools/setup.sh

demo: setup
	$(PY) -m jointfem frf demos/beam2d.toml --out results/beam2d
	$(PY) demos/jointed_beam_levels.py --out results/beam2d_levels

test: setup
	$(PY) -m pytest -q tests

bench: setup
	$(PY) benchmarks/bench.py --out docs/benchmarks.md

clean:
	rm -rf results .pytest_cache
