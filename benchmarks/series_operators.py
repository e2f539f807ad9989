"""The exact condensation's per-omega cost on one scene: the modal path's stiff-mode series against
summing every mode (issue 17; docs/theory.md, "Stiff modes as a series").

    .venv/bin/python benchmarks/series_operators.py demos/lap3d_friction_fine.toml

Prints the dense eigendecomposition's time (offline), the time to form the series at the first
omega, how many modes are summed one by one, the seconds per new omega of each way over five more
omegas across the scene's range, and how far apart their dynamic stiffnesses S lie.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None) -> int:
    from jointfem.harmonics import Harmonics
    from jointfem.hbm.condensed import CondensedProblem, modal_basis
    from jointfem.scene import create_structure, load_scene

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene", type=Path)
    args = ap.parse_args(argv)
    scene = load_scene(args.scene)
    t = time.perf_counter()
    s = create_structure(scene)
    print(f"model: {s.num_dofs} DOFs, {s.num_pairs} pairs, {time.perf_counter() - t:.1f} s", flush=True)
    t = time.perf_counter()
    basis = modal_basis(s, required=True)
    print(f"eigendecomposition (offline): {time.perf_counter() - t:.1f} s, Rayleigh {basis.rayleigh}", flush=True)
    if basis.rayleigh is None:
        print("no Rayleigh damping: the series is not used")
        return 1
    h = Harmonics(scene.solver.harmonics, scene.solver.samples)
    omegas = np.linspace(scene.solver.omega_start, scene.solver.omega_end, 6)
    series = CondensedProblem(s, h, modal=basis)
    every = CondensedProblem(s, h, modal=dataclasses.replace(basis, rayleigh=None))
    t = time.perf_counter()
    series._operators(float(omegas[0]))
    print(f"first omega, forming the series: {time.perf_counter() - t:.1f} s; modes summed one by one: "
          f"{int(series._split[3].sum())} of {s.num_dofs}; retained coordinates r = {series.r}", flush=True)
    every._operators(float(omegas[0]))
    for name, pb in (("series", series), ("every mode", every)):
        t = time.perf_counter()
        for w in omegas[1:]:
            pb._operators(float(w))
        print(f"{name}: {(time.perf_counter() - t) / (omegas.size - 1):.3f} s per new omega", flush=True)
    d = max(float(np.abs(a.S - b.S).max() / np.abs(b.S).max())
            for a, b in zip(series._operators(float(omegas[-1])), every._operators(float(omegas[-1]))))
    print(f"S, series against every mode: {d:.1e} of its largest entry")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
