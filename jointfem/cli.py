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
from .fem.continuum import ContinuumError
from .linalg import LinAlgError
from .results import OutputError
from .rom.common import METHODS, RomError, RomOptions
from .scene import Scene, SceneError, check_solvable, create_structure, load_scene

DEFAULT_COMPARE = "cb,rubin,macneal,dcb,jim,tvd:20:3,penalty"


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


def sweep_options(scene: Scene):
    from .frf import SweepOptions
    from .hbm.harmonics import Harmonics

    s = scene.solver
    return SweepOptions(
        omega_start=s.omega_start, omega_end=s.omega_end, harmonics=Harmonics(s.harmonics, s.samples),
        continuation=ContinuationOptions(ds0=s.ds0, ds_min=s.ds_min, ds_max=s.ds_max, max_points=s.max_points,
                                         newton=NewtonOptions(tol=s.tol, relaxed_kink_tol=max(s.kink_tol, s.tol))))


def solve_scene(scene: Scene, *, progress: bool = False, method: str = "full", rom_options: RomOptions = RomOptions()):
    """Build the model of a scene (and its ROM) and compute its FRF.

    Returns (structure, frf, seconds_build, rom or None).
    """
    from .frf import compute_frf
    from .rom import build_rom

    check_solvable(scene)
    t0 = time.perf_counter()
    structure = create_structure(scene)
    rom = None if method == "full" else build_rom(structure, method, rom_options)
    t_build = time.perf_counter() - t0
    s = scene.solver
    opts = sweep_options(scene)
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
        frf = compute_frf(structure if rom is None else rom, opts, callback=callback)
    finally:
        if bar is not None:
            bar.close()
    return structure, frf, t_build, rom


def _save_shape(structure, rom, out: Path) -> None:
    """shape.npz: node positions and the map from the solved coordinates to the physical DOFs,
    for the deformed-shape picture (continuum models; not for --method exact, whose unknowns are
    the gaps only)."""
    geom = structure.info.get("geometry")
    if geom is None or (rom is not None and not hasattr(rom, "T")):
        return
    import numpy as np

    from .results import _atomic_write

    extra = {} if rom is None else {"recovery": np.asarray(rom.T)}

    def write(p):
        with open(p, "wb") as fh:
            np.savez_compressed(fh, node_coords=geom["node_coords"], dof_node=geom["dof_node"],
                                dof_comp=geom["dof_comp"], **extra)

    _atomic_write(out / "shape.npz", write)


def _rom_options(args) -> RomOptions:
    if args.modes < 0 or args.tvd < 0:
        raise RomError(f"--modes = {args.modes} and --tvd = {args.tvd} must be >= 0")
    return RomOptions(modes=args.modes, tvd=args.tvd)


def cmd_frf(args) -> int:
    from . import parallel

    scene = _override(load_scene(args.scene), args)
    out = Path(args.out) if args.out else Path("results") / scene.name
    t0 = time.perf_counter()
    root = parallel.is_root()
    structure, frf, t_build, rom = solve_scene(scene, progress=not args.quiet and root, method=args.method,
                                               rom_options=_rom_options(args))
    if not root:  # every rank solved the same replicated problem; rank 0 writes it once
        return 0
    from .results import save_frf

    sizes = frf.info["arrays"]["rom_size"]
    rom_info = {"method": args.method, "size_min": int(sizes.min()), "size_max": int(sizes.max()),
                "full_size": structure.num_dofs, "reduction_ratio_max": float(sizes.max() / structure.num_dofs)}
    if rom is not None:
        rom_info.update({"offline_s": rom.offline_s, "modes": args.modes, "tvd": args.tvd,
                         **{k: v for k, v in rom.info.items()}, **frf.info.get("active_set_events", {})})
    summary = {
        "scene": str(scene.path), "scene_data": scene.data, "kind": scene.kind, "method": args.method,
        "model": {"num_dofs": structure.num_dofs, "num_pairs": structure.num_pairs},
        "rom": rom_info,
        "harmonics": scene.solver.harmonics, "samples": scene.solver.samples, "mpi_ranks": parallel.size(),
        "model_timings_s": structure.info.get("timings", {}),
        "num_unknowns": frf.info["num_unknowns"],
        "omega_start_rad_s": scene.solver.omega_start, "omega_end_rad_s": scene.solver.omega_end,
        "wall_s": {"build": t_build, "setup": frf.info["time_setup_s"], "continuation": frf.info["time_online_s"],
                   "total": time.perf_counter() - t0},
    }
    summary = save_frf(frf, out, summary=summary)
    _save_shape(structure, rom, out)
    from .plots import plot_frf

    plot_frf(frf, out / "frf.png", title=f"{scene.name} ({args.method}, H={scene.solver.harmonics})")
    if args.plots and structure.num_pairs:
        from .viz import plot_folder

        for pic in plot_folder(out):
            logging.getLogger("jointfem").info("wrote %s", pic.path)
    logging.getLogger("jointfem").info("wrote %s", out)
    if not args.quiet:
        for name, pk in summary["peaks"].items():
            print(f"{name}: peak {pk['amp1_m']:.6e} m at {pk['omega_rad_s']:.6f} rad/s ({pk['freq_Hz']:.4f} Hz)")
        print(f"{summary['num_points']} points, {summary['newton_iterations_total']} Newton iterations, "
              f"{summary['wall_s']['total']:.2f} s -> {out}/")
    return 0


def cmd_compare(args) -> int:
    from .rom.compare import compare, parse_method, to_markdown

    scene = _override(load_scene(args.scene), args)
    defaults = _rom_options(args)
    specs = [parse_method(m, defaults) for m in args.methods.split(",") if m.strip()]
    check_solvable(scene)
    structure = create_structure(scene)
    output = args.output or next(iter(structure.outputs), None)
    if output not in structure.outputs:
        raise SceneError(args.scene, "--output", output, f"not an output of the scene ({', '.join(structure.outputs)})")
    out = Path(args.out) if args.out else Path("results") / f"{scene.name}_compare"

    def progress(label):
        if not args.quiet:
            print(f"jointfem compare: {label} ...", file=sys.stderr, flush=True)

    results = compare(structure, specs, sweep_options(scene), output=output, progress=progress,
                      reference=args.reference)
    from .plots import plot_compare
    from .results import atomic_write_text, write_table

    rows = [r.row() for r in results]
    write_table(rows, out / "compare.csv")
    md = (f"# {scene.name}: ROMs against {'full order' if args.reference == 'full' else 'the exact condensation'}"
          f"\n\nScene {scene.path}, output {output}, "
          f"H = {scene.solver.harmonics}, N = {scene.solver.samples}, full size {structure.num_dofs}.\n\n"
          + to_markdown(results))
    atomic_write_text(out / "compare.md", md)
    plot_compare(results, output, out / "compare_frf.png", out / "compare_pareto.png", title=scene.name)
    if not args.quiet:
        print(md)
        print(f"-> {out}/")
    return 0


def cmd_plot(args) -> int:
    from .viz import plot_folder

    pics = plot_folder(args.folder, point=args.point, omega=args.omega)
    if not args.quiet:
        for pic in pics:
            print(f"wrote {pic.path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="jointfem", description="Nonlinear vibration of jointed structures (HBM).")
    sub = p.add_subparsers(dest="command", required=True)
    f = sub.add_parser("frf", help="nonlinear frequency response of a scene")
    f.add_argument("scene", help="scene file (TOML)")
    f.add_argument("--out", help="output folder (default results/<scene name>)")
    f.add_argument("--harmonics", type=int, help="number of harmonics H (overrides the scene)")
    f.add_argument("--samples", type=int, help="AFT time samples N >= 2H+1 (overrides the scene)")
    f.add_argument("--method", choices=METHODS, default="full", help="model reduction (default: full order)")
    f.add_argument("--modes", type=int, default=20, help="vibration modes of the ROM (default 20)")
    f.add_argument("--tvd", type=int, default=0, help="trial-vector derivatives (penalty, tvd; default 0)")
    f.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    f.add_argument("--plots", action="store_true", help="also the contact-state pictures (as `jointfem plot`)")
    f.set_defaults(func=cmd_frf)
    pp = sub.add_parser("plot", help="contact-state pictures of a result folder (PNG, off-screen)")
    pp.add_argument("folder", help="a folder written by `jointfem frf`")
    grp = pp.add_mutually_exclusive_group()
    grp.add_argument("--point", default="peak", help="'peak' (default) or a branch point index")
    grp.add_argument("--omega", type=float, help="the branch point nearest to this omega, rad/s")
    pp.add_argument("--quiet", action="store_true")
    pp.set_defaults(func=cmd_plot)
    c = sub.add_parser("compare", help="every ROM against full order: sizes, times, errors (CSV, Markdown, PNG)")
    c.add_argument("scene", help="scene file (TOML)")
    c.add_argument("--methods", default=DEFAULT_COMPARE,
                   help=f"comma-separated name[:modes[:tvd]] (default {DEFAULT_COMPARE})")
    c.add_argument("--modes", type=int, default=20, help="default modes for methods given without (20)")
    c.add_argument("--tvd", type=int, default=0, help="default TVDs for methods given without (0)")
    c.add_argument("--output", help="output DOF the errors are measured on (default: the scene's first)")
    c.add_argument("--reference", choices=("full", "exact"), default="full",
                   help="reference solution: full order (default) or the exact condensation (same solution, "
                        "cheaper for a large continuum)")
    c.add_argument("--out", help="output folder (default results/<scene name>_compare)")
    c.add_argument("--harmonics", type=int, help="number of harmonics H (overrides the scene)")
    c.add_argument("--samples", type=int, help="AFT time samples N >= 2H+1 (overrides the scene)")
    c.add_argument("--quiet", action="store_true", help="no progress or table on the terminal")
    c.set_defaults(func=cmd_compare)
    return p


def main(argv=None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (SceneError, ConvergenceError, ContinuationError, ContactError, OutputError, RomError,
            LinAlgError, ContinuumError) as exc:
        print(f"jointfem: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
