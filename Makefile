# jointfem: `make demo` and `make test` each do the whole set-up first (idempotent).
PY := .venv/bin/python
MPIRUN := mpirun $(if $(filter 0,$(shell id -u)),--allow-run-as-root) --oversubscribe

.PHONY: setup demo test test-portability test-trixie test-fast bench-robustness bench bench-corners bench-scaling bench-scaling-distributed bench-online bench-sweep500 bench-harmonics bench-truncation bench-friction bench-friction-fine bench-exact bench-stability bench-nma bench-preload brb paper validate clean

setup:
	@bash tools/setup.sh

# the beam at 3 N converged (harmonics chosen along the branch, exact condensation, every point's
# stability; demos/beam2d_converged.toml), then its friction-dominated variant at three forcing
# levels, converged the same way (demos/jointed_beam_levels.py)
demo: setup
	$(PY) -m jointfem frf demos/beam2d_converged.toml --out results/beam2d_converged
	$(PY) demos/jointed_beam_levels.py --out results/beam2d_levels

# the suite on up to TEST_JOBS pytest-xdist workers (the machine's cores, at most 4), each with one
# BLAS thread and one numba thread so that the workers do not oversubscribe the cores (the sweeps
# already run BLAS on one thread, linalg.sweep_blas; the AFT kernels' prange loops take every core
# by default, and GNU OpenMP's waiting threads then spin: in the lap3d strong-separation sweep the AFT
# kernel took 33 s beside another job against 4.5 s alone, both under cProfile; with one numba
# thread the sweep took 54 s beside another job); tests/conftest.py orders the tests longest first, and xdist's
# load scheduling hands them out in that order as workers free up
TEST_JOBS ?= $(shell n=$$(nproc 2>/dev/null || echo 1); echo $$(( n < 4 ? n : 4 )))
PYTEST_PAR := OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 $(PY) -m pytest -q -n $(TEST_JOBS) --dist load

test: setup
	$(PYTEST_PAR) tests

# the suite without its slow tests (those marked by hand, and those over tests/conftest.py SLOW_S
# seconds in tests/durations.json, tools/record_durations.py), for a developer's quick answer
test-fast: setup
	$(PYTEST_PAR) -m "not slow" tests

# issue 51: the precision-sensitive tests under other CPU families' OpenBLAS kernels and one BLAS
# thread, those this CPU can run (tools/test_portability.sh; --all for the whole suite). Not part of
# `make test`: about 15 minutes per setting on 2 cores.
test-portability: setup
	bash tools/test_portability.sh

# issue 52: the strong-separation sweeps of tests/test_corners.py under two OpenBLAS kernels and with
# K perturbed by 1e-15 (5 seeds each): completion and the spread of the peaks (over an hour of CPU: 80-225 s a run)
bench-robustness: setup
	$(PY) benchmarks/robustness.py --out docs/benchmarks_robustness.md --cores host Haswell --seeds 5 --jobs 2

# issue 20: the whole suite on Debian 13's stack (dolfinx 0.9, PETSc/SLEPc 3.22, numpy 2) inside a
# Debian 13 root built by mmdebstrap in /work/trixie-root (TRIXIE_ROOT=...) the first time and reused
# after; tools/setup.sh runs inside it. Needs root. Not part of `make test`.
test-trixie:
	bash tools/test_trixie.sh

bench: setup
	$(PY) benchmarks/bench.py --out docs/benchmarks.md
	$(PY) benchmarks/nma.py --out docs/benchmarks_nma.md
	$(PY) demos/brb.py --out docs
	$(PY) benchmarks/sweep_500.py --out docs/benchmarks_sweep500.md

# issue 17's 525-pair joint (100k DOFs): the penalty ROM's sweep of a stick-slip level to completion,
# set against Craig-Bampton's cost per Newton iteration (docs/benchmarks_sweep500.md; also in make bench)
bench-sweep500: setup
	$(PY) benchmarks/sweep_500.py --out docs/benchmarks_sweep500.md

# issue 16's Brake-Reuss beam: free-free on its supports, the static preload of its three bolts, the
# mode-1 backbone and the FRF at three levels, the penalty ROM against the exact condensation
# (docs/brb.md; also part of `make bench`)
brb: setup
	$(PY) demos/brb.py --out docs

# issue 14's sweeps at strong separation, each under a time budget (about 30 min on 2 cores)
bench-corners: setup
	$(PY) benchmarks/corners.py --out docs/benchmarks_corners.md --jobs 2 --skip-before

# issue 17's scaling laws: the offline stages against DOFs and pairs, 1 and 2 MPI ranks, and a model
# of 500k DOFs (docs/benchmarks_scaling.md, docs/img/scaling.png; docs/scaling.md reads them; 16 min)
bench-scaling: setup
	$(PY) benchmarks/scaling.py --out docs/benchmarks_scaling.md

# issue 17's distributed offline stage: the same laws with K, M and the static modes kept in row blocks
# (docs/benchmarks_scaling_distributed.md, docs/img/scaling_distributed.png; a model of 525k DOFs)
bench-scaling-distributed: setup
	$(PY) benchmarks/scaling.py --distributed --out docs/benchmarks_scaling_distributed.md

# issue 17's online scaling: one Newton iteration of the penalty ROM, CB and the exact condensation at
# a stick-slip state against DOFs and pairs (docs/benchmarks_online.md, docs/img/online.png)
bench-online: setup
	$(PY) benchmarks/online_scaling.py --out docs/benchmarks_online.md

# issue 46's truncation estimate against the truth at the located peaks: the SDOF Jenkins oscillator,
# two masses at a 3:1 superharmonic resonance, the beam at 3 N (docs/benchmarks_truncation.md; the
# lumped cases in a minute, the beam in about 12 min)
bench-truncation: setup
	$(PY) benchmarks/truncation.py --out docs/benchmarks_truncation.md

# issue 14's harmonic convergence: the beam at 3 N, exact condensation with the event-accurate AFT,
# H = 3 to 41 (docs/benchmarks_harmonics.md)
bench-harmonics: setup
	$(PY) benchmarks/harmonics.py --out docs/benchmarks_harmonics.md --jobs 2

# issue 14's stability of the beam at a converged H (41): Hill's method at every point of the 3 N sweep
# against Newmark started on one orbit of each stretch (about 15 min on 2 cores)
bench-stability: setup
	$(PY) benchmarks/stability.py --out docs/benchmarks_stability.md

# issue 13's trade where friction dominates: the 3D lap joint at 1 MPa and the beam with kt = 1e6 N/m, ROMs against the exact
# condensation, and the energy per cycle against the force (about 6 min on 2 cores)
bench-friction: setup
	$(PY) benchmarks/friction.py --out docs/benchmarks_friction.md

# the same joint with 221 pairs: penalty ROM against Craig-Bampton at scale (about an hour on 2 cores;
# docs/benchmarks_friction_fine.md)
bench-friction-fine: setup
	$(PY) benchmarks/friction.py --cases lap3d_fine --out docs/benchmarks_friction_fine.md

# issue 17's exact condensation that scales: the sparse-LU path against the modal path on the same
# sweeps (docs/benchmarks_exact.md; a few minutes)
bench-exact: setup
	$(PY) benchmarks/exact_paths.py --out docs/benchmarks_exact.md

# issue 15's nonlinear modes: SDOF closed form and harmonics, backbone against forced sweeps, the
# beam against full order, the 3D lap joint against the exact condensation, and the dissipation of the
# uniformly preloaded and the bolted lap joint (about 8 min on 2 cores; also part of `make bench`)
bench-nma: setup
	$(PY) benchmarks/nma.py --out docs/benchmarks_nma.md

# issue 16's static preload: the bolted lap joint's and the BRB's contact states against mesh refinement (about 1 min: 61 s measured)
bench-preload: setup
	$(PY) benchmarks/preload.py --out docs/benchmarks_preload.md

paper: setup
	$(PY) demos/paper_figures.py --out docs

validate: setup
	$(PY) demos/validation.py --out docs

clean:
	rm -rf results .pytest_cache
