"""Solved curve error of penalty:10+6tvd on the 221-pair joint (benchmarks/friction.py's definition)
without the Craig-Bampton sweep of `make bench-friction-fine` (hours): the ROM swept with its located
peaks, the exact condensation swept without them to seed Newton, then the exact problem solved at
each of the ROM's omegas.  About 10 min; prints its numbers (docs/benchmarks_friction_fine.md).

    .venv/bin/python benchmarks/friction_fine_penalty.py
"""
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from friction import solved_curve_error
from jointfem.analysis.compare import parse_method
from jointfem.analysis.frf import compute_frf, create_problem
from jointfem.app import sweep_options
from jointfem.rom import RomOptions, build_rom
from jointfem.scene import create_structure, load_scene
scene = load_scene(ROOT / "demos" / "lap3d_friction_fine.toml")
st = create_structure(scene)
sweep = sweep_options(scene, stability="off", peak_share=0.0)
t = time.perf_counter()
spec = parse_method("penalty:10:6", RomOptions())
rom = build_rom(st, spec.method, spec.options)
off = time.perf_counter() - t
t = time.perf_counter()
pen = compute_frf(rom, sweep)
on = time.perf_counter() - t
print(f"penalty:10+6tvd offline {off:.1f} s online {on:.1f} s points {pen.num_points} peak {pen.peak('a_mid.uy')} peak-search {pen.info.get('time_peaks_s')}", flush=True)
t = time.perf_counter()
ex = build_rom(st, "exact")
ref = compute_frf(ex, replace(sweep, locate_peaks=False))
print(f"exact (no peak search) {time.perf_counter() - t:.1f} s points {ref.num_points} max amp {ref.amplitude(ref.outputs['a_mid.uy']).max():.6e}", flush=True)
pb = create_problem(ex, sweep.harmonics)
print("solved curve error % of a_mid.uy:", 100 * solved_curve_error(pen, pb, ref, "a_mid.uy"), flush=True)
