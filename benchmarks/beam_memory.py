"""Hill's exponents of the paper's beam at 3 N with and without the sliders' memory, at the top of
its converged branch (issue 46, item 4: the 72-against-283 1/s point of docs/benchmarks_stability.md).

    OPENBLAS_NUM_THREADS=1 NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/beam_memory.py [H]

The sweep of demos/beam2d.toml by the exact condensation with the sampled law (the memory is written
for it; the event-accurate law of benchmarks/stability.py has none), H = 41 by default, N = 1024,
stability off; then at about a dozen of its points above 2.88e-4 m the leading exponent of the full
model's Hill problem at the point's full field, without the memory (``memory=False``) and with it
(analysis.stability.with_memory, SuperLU).  About 2 minutes for the sweep, 5 s a point.
"""
import sys
import time

import numpy as np

from jointfem.analysis import stability as st
from jointfem.analysis.frf import compute_frf, create_problem
from jointfem.app import build_rom, create_structure, override, reduction_of, sweep_options
from jointfem.scene import load_scene

OUTPUT = "b1.mid.uy"


def main():
    H = int(sys.argv[1]) if len(sys.argv) > 1 else 41
    scene = override(load_scene("demos/beam2d.toml"), [f"solver.harmonics={H}", "solver.samples=1024"])
    method, options = reduction_of(scene, "exact", None)
    exact = build_rom(create_structure(scene), method, options)
    opts = sweep_options(scene, stability="off")
    t = time.perf_counter()
    frf = compute_frf(exact, opts)
    print(f"sweep H = {H}: {frf.omega.size} points in {time.perf_counter() - t:.0f} s", flush=True)
    amp = frf.amplitude(frf.outputs[OUTPUT])
    problem = create_problem(exact, opts.harmonics)
    top = np.flatnonzero(amp > 2.88e-4)
    print("| omega [rad/s] | amplitude [m] | Hill | with the memory | method |\n|---|---|---|---|---|")
    for i in top[::max(1, top.size // 12)]:
        x, w = frf.U[i], frf.omega[i]
        ev = problem.evaluate(x, w)
        s0 = st.leading_exponent(problem, x, w, ev, dense=False, memory=False)
        s1, _, how = st._leading(problem, x, w, ev, False, st.FIRST)
        print(f"| {w:.4f} | {amp[i]:.6e} | {s0.real:+.3f} ± {s0.imag:.1f}i | {s1.real:+.3f} ± {s1.imag:.1f}i | {how} |",
              flush=True)


if __name__ == "__main__":
    main()
