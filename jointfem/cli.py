"""Command line: ``jointfem frf|nma|modes|force|compare|plot|export ...`` (also ``python -m jointfem``).

It parses arguments, calls the library layer (jointfem.app) and prints; nothing else.
"""
from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
import time
from pathlib import Path

from . import defaults
from .contact.law import ContactError
from .continuation.arclength import ContinuationError, ConvergenceError
from .fem.continuum import ContinuumError
from .linalg import LinAlgError
from .results import OutputError
from .rom import METHODS, RomError, RomOptions
from .scene import SceneError, load_scene


def _reduction(args, scene, method: str | None = None, *,
               offline: str = "replicated") -> tuple[str, RomOptions]:
    """The method and the reduction's options: each flag given, else the scene's [reduction] key
    (app.reduction_of)."""
    from .app import reduction_of
    from .rom.reductors import MODAL

    # (the scene's [reduction] counts are checked where it is read: a count out of range is a flag's)
    chosen = scene.reduction.method if method is None else method
    for flag, value in (("--modes", args.modes), ("--tvd", args.tvd)):
        lowest = 1 if flag == "--modes" and chosen in MODAL else 0
        if value is not None and value < 0:  # (0 where the method needs more: rom.check_options says why)
            raise RomError(f"{flag} = {value}: must be >= {lowest}"
                           + (f" ({chosen} needs at least one vibration mode)" if lowest else ""))
    return reduction_of(scene, method, modes=args.modes, tvd=args.tvd, tvd_kind=args.tvd_kind, offline=offline)


def _count(least: int):
    """An argparse type: an integer of at least ``least`` (argparse names the option and exits 2)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if value < least:
            raise argparse.ArgumentTypeError(f"{value} < {least}")
        return value
    return parse


def _rom_args(parser, modes: str = "vibration modes of the ROM",
              tvd: str = "trial-vector derivatives (penalty, tvd)") -> None:
    """--modes, --tvd and --tvd-kind, each defaulting to the scene's [reduction] key (_reduction)."""
    parser.add_argument("--modes", type=int,
                        help=f"{modes} (default: the scene's [reduction] modes, else {defaults.ROM_MODES})")
    parser.add_argument("--tvd", type=int,
                        help=f"{tvd} (default: the scene's [reduction] tvd, else {defaults.ROM_TVD})")
    _tvd_kind_arg(parser)


def _tvd_kind_arg(parser) -> None:
    from .rom.cms import TVD_KINDS
    parser.add_argument("--tvd-kind", choices=TVD_KINDS,
                        help="eigen (default, or the scene's [reduction] tvd_kind): exact eigenvector derivatives "
                             "with respect to each contact stiffness; "
                             "eq12: the paper's static modal derivatives (tvd method; docs/theory.md)")


def cmd_frf(args) -> int:
    from . import app, parallel

    auto = args.harmonics == "auto"  # as the scene's harmonics = "auto", with its rules
    scene = app.override_harmonics(app.override(load_scene(args.scene), args.set + (['solver.harmonics="auto"']
                                                                                     if auto else [])),
                                   None if auto else args.harmonics, args.samples)
    out = Path(args.out) if args.out else Path("results") / scene.name
    t0 = time.perf_counter()
    root = parallel.is_root()
    method, options = _reduction(args, scene, args.method, offline=args.offline)
    resume = None
    if args.resume:
        out = Path(args.out) if args.out else Path(args.resume)
        resume = app.load_resume(Path(args.resume), scene, method, options)
    if root:
        app.check_output(out)  # before any solve
    solution = app.solve_scene(scene, progress=not args.quiet and root, method=method, rom_options=options,
                               stability=args.stability, keep_incomplete=True, resume=resume)
    if not root:  # every rank solved the same replicated problem; rank 0 writes it once
        return 0
    summary = app.write_frf(solution, scene, out, method=method, rom_options=options,
                            mpi_ranks=parallel.size(), wall_start=t0, plots=args.plots)
    if solution.incomplete is not None:
        stop = solution.incomplete
        print(f"jointfem: sweep incomplete: {stop}. The {summary['num_points']} converged points are in {out}/ "
              f"(summary.json status \"incomplete\")", file=sys.stderr)
        return _interrupted_code() if stop.interrupted else 3
    if not args.quiet:
        for name, pk in summary["peaks"].items():
            if pk.get("edge"):  # the largest amplitude at an end of the range: no resonance inside it
                print(f"{name}: no peak inside the range: largest {pk['amp1_m']:.6e} m at its end, "
                      f"{pk['omega_rad_s']:.6f} rad/s ({pk['freq_Hz']:.4f} Hz)")
                continue
            bar = pk.get("change_at_higher_H_m")
            print(f"{name}: peak {pk['amp1_m']:.6e} m" + ("" if bar is None else f" ± {bar:.1e} (its change at H + 2)")
                  + f" at {pk['omega_rad_s']:.6f} rad/s ({pk['freq_Hz']:.4f} Hz)")
        print(_what_is_known(summary))
        print(f"{summary['num_points']} points, {summary['newton_iterations_total']} Newton iterations, "
              f"{summary['wall_s']['total']:.2f} s -> {out}/")
    return 0


def _what_is_known(summary: dict) -> str:
    """The harmonics solved, the truncation estimate and the stability of a sweep, in one line for
    the terminal: what is known of the answer, beside it and not only in summary.json."""
    parts = [f"H = {summary['harmonics']}, N = {summary['samples']}"]
    if (ad := summary.get("harmonics_adaptive")) is not None:
        per = ", ".join(f"{n} at H = {H}" for H, n in ad["points_per_H"].items())
        parts = [f"H chosen along the branch ({per}; target {ad['target']:g}"
                 + ("" if ad["reached"] else f", not met within harmonics_max = {ad['H_max']}") + f"), N = {summary['samples']}"]
    he = summary.get("harmonic_error")
    if he is not None:
        parts.append(f"truncation estimate up to {he['max']:.3g}" + (" (not converged in H: see the warning)"
                                                                      if "warning" in he else ""))
    stab = summary.get("stability")
    if stab is not None:
        if "unstable_points" in stab:
            parts.append(f"stability computed: {stab['unstable_points']} of {summary['num_points']} points unstable")
        else:
            parts.append(f"stability {stab['status']}")
    return "; ".join(parts)


def cmd_modes(args) -> int:
    from . import app
    from .scene import create_structure

    scene = app.override(load_scene(args.scene), args.set)
    out = Path(args.out) if args.out else Path("results") / f"{scene.name}_modes"
    app.check_output(out)
    structure = create_structure(scene)
    modes = app.linear_modes(structure, args.num)
    app.write_modes(modes, structure, out)
    if not args.quiet:
        st, fr = modes["stuck"], modes["free"]
        lo, hi = scene.solver.omega_min, scene.solver.omega_max
        print(f"{'mode':>4}  {'stuck [rad/s]':>14} {'[Hz]':>10} {'zeta':>9}   {'free [rad/s]':>14} {'[Hz]':>10}")
        for k in range(st["omega_rad_s"].size):
            w = st["omega_rad_s"][k]
            mark = "  <- in omega_range" if lo <= w <= hi else ""
            print(f"{k + 1:>4}  {w:14.6g} {st['freq_Hz'][k]:10.5g} {st['damping_ratio'][k]:9.3g}   "
                  f"{fr['omega_rad_s'][k]:14.6g} {fr['freq_Hz'][k]:10.5g}{mark}")
        print(f"-> {out}/")
    return 0


def cmd_force(args) -> int:
    from . import app, parallel
    from .analysis.force import ForceIncomplete, compute_force_response
    from .harmonics import Harmonics
    from .rom import build_rom
    from .scene import check_solvable, create_structure

    scene = app.override_harmonics(app.override(load_scene(args.scene), args.set), args.harmonics, args.samples)
    app.at_one_harmonics(scene, "a force sweep is solved at one H")
    out = Path(args.out) if args.out else Path("results") / f"{scene.name}_force"
    if not args.omega > 0:
        raise SceneError("--omega", "omega", args.omega, "must be > 0 rad/s")
    lo, hi = args.scale
    if not 0 < lo < hi:
        raise SceneError("--scale", "scale", [lo, hi], "must be 0 < start < end")
    method, options = _reduction(args, scene, args.method)
    resume = None
    if args.resume:
        out = Path(args.out) if args.out else Path(args.resume)
        resume = app.load_force_resume(Path(args.resume), scene, method, options, args.omega)
    if parallel.is_root():
        app.check_output(out)
    check_solvable(scene)
    structure = create_structure(scene)
    app.check_resources(scene, structure)
    model = structure if method == "full" else build_rom(structure, method, options)
    app.check_time(scene, model, Harmonics(scene.solver.harmonics, scene.solver.samples), args.omega)
    opts = app.sweep_options(scene, stability="off").continuation
    stopped = None
    try:
        resp = compute_force_response(model, args.omega, Harmonics(scene.solver.harmonics, scene.solver.samples),
                                      lo, hi, opts, resume=resume)
    except ForceIncomplete as exc:  # the points so far are written, marked incomplete
        resp, stopped = exc.response, exc
    if not parallel.is_root():
        return 0
    summary = app.write_force(resp, scene, out, method=method, rom_options=options, structure=structure,
                              rom=None if method == "full" else model)
    if stopped is not None:
        print(f"jointfem: force sweep incomplete: {stopped}. The {summary['num_points']} converged points are in "
              f"{out}/ (summary.json status \"incomplete\"; go on with --resume {out})", file=sys.stderr)
        return _interrupted_code() if stopped.interrupted else 3
    if not args.quiet:
        print(f"{summary['num_points']} points from scale {lo:g} to {resp.scale[-1]:.6g} at {args.omega:g} rad/s "
              f"-> {out}/")
    return 0


def cmd_nma(args) -> int:
    from . import app, parallel

    scene = app.override_harmonics(app.override(load_scene(args.scene), args.set), args.harmonics, args.samples)
    app.at_one_harmonics(scene, "a nonlinear mode is followed at one H")
    out = Path(args.out) if args.out else Path("results") / f"{scene.name}_nma"
    if args.mode is not None and args.mode < 1:
        raise SceneError("--mode", "mode", args.mode, "must be >= 1 (1 = the lowest mode)")
    if args.frf is not None and not (Path(args.frf) / "branch.npz").is_file():
        raise SceneError("--frf", "frf", args.frf, "is not a result folder of `jointfem frf` (no branch.npz in it)")
    app.nma_options(scene, mode=args.mode)  # a scene without [nma]: one line, before any work
    t0 = time.perf_counter()
    method, options = _reduction(args, scene, args.method)
    if parallel.is_root():
        app.check_output(out)
    solution = app.solve_nma(scene, method=method, rom_options=options, mode=args.mode,
                             progress=not args.quiet and parallel.is_root())
    if not parallel.is_root():
        return 0
    summary = app.write_nma(solution, scene, out, method=method, rom_options=options,
                            frf_folder=Path(args.frf) if args.frf else None, wall_start=t0)
    if args.plots and solution.structure.num_pairs:
        from .viz import plot_folder

        plot_folder(out)
    if solution.incomplete is not None:
        stop = solution.incomplete
        print(f"jointfem: backbone incomplete: {stop}. The {summary['num_points']} converged points are in {out}/ "
              f"(summary.json status \"incomplete\")", file=sys.stderr)
        return _interrupted_code() if stop.interrupted else 3
    if not args.quiet:
        lin = summary["linear"]
        print(f"mode {summary['mode']}: stuck {lin['omega_rad_s']:.6g} rad/s ({lin['freq_Hz']:.5g} Hz), "
              f"zeta {lin['damping_ratio']:.3g}")
        lo, hi = summary["omega_range_rad_s"]
        zl, zh = summary["damping_ratio_range"]
        print(f"amplitude {summary['amplitude_range_m'][0]:.3g} to {summary['amplitude_range_m'][1]:.3g} m at "
              f"{summary['output']}: omega {lo:.6g} to {hi:.6g} rad/s, zeta {zl:.3g} to {zh:.3g}; "
              f"{summary['num_points']} points, {summary['wall_s']['total']:.2f} s -> {out}/")
    return 0


def cmd_export(args) -> int:
    from .export import export_point

    paths = export_point(args.folder, point=args.point, omega=args.omega, out=args.out)
    if not args.quiet:
        for p in paths:
            print(f"wrote {p}")
    return 0


def cmd_compare(args) -> int:
    from . import app

    scene = app.override_harmonics(app.override(load_scene(args.scene), args.set), args.harmonics, args.samples)
    out = Path(args.out) if args.out else Path("results") / f"{scene.name}_compare"

    def progress(label):
        if not args.quiet:
            print(f"jointfem compare: {label} ...", file=sys.stderr, flush=True)

    options = _reduction(args, scene)[1]
    if args.analysis == "nma":
        app.nma_options(scene)  # a scene without [nma]: one line, before any work
        app.check_output(out)
        md = app.compare_nma_scene(scene, args.methods, options, out=out, reference=args.reference,
                                   progress=progress)
    else:
        md = app.compare_scene(scene, args.methods, options, out=out, output=args.output,
                               reference=args.reference, progress=progress, stability=args.stability)
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


def _set_arg(p) -> None:
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene key (repeatable): force.amplitude=3.0, solver.omega_range=[1600,1700], "
                        "jenkins[0].mu=0.2; the scene is validated again as a whole")


def _harmonics_arg(text: str) -> int | str:
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer or auto, not {text!r}") from None


def _stability_arg(p) -> None:
    p.add_argument("--stability", choices=("auto", "on", "off"),
                   help="Floquet exponents of every point (Hill's method; default: the scene's [solver] stability, "
                        "else auto): auto computes them wherever "
                        "the method has Hill matrices, at any size, but for the exact condensation (whose Hill "
                        "problem is the full model's); on computes them there too; off skips them")


def build_parser() -> argparse.ArgumentParser:
    from .version import installed_version

    p = argparse.ArgumentParser(prog="jointfem", description="Nonlinear vibration of jointed structures (HBM).")
    p.add_argument("--version", action="version", version=f"jointfem {installed_version()}")
    sub = p.add_subparsers(dest="command", required=True)
    f = sub.add_parser("frf", help="nonlinear frequency response of a scene")
    f.add_argument("scene", help="scene file (TOML)")
    f.add_argument("--out", help="output folder (default results/<scene name>)")
    f.add_argument("--harmonics", type=_harmonics_arg,
                   help='number of harmonics H, or "auto" (H chosen along the branch; overrides the scene)')
    f.add_argument("--samples", type=int, help="AFT time samples N >= 2H+1 (overrides the scene)")
    f.add_argument("--method", choices=METHODS,
                   help="model reduction (default: the scene's [reduction] method, else full order)")
    _rom_args(f)
    f.add_argument("--offline", choices=("replicated", "distributed"), default="replicated",
                   help="penalty on a continuum scene: replicated (default: every MPI rank holds K, M and the basis) "
                        "or distributed (they stay in row blocks on the ranks; the deformed shape is not written)")
    f.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    f.add_argument("--plots", action="store_true", help="also the contact-state pictures (as `jointfem plot`)")
    f.add_argument("--resume", metavar="DIR", help="go on with the incomplete sweep in DIR (same scene, method, H, N), "
                   "from its last point with the step it would have taken; writes the whole branch to --out "
                   "(default DIR)")
    _stability_arg(f)
    _set_arg(f)
    f.set_defaults(func=cmd_frf)
    mo = sub.add_parser("modes", help="the linear modes with the joint stuck and free (CSV, NPZ): where to sweep")
    mo.add_argument("scene", help="scene file (TOML)")
    mo.add_argument("--num", type=_count(1), default=10, help="number of modes (default 10)")
    mo.add_argument("--out", help="output folder (default results/<scene name>_modes)")
    mo.add_argument("--quiet", action="store_true")
    _set_arg(mo)
    mo.set_defaults(func=cmd_modes)
    fo = sub.add_parser("force", help="the response against the force amplitude at one omega (continuation)")
    fo.add_argument("scene", help="scene file (TOML)")
    fo.add_argument("--omega", type=float, required=True, help="the fixed frequency, rad/s")
    fo.add_argument("--scale", type=float, nargs=2, default=(0.01, 1.0), metavar=("START", "END"),
                    help="the range of the factor on every force of the scene (default 0.01 1)")
    fo.add_argument("--out", help="output folder (default results/<scene name>_force)")
    fo.add_argument("--resume", metavar="DIR", help="go on with the incomplete force sweep in DIR (same scene, "
                    "omega, method, H, N); writes the whole branch into --out (default DIR)")
    fo.add_argument("--harmonics", type=int, help="number of harmonics H (overrides the scene)")
    fo.add_argument("--samples", type=int, help="AFT time samples N >= 2H+1 (overrides the scene)")
    fo.add_argument("--method", choices=METHODS,
                   help="model reduction (default: the scene's [reduction] method, else full order)")
    _rom_args(fo)
    fo.add_argument("--quiet", action="store_true")
    _set_arg(fo)
    fo.set_defaults(func=cmd_force)
    nm = sub.add_parser("nma", help="a nonlinear mode: frequency and damping against amplitude (EPMC)")
    nm.add_argument("scene", help="scene file (TOML) with an [nma] table")
    nm.add_argument("--mode", type=int, help="the stuck linear mode to follow (overrides [nma] mode; 1 = lowest)")
    nm.add_argument("--out", help="output folder (default results/<scene name>_nma)")
    nm.add_argument("--frf", metavar="DIR", help="a `jointfem frf` result folder to overlay on the synthesised FRF")
    nm.add_argument("--harmonics", type=int, help="number of harmonics H (overrides the scene)")
    nm.add_argument("--samples", type=int, help="AFT time samples N >= 2H+1 (overrides the scene)")
    nm.add_argument("--method", choices=METHODS,
                    help="model reduction (default: the scene's [reduction] method, else full order; exact: the "
                         "condensation on the gaps, the same "
                         "backbone as full order)")
    _rom_args(nm)
    nm.add_argument("--quiet", action="store_true")
    nm.add_argument("--plots", action="store_true",
                    help="also the contact-state pictures (as `jointfem plot`; 'peak' is the largest amplitude)")
    _set_arg(nm)
    nm.set_defaults(func=cmd_nma)
    ex = sub.add_parser("export", help="ParaView files (VTU, XDMF) of a result folder at one branch point")
    ex.add_argument("folder", help="a folder written by `jointfem frf`, `jointfem nma` or `jointfem force`")
    grp = ex.add_mutually_exclusive_group()
    grp.add_argument("--point", default="peak", help="'peak' (default: the largest amplitude) or a branch point index")
    grp.add_argument("--omega", type=float, help="the branch point nearest to this omega, rad/s (not for a force "
                                                  "sweep, all at one omega)")
    ex.add_argument("--out", help="output folder (default FOLDER/export)")
    ex.add_argument("--quiet", action="store_true")
    ex.set_defaults(func=cmd_export)
    pp = sub.add_parser("plot", help="contact-state pictures of a result folder (PNG, off-screen)")
    pp.add_argument("folder", help="a folder written by `jointfem frf`, `jointfem nma` or `jointfem force`")
    grp = pp.add_mutually_exclusive_group()
    grp.add_argument("--point", default="peak", help="'peak' (default: the largest amplitude) or a branch point index")
    grp.add_argument("--omega", type=float, help="the branch point nearest to this omega, rad/s (not for a force "
                                                  "sweep, all at one omega)")
    pp.add_argument("--quiet", action="store_true")
    pp.set_defaults(func=cmd_plot)
    c = sub.add_parser("compare", help="every ROM against full order: sizes, times, errors (CSV, Markdown, PNG)")
    c.add_argument("scene", help="scene file (TOML)")
    c.add_argument("--methods", default=None,
                   help=f"comma-separated name[:modes[:tvd[:kind]]] (default {defaults.COMPARE_METHODS}, less the "
                        f"substructure methods on a model that defines no substructures)")
    _rom_args(c, modes="modes for the methods given without", tvd="TVDs for the methods given without")
    c.add_argument("--output", help="output DOF the errors are measured on (default: the scene's first)")
    c.add_argument("--analysis", choices=("frf", "nma"), default="frf",
                   help="frf (default): forced responses; nma: nonlinear modes of the scene's [nma] table, errors "
                        "in frequency and damping over its amplitude range")
    c.add_argument("--reference", choices=("full", "exact"), default="full",
                   help="reference solution: full order (default) or the exact condensation (same solution, "
                        "cheaper for a large continuum)")
    c.add_argument("--out", help="output folder (default results/<scene name>_compare)")
    c.add_argument("--harmonics", type=int, help="number of harmonics H (overrides the scene)")
    c.add_argument("--samples", type=int, help="AFT time samples N >= 2H+1 (overrides the scene)")
    c.add_argument("--quiet", action="store_true", help="no progress or table on the terminal")
    _stability_arg(c)
    _set_arg(c)
    c.set_defaults(func=cmd_compare)
    return p


_SIGNAL = [signal.SIGINT]  # the last signal that interrupted the run


def _stop_on_signal(signum, frame):
    """SIGTERM and SIGHUP (a batch scheduler's wall-time limit, `timeout`, a closed terminal) stop the
    run as Ctrl-C does: a sweep keeps its converged points and writes them, status incomplete."""
    _SIGNAL[0] = signum
    raise KeyboardInterrupt(signal.Signals(signum).name)


def _interrupted_code() -> int:
    """The shell's code for a run stopped by a signal: 128 + its number (130 Ctrl-C, 143 SIGTERM)."""
    return 128 + int(_SIGNAL[0])


def _signal_policy() -> dict:
    """One policy for every command: SIGINT raises KeyboardInterrupt (Python's own handler, which
    gmsh takes away: jointfem.fem.compat.restore_sigint puts it back), SIGTERM and SIGHUP likewise
    (_stop_on_signal).  Returns the handlers it replaced, which main() puts back when it returns:
    a program that calls main() (a test, a script) keeps its own handling after it."""
    if threading.current_thread() is not threading.main_thread():
        return {}  # (main() called from a thread: signals are the main thread's)
    # a signal ignored when the run started stays ignored (nohup ignores SIGHUP; a shell's background
    # job SIGINT), as Python itself leaves an ignored SIGINT
    return {sig: signal.signal(sig, _stop_on_signal) for sig in (signal.SIGTERM, signal.SIGHUP)
            if signal.getsignal(sig) == signal.SIG_DFL}


def main(argv=None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    args = build_parser().parse_args(argv)
    _SIGNAL[0] = signal.SIGINT
    replaced = _signal_policy()
    try:
        # warnings go through tqdm.write: above the progress bar, each on its own line, not onto it
        from tqdm.contrib.logging import logging_redirect_tqdm

        with logging_redirect_tqdm():
            return args.func(args)
    except KeyboardInterrupt:  # outside a sweep (a sweep keeps its points and returns 130 itself)
        print(f"jointfem: interrupted ({signal.Signals(_SIGNAL[0]).name})", file=sys.stderr)
        return _interrupted_code()
    except (SceneError, ConvergenceError, ContinuationError, ContactError, OutputError, RomError,
            LinAlgError, ContinuumError) as exc:
        from . import parallel

        if parallel.is_root():  # under mpirun every rank meets the same error: one line, not one per rank
            print(f"jointfem: error: {exc}", file=sys.stderr)
        return 2
    finally:
        for sig, handler in replaced.items():
            signal.signal(sig, handler)


if __name__ == "__main__":
    sys.exit(main())
