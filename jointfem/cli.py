"""Command line: ``jointfem frf SCENE ...`` (also ``python -m jointfem``)."""
from __future__ import annotations

import argparse
import dataclasses
import logging
import sys
import time
from pathlib import Path

from .continuation.arclength import ContinuationError, ContinuationOptions, ConvergenceError, NewtonOptions
from .contact.jenkins import ContactError
from .results import OutputError
from .scene import Scene, SceneError, create_structure, load_scene

METHODS = ("full",)


def _override(scene: Scene, args) -> Scene:
    """Apply --harmonics/--samples, re-validating with the scene's own rules."""
    s = scene.solver
    H = args.harmonics if args.harmonics is not None else s.harmonics
    N = args.samples if args.samples is not None else (s.samples if s.samples >= 2 * H + 1 else max(256, 4 * H + 4))
    if H < 1:
        raise SceneError("--harmonics", "harmonics", H, "must be an integer >= 1")
    if N < 2 * H + 1:
        raise SceneError("--samples", "samples", N, f"must be >= 2*harmonics+1 = {2 * H + 1}")
    return dataclasses.replace(scene, solver=dataclasses.replace(s, harmonics=H, samples=N))


def solve_scene(scene: Scene, *, progress: bool = False):
    """Build the model of a scene and compute its FRF.  Returns (structure, frf, seconds_build)."""
    from .frf import SweepOptions, compute_frf
    from .hbm.harmonics import Harmonics

    t0 = time.perf_counter()
    structure = create_structure(scene)
    t_build = time.perf_counter() - t0
    s = scene.solver
    opts = SweepOptions(
        omega_start=s.omega_start, omega_end=s.omega_end, harmonics=Harmonics(s.harmonics, s.samples),
        continuation=ContinuationOptions(ds0=s.ds0, ds_min=s.ds_min, ds_max=s.ds_max, max_points=s.max_points,
                                         newton=NewtonOptions(tol=s.tol)))
    bar = None
    callback = None
    if progress:
        from tqdm import tqdm

        span = abs(s.omega_end - s.omega_start)
        bar = tqdm(total=round(span, 6), unit="rad/s", desc=f"{scene.name} omega", file=sys.stderr,
                   bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.4g}/{total:.4g} rad/s [{elapsed}<{remaining}]"
                              "{postfix}")

        def callback(point):
            done = min(abs(point.lam - s.omega_start), span)
            if done > bar.n:
                bar.update(done - bar.n)
            bar.set_postfix_str(f"omega={point.lam:.6g} newton={point.iterations}", refresh=False)

    try:
        frf = compute_frf(structure, opts, callback=callback)
    finally:
        if bar is not None:
            bar.close()
    return structure, frf, t_build


def cmd_frf(args) -> int:
    scene = _override(load_scene(args.scene), args)
    out = Path(args.out) if args.out else Path("results") / scene.name
    t0 = time.perf_counter()
    structure, frf, t_build = solve_scene(scene, progress=not args.quiet)
    from .results import save_frf

    summary = {
        "scene": str(scene.path), "scene_data": scene.data, "kind": scene.kind, "method": args.method,
        "model": {"num_dofs": structure.num_dofs, "num_pairs": structure.num_pairs},
        "rom": {"num_dofs": structure.num_dofs, "note": "full order: the ROM is the model"},
        "harmonics": scene.solver.harmonics, "samples": scene.solver.samples,
        "num_unknowns": frf.info["num_unknowns"],
        "omega_start_rad_s": scene.solver.omega_start, "omega_end_rad_s": scene.solver.omega_end,
        "wall_s": {"build": t_build, "setup": frf.info["time_setup_s"], "continuation": frf.info["time_online_s"],
                   "total": time.perf_counter() - t0},
    }
    summary = save_frf(frf, out, summary=summary)
    from .plots import plot_frf

    plot_frf(frf, out / "frf.png", title=f"{scene.name} ({args.method}, H={scene.solver.harmonics})")
    logging.getLogger("jointfem").info("wrote %s", out)
    if not args.quiet:
        for name, pk in summary["peaks"].items():
            print(f"{name}: peak {pk['amp1_m']:.6e} m at {pk['omega_rad_s']:.6f} rad/s ({pk['freq_Hz']:.4f} Hz)")
        print(f"{summary['num_points']} points, {summary['newton_iterations_total']} Newton iterations, "
              f"{summary['wall_s']['total']:.2f} s -> {out}/")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="jointfem", description="Nonlinear vibration of jointed structures (HBM).")
    sub = p.add_subparsers(dest="command", required=True)
    f = sub.add_parser("frf", help="nonlinear frequency response of a scene")
    f.add_argument("scene", help="scene file (TOML)")
    f.add_argument("--out", help="output folder (default results/<scene name>)")
    f.add_argument("--harmonics", type=int, help="number of harmonics H (overrides the scene)")
    f.add_argument("--samples", type=int, help="AFT time samples N >= 2H+1 (overrides the scene)")
    f.add_argument("--method", choices=METHODS, default="full", help="model reduction (only full order so far)")
    f.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    f.set_defaults(func=cmd_frf)
    return p


def main(argv=None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (SceneError, ConvergenceError, ContinuationError, ContactError, OutputError) as exc:
        print(f"jointfem: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
