"""Record the converged points of a fixed set of sweeps, to check that a refactor changes nothing.

    python tools/record_points.py OUT.npz            # record
    python tools/record_points.py OUT.npz --against BASE.npz   # record and compare (max abs diff)

Cases: the SDOF and beam scenes at full order, the beam with penalty:10+3tvd and cb:10, and the
3D lap joint (coarse mesh) with penalty:10 and the exact condensation.  Each case stores omega
and U of every point.  It goes through the public entry points of its own tree only.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _solve(scene, method, modes=10, tvd=0):
    try:
        from jointfem.app import solve_scene
    except ImportError:  # before the library layer existed
        from jointfem.cli import solve_scene
    from jointfem.rom import RomOptions

    res = solve_scene(scene, method=method, rom_options=RomOptions(modes=modes, tvd=tvd))
    frf = res[1] if isinstance(res, tuple) else res.frf
    return frf


def cases():
    from jointfem.scene import load_scene, parse_scene

    sdof = load_scene(ROOT / "demos" / "sdof_jenkins.toml")
    beam = load_scene(ROOT / "demos" / "beam2d.toml")
    import tomllib

    data = tomllib.loads((ROOT / "demos" / "lap3d.toml").read_text())
    data["mesh"].update(size=0.02)
    data["mesh"].pop("file", None)
    data["force"]["amplitude"] = 2.0
    lap = parse_scene(data, path=ROOT / "demos" / "lap3d_coarse.toml")
    yield "sdof_full", sdof, "full", 0, 0
    yield "beam_full", beam, "full", 0, 0
    yield "beam_penalty10_3", beam, "penalty", 10, 3
    yield "beam_cb10", beam, "cb", 10, 0
    yield "lap3d_penalty10", lap, "penalty", 10, 0
    yield "lap3d_exact", lap, "exact", 0, 0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--against")
    args = ap.parse_args()
    data = {}
    for name, scene, method, modes, tvd in cases():
        t0 = time.perf_counter()
        frf = _solve(scene, method, modes, tvd)
        data[f"{name}.omega"], data[f"{name}.U"] = frf.omega, frf.U
        print(f"{name}: {frf.num_points} points, {time.perf_counter() - t0:.1f} s", flush=True)
    np.savez(args.out, **data)
    if args.against:
        base = np.load(args.against)
        worst = 0.0
        for k in sorted(base.files):
            a, b = base[k], data[k]
            if a.shape != b.shape:
                print(f"{k}: shape {a.shape} -> {b.shape}")
                worst = np.inf
                continue
            d = float(np.abs(a - b).max() / max(np.abs(a).max(), 1e-300))
            worst = max(worst, d)
            print(f"{k}: {a.shape}, max relative difference {d:.3e}")
        print(f"worst {worst:.3e}")
        sys.exit(0 if worst <= 1e-12 else 1)


if __name__ == "__main__":
    main()
