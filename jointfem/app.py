"""The library layer: what the command line, the demos and the benchmarks call.

``solve_scene`` builds a scene's model (and its ROM) and computes its FRF; ``write_frf`` writes a
solved scene's result folder; ``compare_scene`` runs and writes a ROM comparison.  cli.py only
parses arguments and prints.
"""
from __future__ import annotations

import dataclasses
import json
import logging
import os
import re
import shutil
import sys
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .analysis.adaptive import HarmonicAdaptation
from .analysis.frf import Resume, SweepIncomplete, SweepOptions, compute_frf, create_problem
from .continuation.arclength import ContinuationOptions, NewtonOptions
from .defaults import COMPARE_METHODS, default_samples
from .harmonics import Harmonics
from .models.structure import Structure
from .results import FrequencyResponse, OutputError, atomic_write, load_branch
from .rom import RomOptions, build_rom
from .rom.common import Reduction
from .scene import MISSING, Scene, SceneError, check_solvable, create_structure, parse_scene

log = logging.getLogger("jointfem")


def override_harmonics(scene: Scene, harmonics: int | None = None, samples: int | None = None) -> Scene:
    """The scene with H and N replaced (None: keep the scene's), re-validated with the scene's own
    rules; N follows defaults.default_samples when H changes and the scene's N no longer fits."""
    s = scene.solver
    H = harmonics if harmonics is not None else s.harmonics
    N = samples if samples is not None else (s.samples if s.samples >= 2 * H + 1 else default_samples(H))
    if H < 1:
        raise SceneError("--harmonics", "harmonics", H, "must be an integer >= 1")
    if N < 2 * H + 1:
        raise SceneError("--samples", "samples", N, f"must be >= 2*harmonics+1 = {2 * H + 1}")
    auto = s.harmonics_auto and harmonics is None  # --harmonics fixes H
    return dataclasses.replace(scene, solver=dataclasses.replace(
        s, harmonics=H, samples=N, harmonics_auto=auto, samples_given=s.samples_given or samples is not None))


def override(scene: Scene, assignments: list[str]) -> Scene:
    """The scene with ``key=value`` assignments applied (``--set``), re-validated as a whole.

    A key is a dotted path into the scene file: ``force.amplitude``, ``solver.omega_range``,
    ``jenkins[0].mu`` (or ``jenkins.0.mu``; ``force.amplitude`` where the scene has one
    ``[[force]]``).  A value is TOML (``3.0``, ``[1600, 1700]``,
    ``"down"``); anything that is not valid TOML is taken as a string."""
    if not assignments:
        return scene
    data = json.loads(json.dumps(scene.data))
    for item in assignments:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise SceneError("--set", item, MISSING, "must be key=value, e.g. force.amplitude=3.0")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        parts = [p for p in re.split(r"\.|\[(\d+)\]", key) if p]
        node = data
        for i, part in enumerate(parts[:-1]):
            if isinstance(node, list) and len(node) == 1 and not part.isdigit():
                node = node[0]  # an array of one table ([[force]]): force.amplitude means its only entry
            if isinstance(node, list) and part.isdigit() and int(part) < len(node):
                node = node[int(part)]
            elif isinstance(node, dict) and part in node and isinstance(node[part], (dict, list)):
                node = node[part]
            elif isinstance(node, dict) and part not in node and not part.isdigit():
                node = node.setdefault(part, {})
            else:
                raise SceneError("--set", key, text, f"{'.'.join(parts[:i + 1])} is not a table of the scene")
        last = parts[-1]
        if isinstance(node, list) and len(node) == 1 and not last.isdigit():
            node = node[0]
        if isinstance(node, list):
            if not (last.isdigit() and int(last) < len(node)):
                raise SceneError("--set", key, text, "no such entry")
            node[int(last)] = value
        else:
            node[last] = value
    return parse_scene(data, scene.path)


STABILITY = {"auto": None, "on": True, "off": False}  # --stability


def sweep_options(scene: Scene, *, stability: str | None = None, peak_share: float | None = None) -> SweepOptions:
    """The scene's [solver] table as the FRF's options; ``stability``: auto, on or off, and
    ``peak_share`` (None: the scene's [solver] stability and peak_share; benchmarks that measure
    errors below a peak's truncation error locate it with peak_share = 0)."""
    stability = scene.solver.stability if stability is None else stability
    s = scene.solver
    return SweepOptions(
        stability=STABILITY[stability], stability_memory=s.stability_memory, omega_limits=s.omega_limits,
        peak_error=s.peak_error, peak_share=s.peak_share if peak_share is None else peak_share,
        harmonic_adaptation=(HarmonicAdaptation(target=s.harmonic_target, H_max=s.harmonics_max, tol=s.amplitude_tol)
                             if s.harmonics_auto else None),
        omega_start=s.omega_start, omega_end=s.omega_end, harmonics=Harmonics(s.harmonics, s.samples),
        continuation=ContinuationOptions(ds0=s.ds0, ds_min=s.ds_min, ds_max=s.ds_max, max_points=s.max_points,
                                         time_limit=s.time_limit,
                                         newton=NewtonOptions(tol=s.tol, relaxed_kink_tol=max(s.kink_tol, s.tol))))


@dataclass
class SceneSolution:
    """A solved scene: the physical model (its ModelSummary where it stayed distributed), its FRF,
    the model-building seconds and the ROM (None at full order)."""

    structure: "Structure | ModelSummary"
    frf: FrequencyResponse
    build_s: float
    rom: Reduction | None
    incomplete: SweepIncomplete | None = None  # the sweep stopped early: frf holds the points before it


def memory_estimate(structure: Structure, harmonics: Harmonics) -> float:
    """Bytes a sweep holds at least: the AFT's transform pair (N x (2H+1), twice), every contact
    pair's Jacobian block (per pair (m (2H+1))^2), and the linear operator (nnz(K, M, D) per
    harmonic block, four times)."""
    nh, N = harmonics.num_hc, harmonics.N
    nnz = sum(sp_nnz(A) for A in (structure.K, structure.M, structure.D))
    pairs = sum(g.pairs.num_pairs * (g.pairs.num_comp * nh) ** 2 for g in structure.contacts)
    return 8.0 * (2 * N * nh + pairs + 4 * nnz * nh) + 12.0 * 4 * nnz * nh


def sp_nnz(A) -> int:
    return int(A.nnz) if sp.issparse(A) else int(np.count_nonzero(A))


def largest_harmonics(scene: Scene) -> Harmonics:
    """The largest H (and its N) a run of the scene solves at: harmonics, or harmonics_max with
    harmonics = "auto"."""
    s = scene.solver
    return Harmonics(s.harmonics_max if s.harmonics_auto else s.harmonics,
                     s.samples if s.samples_given or not s.harmonics_auto else default_samples(s.harmonics_max))


def at_one_harmonics(scene: Scene, why: str) -> None:
    """Refuse harmonics = "auto" (chosen along an FRF's branch, by `jointfem frf` only) for a command
    that solves at one H, with one line before any work."""
    if scene.solver.harmonics_auto:
        raise SceneError(scene.path, "solver.harmonics", "auto", f"{why}: give harmonics a number, or --harmonics "
                         "(jointfem frf chooses H along its branch with \"auto\")")


def check_resources(scene: Scene, structure: Structure) -> None:
    """Refuse, with one line and the estimate, a sweep whose arrays would not fit in half of this
    machine's memory (``--harmonics 100000`` asked for 298 GiB before it failed)."""
    h = largest_harmonics(scene)
    need = memory_estimate(structure, h)
    total = _memory_total()
    if total and need > 0.5 * total:
        raise SceneError(scene.path, "solver.harmonics", h.H,
                         f"with N = {h.N} samples and {structure.num_dofs} DOFs a sweep needs at least "
                         f"{need / 2**30:.1f} GiB, more than half of this machine's {total / 2**30:.1f} GiB")


PROBE_ABOVE_H = 15  # below this a Newton iteration costs at most seconds on the models jointfem builds


def iteration_estimate(model, harmonics: Harmonics, omega: float, *, enough: float = 0.2) -> dict | None:
    """Seconds of one Newton iteration (the residual with its Jacobian, then the linear solve) at
    ``harmonics``, extrapolated from the same model at fewer harmonics: H = 1, 3, 7, 15, ... (N in
    proportion) until one takes ``enough`` seconds, then t ~ (2H+1)^p with p from the last two
    probes (clamped to [2, 4]; it grows with H, so this is an estimate from below).  None when H is
    small enough to need none."""
    from .linalg import sparse_lu

    if harmonics.H <= PROBE_ABOVE_H:
        return None
    ratio = harmonics.N / harmonics.num_hc
    probes = []
    Hp = 1
    while Hp < harmonics.H:
        h = Harmonics(Hp, max(2 * Hp + 1, int(round(ratio * (2 * Hp + 1)))))
        problem = create_problem(model, h)
        x = problem.initial_guess(omega)
        t0 = time.perf_counter()
        ev = problem.evaluate(x, omega, jacobian=True)
        if sp.issparse(ev.J):
            sparse_lu(ev.J)
        else:
            np.linalg.solve(np.asarray(ev.J), ev.R)
        probes.append((h.num_hc, time.perf_counter() - t0))
        if probes[-1][1] >= enough and len(probes) >= 2:
            break
        Hp = 2 * Hp + 1
    (n1, t1), (n2, t2) = probes[-2], probes[-1]
    p = float(np.clip(np.log(max(t2, 1e-9) / max(t1, 1e-9)) / np.log(n2 / n1), 2.0, 4.0))
    return {"seconds": t2 * (harmonics.num_hc / n2) ** p, "probe_H": (n2 - 1) // 2, "probe_s": t2, "exponent": p}


def check_time(scene: Scene, model, harmonics: Harmonics, omega: float) -> None:
    """Refuse, with one line and the estimate, a run whose first point alone (three Newton
    iterations or more) would pass the scene's time limit; say the estimate where an iteration
    takes more than a second (``--harmonics 1000`` on the beam: about 2 h per iteration)."""
    est = iteration_estimate(model, harmonics, omega)
    if est is None:
        return
    what = (f"about {est['seconds']:.3g} s per Newton iteration at H = {harmonics.H}, N = {harmonics.N} (measured "
            f"{est['probe_s']:.3g} s at H = {est['probe_H']}, scaled by (2H+1)^{est['exponent']:.1f})")
    limit = scene.solver.time_limit
    if 3 * est["seconds"] > limit:
        raise SceneError(scene.path, "solver.harmonics", harmonics.H,
                         f"{what}: the first point alone (3 iterations or more) would pass solver.time_limit = "
                         f"{limit:g} s")
    if est["seconds"] > 1.0:
        log.warning("%s: %s; a sweep takes hundreds of iterations", scene.name, what)


def _memory_total() -> float:
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemTotal"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    return 0.0


def check_forced_resonances(scene: Scene, structure: Structure, max_dofs: int = 2000) -> None:
    """Refuse, with one line, a forced undamped resonance in the sweep's range that nothing can
    bound: a mode of small vibrations about rest (Structure.K_rest: pairs stuck, open gaps open)
    with omega in omega_range, no viscous damping, a share of the force, and no relative motion
    along any friction component (friction then cannot dissipate its energy) or any component
    whose law engages away from rest (a unilateral spring short of its gap: its stiffness detunes
    the mode once the gap closes).  Its linear response is infinite there, and the sweep would
    fail on a NaN.  (An undamped mode that moves a slider is left alone: friction holds it,
    tests/test_extremes_systems.py.)  Models of more than ``max_dofs`` DOFs are not checked (their
    dense eigensolve would cost more than it saves)."""
    import scipy.linalg as sla

    n = structure.num_dofs
    if n > max_dofs:
        return
    dense = lambda A: A.toarray() if sp.issparse(A) else np.asarray(A)  # noqa: E731
    w2, Phi = sla.eigh(dense(structure.K_rest), dense(structure.M))
    f = structure.fc - 1j * structure.fs
    s = scene.solver
    rows = [g.gap[np.flatnonzero(g.pairs.dissipative.ravel()
                                 | (np.asarray(g.pairs.rest_stiffness).ravel() != np.asarray(g.pairs.stiffness).ravel()))]
            for g in structure.contacts]
    G = sp.vstack(rows).toarray() if rows and sum(r.shape[0] for r in rows) else np.zeros((0, n))
    D = dense(structure.D)
    for k in np.flatnonzero((w2 > 0) & (np.sqrt(np.abs(w2)) >= s.omega_min) & (np.sqrt(np.abs(w2)) <= s.omega_max)):
        phi, w = Phi[:, k], float(np.sqrt(w2[k]))
        scale = np.abs(phi).max()
        damped = abs(phi @ D @ phi) > 1e-12 * 2 * w  # modal damping ratio above 1e-12
        forced = abs(phi @ f) > 1e-12 * scale * np.abs(f).sum()
        held = G.shape[0] and np.abs(G @ phi).max() > 1e-9 * scale
        if forced and not damped and not held:
            dof = structure.dof_names[int(np.argmax(np.abs(phi)))] if structure.dof_names else int(np.argmax(np.abs(phi)))
            raise SceneError(scene.path, "solver.omega_range", [s.omega_min, s.omega_max],
                             f"contains an undamped, forced stuck mode at {w:.6g} rad/s ({w / (2 * np.pi):.5g} Hz), "
                             f"mostly {dof}, that no friction component moves: its response is unbounded "
                             f"(add a damper on {dof}, or move the range)")


@dataclass(frozen=True)
class ModelSummary:
    """What the writers need of a model whose matrices stay distributed on the ranks (--offline
    distributed): never K or M, which no rank holds whole."""

    num_dofs: int
    num_pairs: int
    outputs: dict
    info: dict


def _distributed_rom(scene: Scene, method: str, rom_options: RomOptions):
    """The penalty ROM from the distributed offline stage (jointfem.fem.distributed), and the model's
    summary; refused, before any work, for what that stage does not take."""
    if method != "penalty":
        raise SceneError(scene.path, "--offline", "distributed", f"is the penalty ROM's offline stage: --method "
                                                                 f"{method} needs the replicated model")
    if not scene.kind.startswith("continuum"):
        raise SceneError(scene.path, "--offline", "distributed", f"is for continuum scenes (this one is {scene.kind})")
    from .rom.reductors import check_options

    check_options(method, rom_options)
    from .fem.distributed import create_distributed
    from .rom.penalty import PenaltyROM

    t0 = time.perf_counter()
    model = create_distributed(scene.model)
    t1 = time.perf_counter()
    try:
        rom = PenaltyROM(None, rom_options, distributed=model)
    finally:
        model.destroy()
    rom.offline_s = time.perf_counter() - t1
    info = dict(model.info, timings=dict(model.info["timings"], distributed_model_s=t1 - t0))
    return ModelSummary(model.num_dofs, int(model.info["num_pairs"]), dict(model.outputs), info), rom


def reduction_of(scene: Scene, method: str | None = None, rom_options: RomOptions | None = None, *,
                 modes: int | None = None, tvd: int | None = None, tvd_kind: str | None = None,
                 offline: str = "replicated") -> tuple[str, RomOptions]:
    """The method and options given (``rom_options`` whole, or ``modes``, ``tvd``, ``tvd_kind`` one
    by one, as the command line gives them), else the scene's [reduction] table's (full order
    without one).  A method that cannot take the options is refused here (rom.check_options), before
    any model is built: a continuum's meshing and assembly would otherwise come first."""
    from .rom.reductors import check_options

    red = scene.reduction
    if rom_options is None:
        rom_options = RomOptions(modes=red.modes if modes is None else modes, tvd=red.tvd if tvd is None else tvd,
                                 tvd_kind=red.tvd_kind if tvd_kind is None else tvd_kind, offline=offline)
    method = red.method if method is None else method
    if method != "full":
        check_options(method, rom_options)
    return method, rom_options


def solve_scene(scene: Scene, *, progress: bool = False, method: str | None = None,
                rom_options: RomOptions | None = None, stability: str | None = None,
                keep_incomplete: bool = False, resume: Resume | None = None) -> SceneSolution:
    """Build the model of a scene (and its ROM) and compute its FRF (``stability``: auto, on, off;
    None: the scene's [solver] stability).
    ``method``, ``rom_options``: the scene's [reduction] where not given (reduction_of).

    A sweep that stops early (a stall, the time limit, Ctrl-C) raises SweepIncomplete, or, with
    ``keep_incomplete``, returns its converged points with ``incomplete`` set.  ``resume`` (from
    load_resume) goes on with a branch that stopped."""
    method, rom_options = reduction_of(scene, method, rom_options)
    check_solvable(scene)
    t0 = time.perf_counter()
    if rom_options.offline == "distributed":
        structure, rom = _distributed_rom(scene, method, rom_options)
    else:
        structure = create_structure(scene)
        check_resources(scene, structure)
        check_forced_resonances(scene, structure)
        rom = None if method == "full" else build_rom(structure, method, rom_options)
    t_build = time.perf_counter() - t0
    s = scene.solver
    check_time(scene, structure if rom is None else rom, largest_harmonics(scene), s.omega_start)
    opts = sweep_options(scene, stability=stability)
    bar = None
    callback = stability_progress = None
    if progress:
        from tqdm import tqdm

        span = abs(s.omega_end - s.omega_start)
        # until the first point: numba compiles the contact kernels on a machine's first run (about
        # 50 s, cached after), and the start point's Newton solve; the bar says so, not a fake rate
        bar = tqdm(total=round(span, 6), unit="rad/s", desc=f"{scene.name}: compiling kernels / first point",
                   file=sys.stderr,
                   bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.4g}/{total:.4g} rad/s [{elapsed}<{remaining}]"
                              "{postfix}")

        count = [0, 0.0]

        def callback(point):
            # the bar counts the span covered; the postfix the points (a branch that turns back at a
            # fold makes progress the bar cannot show), refreshed at most twice a second
            count[0] += 1
            if count[0] == 1:
                bar.set_description_str(f"{scene.name} omega", refresh=False)
                bar.reset(total=round(span, 6))  # the estimate starts at the first point
            done = min(abs(point.lam - s.omega_start), span)
            now = time.monotonic()
            bar.set_postfix_str(f"points={count[0]} omega={point.lam:.6g} newton={point.iterations}",
                                refresh=False)
            if done > bar.n:
                bar.update(done - bar.n)
                count[1] = now
            elif now - count[1] > 0.5:
                bar.refresh()
                count[1] = now

        def stability_progress(done, total):
            # an auto sweep's exponents are made once its branch is traced (minutes at large H):
            # the same bar, now counting points
            if done == 0:
                bar.set_description_str(f"{scene.name} stability", refresh=False)
                bar.bar_format = "{desc}: {percentage:3.0f}%|{bar}| {n}/{total} points [{elapsed}<{remaining}]"
                bar.reset(total=total)
            bar.update(done - bar.n)

    model = structure if rom is None else rom
    incomplete = None
    try:
        frf = compute_frf(model, opts, callback=callback, resume=resume, stability_progress=stability_progress)
    except SweepIncomplete as exc:
        if not keep_incomplete:
            raise
        frf, incomplete = exc.frf, exc
    finally:
        if bar is not None:
            bar.close()
    return SceneSolution(structure, frf, t_build, rom, incomplete)


def _incomplete_run(folder: Path, scene: Scene, method: str, rom_options: RomOptions, analysis: str,
                    **same) -> tuple[dict, dict]:
    """(summary, branch arrays) of the incomplete run of ``analysis`` in ``folder``, checked to be
    this scene's with this method (and H, N, ROM options, and the ``same`` summary values);
    OutputError with one line otherwise."""
    folder = Path(folder)
    try:
        summary = json.loads((folder / "summary.json").read_text())
        b = load_branch(folder / "branch.npz")
    except (OSError, ValueError) as exc:
        raise OutputError(f"--resume {folder}: no result folder to resume ({exc})") from None
    if (theirs_analysis := summary.get("analysis", "frf")) != analysis:
        raise OutputError(f"--resume {folder}: it holds a {theirs_analysis} run, not a {analysis} run")
    if summary.get("status") != "incomplete":
        raise OutputError(f"--resume {folder}: its sweep is {summary.get('status', 'of an older jointfem')}, "
                          f"not incomplete: nothing to resume")
    rom = summary.get("rom", {})

    def problem_of(data):  # the run's budgets are not part of the problem
        data = json.loads(json.dumps(data or {}))
        for key in ("max_points", "time_limit"):
            data.get("solver", {}).pop(key, None)
        return data

    # (harmonics = "auto": H changes along the branch, and what the scene fixes is that it does)
    mine = {"scene": problem_of(scene.data), "method": method,
            "harmonics": "auto" if scene.solver.harmonics_auto else scene.solver.harmonics,
            "samples": scene.solver.samples, **same}
    theirs = {"scene": problem_of(summary.get("scene_data")), "method": summary.get("method"),
              "harmonics": "auto" if "harmonics_adaptive" in summary else summary.get("harmonics"),
              "samples": summary.get("samples"),
              **{k: summary.get(k) for k in same}}
    if method != "full":
        mine.update(modes=rom_options.modes, tvd=rom_options.tvd, tvd_kind=rom_options.tvd_kind)
        theirs.update(modes=rom.get("modes"), tvd=rom.get("tvd"), tvd_kind=rom.get("tvd_kind", "eigen"))
    differ = [k for k in mine if mine[k] != theirs[k]]
    if differ:
        raise OutputError(f"--resume {folder}: it was solved with another {', '.join(differ)} "
                          f"({', '.join(f'{k} = {theirs[k]!r}' for k in differ if k != 'scene') or 'scene data'})")
    if "ds_next" not in b:
        raise OutputError(f"--resume {folder}: written by an older jointfem (no ds_next in branch.npz)")
    return summary, b


def load_resume(folder: Path, scene: Scene, method: str, rom_options: RomOptions) -> Resume:
    """The branch of an incomplete sweep in ``folder``, checked to be this scene's with this method
    (and H, N, ROM options); OutputError with one line otherwise."""
    summary, b = _incomplete_run(folder, scene, method, rom_options, "frf")
    return Resume(omega=b["omega"], U=b["U"], iterations=b["iterations"], residual=b["residual"],
                  ds_next=float(b["ds_next"][-1]),
                  harmonics=b["harmonics"] if "harmonics_adaptive" in summary else None)


def load_force_resume(folder: Path, scene: Scene, method: str, rom_options: RomOptions, omega: float) -> dict:
    """The branch arrays of an incomplete `jointfem force` run in ``folder`` at this omega, checked
    as load_resume checks a sweep's (compute_force_response's ``resume``)."""
    _, b = _incomplete_run(folder, scene, method, rom_options, "force", omega_rad_s=omega)
    return b


# Every file and subfolder a command writes into a result folder.  A folder holds one run: a run
# (frf, nma, force, compare, modes) first removes whatever any command wrote there, then writes its
# own; `plot` and `export` add to the run's folder.  What a run removes that is not its own (another
# command's files, an export/ folder) it names in one warning.  Files jointfem does not write are
# left alone, and so is an export/ folder holding one (README.md, "Command line").
WRITES = {
    "frf": ("frf.csv", "branch.npz", "summary.json", "shape.npz", "frf.png"),
    "nma": ("backbone.csv", "branch.npz", "summary.json", "shape.npz", "backbone.png", "frf_synthesized.png"),
    "force": ("force.csv", "branch.npz", "summary.json", "shape.npz", "force.png"),
    "compare": ("compare.csv", "compare.md", "compare_frf.png", "compare_pareto.png", "compare_backbone.png"),
    "modes": ("modes.csv", "modes.npz"),
    "plot": ("states_branch.png", "interface_*.png", "shape_*.png"),
    "export": ("export",),
}
EXPORT_WRITES = ("field_*.vtu", "field_*.xdmf", "pairs_*.vtu")


def remove_stale(out: Path, command: str) -> list[Path]:
    """Clear the result folder ``out`` for a run of ``command`` (WRITES' rule above).  Returns what
    was removed."""
    out = Path(out)
    if not out.is_dir():
        return []
    found = sorted({p for patterns in WRITES.values() for pattern in patterns for p in out.glob(pattern)})
    own = {p for pattern in WRITES[command] + WRITES["plot"] for p in out.glob(pattern)}
    removed, kept, foreign = [], [], []
    for p in found:
        if p.is_dir():
            if not all(q.is_file() and any(q.match(e) for e in EXPORT_WRITES) for q in p.iterdir()):
                kept.append(p)
                continue
            shutil.rmtree(p)
        elif p.is_file():
            p.unlink()
        else:
            continue
        removed.append(p)
        if p not in own:
            foreign.append(p.name + ("/" if p.name == "export" else ""))
    if foreign:
        log.warning("%s: removed what an earlier run wrote there, before writing %s's files: %s", out, command,
                    ", ".join(foreign))
    for p in kept:
        log.warning("%s: left %s/ alone: it holds files jointfem export does not write", out, p.name)
    return removed


def software() -> dict:
    """The versions a result was computed with, and the commit of a git checkout of jointfem."""
    import platform
    import subprocess

    import scipy

    from .version import installed_version

    out = {"jointfem": installed_version(), "python": platform.python_version(), "numpy": np.__version__,
           "scipy": scipy.__version__}
    try:
        root = Path(__file__).resolve().parents[1]
        r = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=root, capture_output=True, text=True,
                           timeout=10)
        if r.returncode == 0:
            out["commit"] = r.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        pass
    return out


def linear_modes(structure: Structure, num: int = 10) -> dict:
    """The lowest ``num`` linear modes of the structure at rest with every friction pair stuck
    (K_rest: the joint as linear springs, open pairs and unilateral springs short of their gap
    open, as small vibrations about rest see it) and free (K: every pair slipping or open, no
    contact stiffness).  Per mode: omega (rad/s), the frequency (Hz), the modal damping ratio
    phi^T D phi / (2 omega) of mass-normalised phi, and the share of the force phi^T f.  Rigid-body
    modes of a free joint (K singular) come out at 0 rad/s."""
    from .linalg import eigen

    num = min(num, structure.num_dofs)
    f = structure.fc - 1j * structure.fs
    out = {}
    for label, K in (("stuck", structure.K_rest), ("free", structure.K)):
        # a free joint may leave rigid-body modes: shift below zero (rad^2/s^2 of the lowest stuck mode)
        w2, Phi = eigen(K, structure.M, num, what=f"{label} modes", sigma=-1.0)
        w = np.sqrt(np.clip(w2, 0.0, None))
        D = structure.D
        zeta = np.array([float(Phi[:, k] @ (D @ Phi[:, k])) / (2 * w[k]) if w[k] > 0 else np.nan
                         for k in range(w.size)])
        out[label] = {"omega_rad_s": w, "freq_Hz": w / (2 * np.pi), "damping_ratio": zeta,
                      "modal_force_N": np.abs(Phi.T @ f), "shapes": Phi}
    return out


def write_modes(modes: dict, structure: Structure, out: Path) -> None:
    """modes.csv (one row per mode: stuck and free frequencies, damping ratios, modal forces) and
    modes.npz (the mass-normalised shapes, DOF names)."""
    st, fr = modes["stuck"], modes["free"]
    rows = ["mode,stuck_omega_rad_s,stuck_freq_Hz,stuck_damping_ratio,stuck_modal_force_N,"
            "free_omega_rad_s,free_freq_Hz,free_damping_ratio,free_modal_force_N"]
    for k in range(st["omega_rad_s"].size):
        vals = [st[c][k] for c in ("omega_rad_s", "freq_Hz", "damping_ratio", "modal_force_N")]
        vals += [fr[c][k] for c in ("omega_rad_s", "freq_Hz", "damping_ratio", "modal_force_N")]
        rows.append(",".join([str(k + 1)] + ["" if not np.isfinite(v) else f"{v:.10g}" for v in vals]))
    remove_stale(out, "modes")
    atomic_write(Path(out) / "modes.csv", lambda p: Path(p).write_text("\n".join(rows) + "\n"))

    def npz(p):
        with open(p, "wb") as fh:
            np.savez_compressed(fh, stuck_shapes=st["shapes"], free_shapes=fr["shapes"],
                                stuck_omega_rad_s=st["omega_rad_s"], free_omega_rad_s=fr["omega_rad_s"],
                                dof_names=np.array(structure.dof_names, dtype=str))

    atomic_write(Path(out) / "modes.npz", npz)


def write_force(response, scene: Scene, out: Path, *, method: str, rom_options: RomOptions | None = None,
                structure: Structure | None = None, rom: Reduction | None = None) -> dict:
    """A force sweep's folder: force.csv (scale, the scene's first harmonic force times it, each
    output's first-harmonic amplitude), branch.npz, summary.json, force.png (log-log) and, for a
    continuum ``structure``, shape.npz.  branch.npz holds what a sweep's does for `jointfem plot`
    and `export` (the output layout, the pairs, omega per point), and the force per point."""
    from .plots import plot_force
    from .results import output_arrays

    out = Path(out)
    amps = [a for a in scene_force_amplitudes(scene) if a]
    F1 = float(amps[0]) if amps else 1.0
    names = list(response.outputs)
    cols = [response.scale, response.scale * F1] + [response.amplitude(n) for n in names]
    header = ["force_scale", "force_N"] + [f"{n}_amp1_m" for n in names]
    table = np.column_stack(cols)
    if not np.all(np.isfinite(table)):
        raise OutputError("force sweep holds a non-finite value; nothing written")
    remove_stale(out, "force")
    atomic_write(out / "force.csv", lambda p: np.savetxt(p, table, delimiter=",", header=",".join(header),
                                                          comments="", fmt="%.12e"))

    def npz(p):
        with open(p, "wb") as fh:
            q = response.U.shape[1] // response.harmonics.num_hc
            np.savez_compressed(fh, scale=response.scale, force_N=response.scale * F1, U=response.U,
                                states=response.states, omega=np.full(response.scale.size, response.omega),
                                H=response.harmonics.H, N=response.harmonics.N, num_dofs=q,
                                output_names=np.array(names, dtype=str), **output_arrays(response.outputs, q),
                                pair_names=np.array(response.pair_names, dtype=str),
                                **({"pair_coords": np.asarray(response.pair_coords)}
                                   if response.pair_coords is not None else {}),
                                **({"pair_area_m2": np.asarray(response.pair_areas)}
                                   if response.pair_areas is not None else {}),
                                layout=np.array("harmonic-major: U[j*n + dof], j=0 const, 2k-1 cos k, 2k sin k"),
                                **{k: np.asarray(v) for k, v in response.info["arrays"].items()})

    atomic_write(out / "branch.npz", npz)
    if structure is not None:
        save_shape(structure, rom, out)
    summary = {"scene": str(scene.path), "scene_data": scene.data, "method": method, "analysis": "force",
               "omega_rad_s": response.omega, "freq_Hz": response.omega / (2 * np.pi),
               "harmonics": response.harmonics.H, "samples": response.harmonics.N,
               "num_points": int(response.scale.size), "status": response.info.get("status", "complete"),
               **({"stop_reason": response.info["stop_reason"]} if "stop_reason" in response.info else {}),
               "continuation": response.info["continuation"], "num_unknowns": response.info["num_unknowns"],
               "wall_s": response.info["time_s"], "software": software(),
               **({"rom": {"modes": rom_options.modes, "tvd": rom_options.tvd, "tvd_kind": rom_options.tvd_kind}}
                  if method != "full" and rom_options is not None else {})}
    atomic_write(out / "summary.json", lambda p: Path(p).write_text(json.dumps(summary, indent=2, default=float)))
    plot_force(response, F1, out / "force.png",
               title=f"{scene.name} at {response.omega:.6g} rad/s ({response.omega / (2 * np.pi):.5g} Hz), {method}")
    return summary


def scene_force_amplitudes(scene: Scene) -> list[float]:
    """The harmonic amplitudes of the scene's forces, N (lumped and matrices kinds: each
    [[force]]; the beam and continua: their one force)."""
    if scene.kind in ("lumped", "matrices"):
        return [f.amplitude for f in scene.model.forces]
    return [scene.model.force]


def check_output(out: Path) -> None:
    """Refuse, before any solve, an output folder that cannot be written (read-only, or a file in
    its path), with one line (OutputError).  Nothing is created: a run that then fails early leaves
    no folder behind."""
    out = Path(out).absolute()
    existing = next(p for p in (out, *out.parents) if p.exists())
    if not existing.is_dir():
        raise OutputError(f"cannot write the results to {out}/: {existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise OutputError(f"cannot write the results to {out}/: {existing} is not writable")


def _harmonics_label(frf: FrequencyResponse) -> str:
    """H=5, or H=3-21 for a branch whose H changes along it (harmonics = "auto")."""
    H = frf.info["arrays"].get("harmonics")
    if H is None or H.size == 0 or H.min() == H.max():
        return f"H={frf.harmonics.H}"
    return f"H={int(H.min())}-{int(H.max())}"


def save_shape(structure: Structure, rom: Reduction | None, out: Path) -> None:
    """shape.npz: node positions and the map from the solved coordinates to the physical DOFs,
    for the deformed-shape picture (continuum models; not for --method exact, whose unknowns are
    the gaps and outputs only)."""
    geom = structure.info.get("geometry")
    if geom is None or (rom is not None and rom.basis is None):
        return
    extra = {} if rom is None else {"recovery": np.asarray(rom.basis)}

    def write(p):
        with open(p, "wb") as fh:
            np.savez_compressed(fh, node_coords=geom["node_coords"], dof_node=geom["dof_node"],
                                dof_comp=geom["dof_comp"], **extra,
                                **{k: geom[k] for k in ("cell_nodes", "vtk_cell_type") if k in geom})

    atomic_write(Path(out) / "shape.npz", write)


def write_frf(solution: SceneSolution, scene: Scene, out: Path, *, method: str, rom_options: RomOptions,
              mpi_ranks: int = 1, wall_start: float | None = None, plots: bool = False) -> dict:
    """Write a solved scene's folder: frf.csv, branch.npz, summary.json, shape.npz (continua),
    frf.png and, with ``plots``, the contact-state pictures.  Returns the summary written."""
    from .plots import plot_frf
    from .results import save_frf

    structure, frf, rom = solution.structure, solution.frf, solution.rom
    sizes = frf.info["arrays"]["rom_size"]
    rom_info = {"method": method, "size_min": int(sizes.min()), "size_max": int(sizes.max()),
                "full_size": structure.num_dofs, "reduction_ratio_max": float(sizes.max() / structure.num_dofs)}
    if rom is not None:
        rom_info.update({"offline_s": rom.offline_s, "modes": rom_options.modes, "tvd": rom_options.tvd,
                         "tvd_kind": rom_options.tvd_kind,
                         **{k: v for k, v in rom.info.items()}, **frf.info.get("active_set_events", {})})
    t_end = time.perf_counter()
    summary = {
        "scene": str(scene.path), "scene_data": scene.data, "kind": scene.kind, "method": method,
        "model": {"num_dofs": structure.num_dofs, "num_pairs": structure.num_pairs},
        "rom": rom_info,
        "harmonics": frf.harmonics.H, "samples": frf.harmonics.N, "mpi_ranks": mpi_ranks,
        **({"harmonics_adaptive": frf.info["harmonics_adaptive"]} if "harmonics_adaptive" in frf.info else {}),
        "model_timings_s": structure.info.get("timings", {}),
        "num_unknowns": frf.info["num_unknowns"],
        "omega_start_rad_s": scene.solver.omega_start, "omega_end_rad_s": scene.solver.omega_end,
        "status": frf.info.get("status", "complete"),
        **({"stop_reason": frf.info["stop_reason"]} if "stop_reason" in frf.info else {}),
        "wall_s": {"build": solution.build_s, "setup": frf.info["time_setup_s"],
                   "continuation": frf.info["time_online_s"],  # the peak search included
                   "peak_search": frf.info.get("time_peaks_s", 0.0),
                   "total": t_end - (wall_start if wall_start is not None else t_end)},
    }
    summary["software"] = software()
    remove_stale(out, "frf")
    summary = save_frf(frf, out, summary=summary)
    save_shape(structure, rom, out)
    plot_frf(frf, out / "frf.png", title=f"{scene.name} ({method}, {_harmonics_label(frf)})")
    if plots and structure.num_pairs:
        from .viz import plot_folder

        for pic in plot_folder(out):
            log.info("wrote %s", pic.path)
    log.info("wrote %s", out)
    return summary


def applicable_methods(specs: list, structure: Structure, *, given: bool) -> tuple[list, str]:
    """compare's methods for ``structure``: all of ``specs`` where the user ``given`` them (a method
    the model cannot take is then refused by name), else the default list less the methods that
    reduce each substructure where the model defines none (a lumped or matrices model), with a
    sentence saying so ("" where none was left out)."""
    from .rom.reductors import MODAL, SUBSTRUCTURED

    if given:
        return specs, ""
    notes = []
    out = [s for s in specs if s.method in SUBSTRUCTURED] if structure.substructure is None else []
    if out:
        specs = [s for s in specs if s not in out]
        notes.append(f"Left out of the default methods: {', '.join(s.method for s in out)}, which reduce each "
                     f"substructure (the model, {structure.info.get('kind', '?')}, defines none).")
    n = structure.num_dofs
    few = [s for s in specs if s.method in MODAL and s.options.modes + s.options.tvd > n]
    if few:
        def fit(o: RomOptions) -> RomOptions:
            modes = min(o.modes, n)
            return dataclasses.replace(o, modes=modes, tvd=min(o.tvd, n - modes))

        specs = [dataclasses.replace(s, options=fit(s.options)) if s in few else s for s in specs]
        notes.append(f"The default methods' modes and TVDs are at most the model's {n} DOF{'s' if n != 1 else ''} in all "
                     f"({', '.join(s.label for s in specs if s.method in MODAL)}).")
    return specs, " ".join(notes)


def compare_scene(scene: Scene, methods: str | None, defaults: RomOptions, *, out: Path, output: str | None = None,
                  reference: str = "full", progress=None, stability: str | None = None) -> str:
    """Every ROM of ``methods`` (comma-separated name[:modes[:tvd]]) against the reference on one
    scene: writes compare.csv, compare.md, compare_frf.png and compare_pareto.png into ``out``, and
    returns the Markdown."""
    from .analysis.compare import compare, parse_method, to_markdown
    from .plots import plot_compare
    from .results import atomic_write_text, write_table

    specs = [parse_method(m, defaults) for m in (methods or COMPARE_METHODS).split(",") if m.strip()]
    at_one_harmonics(scene, "compare measures every method at one H")
    check_solvable(scene)
    structure = create_structure(scene)
    specs, left_out = applicable_methods(specs, structure, given=methods is not None)
    output = output or next(iter(structure.outputs), None)
    if output not in structure.outputs:
        raise SceneError(scene.path, "--output", output, f"not an output of the scene ({', '.join(structure.outputs)})")
    results = compare(structure, specs, sweep_options(scene, stability=stability), output=output, progress=progress,
                      reference=reference)
    remove_stale(out, "compare")
    write_table([r.row() for r in results], out / "compare.csv")
    md = (f"# {scene.name}: ROMs against {'full order' if reference == 'full' else 'the exact condensation'}"
          f"\n\nScene {scene.path}, output {output}, "
          f"H = {scene.solver.harmonics}, N = {scene.solver.samples}, full size {structure.num_dofs}.\n\n"
          + (f"{left_out}\n\n" if left_out else "") + to_markdown(results))
    atomic_write_text(out / "compare.md", md)
    plot_compare(results, output, out / "compare_frf.png", out / "compare_pareto.png", title=scene.name)
    return md


@dataclass
class NmaSolution:
    """A scene's nonlinear mode: the physical model, the backbone, the model-building seconds,
    the ROM (None at full order) and, where it stopped early, why."""

    structure: Structure
    backbone: object  # analysis.nma.Backbone
    build_s: float
    rom: Reduction | None
    incomplete: object = None  # analysis.nma.NmaIncomplete


def nma_options(scene: Scene, *, mode: int | None = None):
    """The scene's [nma] table (and [solver]'s harmonics and continuation settings) as NmaOptions;
    ``mode`` overrides [nma] mode.  A scene without [nma] is refused, naming the table."""
    from .analysis.nma import NmaOptions

    if scene.nma is None:
        raise SceneError(scene.path, "[nma]", MISSING, "the scene has no [nma] table: give amplitude_range = [start, end] "
                         "(m, at the output) and optionally mode and output (docs/scenes.md)")
    s, n = scene.solver, scene.nma
    cont = sweep_options(scene, stability="off").continuation
    return NmaOptions(mode=mode if mode is not None else n.mode, amplitude_start=n.amplitude_range[0],
                      amplitude_end=n.amplitude_range[1], output=n.output, excitation=n.self_excitation,
                      harmonics=Harmonics(s.harmonics, s.samples), continuation=cont)


def check_nma(scene: Scene, structure: Structure, options) -> None:
    """Refuse, before any solve, an [nma] table that does not fit the model (its output, its mode)."""
    if options.output is not None and options.output not in structure.outputs:
        raise SceneError(scene.path, "nma.output", options.output,
                         f"no such output (known: {', '.join(structure.outputs)})")
    if not structure.outputs:
        raise SceneError(scene.path, "[output]", MISSING, "nonlinear modes need an output at which to measure the amplitude")
    if options.mode > structure.num_dofs:
        raise SceneError(scene.path, "nma.mode", options.mode, f"the model has only {structure.num_dofs} DOFs")


def solve_nma(scene: Scene, *, method: str | None = None, rom_options: RomOptions | None = None,
              mode: int | None = None, progress: bool = False, keep_incomplete: bool = True) -> NmaSolution:
    """Build the model of a scene (and its ROM) and follow its nonlinear mode ([nma] table);
    ``method``, ``rom_options``: the scene's [reduction] where not given."""
    from .analysis.nma import NmaError, NmaIncomplete, compute_backbone

    method, rom_options = reduction_of(scene, method, rom_options)

    opts = nma_options(scene, mode=mode)
    check_solvable(scene)
    t0 = time.perf_counter()
    structure = create_structure(scene)
    check_nma(scene, structure, opts)
    check_resources(scene, structure)
    rom = None if method == "full" else build_rom(structure, method, rom_options)
    t_build = time.perf_counter() - t0
    check_time(scene, structure if rom is None else rom, opts.harmonics, scene.solver.omega_start)
    bar, callback = None, None
    if progress:
        from tqdm import tqdm

        lo, hi = np.log10(opts.amplitude_start), np.log10(opts.amplitude_end)
        bar = tqdm(total=hi - lo, desc=f"{scene.name}: compiling kernels / first point", file=sys.stderr,
                   bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.3g}/{total:.3g} decades [{elapsed}<{remaining}]"
                              "{postfix}")
        count = [0]

        def callback(point):
            count[0] += 1
            if count[0] == 1:
                bar.set_description_str(f"{scene.name} nma", refresh=False)
            bar.set_postfix_str(f"points={count[0]} amplitude={10 ** point.lam:.4g} m", refresh=False)
            done = min(max(point.lam - lo, 0.0), bar.total)
            if done > bar.n:
                bar.update(done - bar.n)
            else:
                bar.refresh()

    incomplete = None
    try:
        bb = compute_backbone(structure if rom is None else rom, opts, callback=callback)
    except NmaIncomplete as exc:
        if not keep_incomplete:
            raise
        bb, incomplete = exc.backbone, exc
    except NmaError as exc:
        raise SceneError(scene.path, "nma", dataclasses.asdict(scene.nma), str(exc)) from None
    finally:
        if bar is not None:
            bar.close()
    return NmaSolution(structure, bb, t_build, rom, incomplete)


def write_nma(solution: NmaSolution, scene: Scene, out: Path, *, method: str, rom_options: RomOptions | None = None,
              frf_folder: Path | None = None, wall_start: float | None = None) -> dict:
    """A nonlinear mode's folder: backbone.csv (amplitude, frequency in rad/s and Hz, damping ratio,
    energies per cycle, each output's amplitude), branch.npz, summary.json, backbone.png and, where
    the scene has a harmonic force on the mode, frf_synthesized.png (with the forced sweep of
    ``frf_folder`` overlaid)."""
    from .analysis.nma import synthesize_frf
    from .plots import plot_backbone, plot_synthesized
    from .results import _json, output_arrays

    bb = solution.backbone
    arr = bb.info["arrays"]
    names = list(bb.outputs)
    cols = [bb.amplitude, bb.omega, bb.omega / (2 * np.pi), bb.zeta, arr["energy_J"], arr["joint_energy_J"],
            arr["harmonic_error"], arr["unknowns"]] + [bb.output_amplitude(n) for n in names]
    header = ["amplitude_m", "omega_rad_s", "freq_Hz", "damping_ratio", "energy_per_cycle_J",
              "joint_energy_per_cycle_J", "harmonic_error", "unknowns"] + [f"{n}_amp1_m" for n in names]
    table = np.column_stack(cols)
    if not np.all(np.isfinite(table)) or not np.all(np.isfinite(bb.U)):
        raise OutputError("the backbone holds a non-finite value; nothing written")
    out = Path(out)
    remove_stale(out, "nma")
    atomic_write(out / "backbone.csv", lambda p: np.savetxt(p, table, delimiter=",", header=",".join(header),
                                                             comments="", fmt="%.12e"))

    def npz(p):
        with open(p, "wb") as fh:
            q = bb.U.shape[1] // bb.harmonics.num_hc
            # the arrays of a forced sweep's branch.npz too, so that `jointfem plot` and `export` read it
            np.savez_compressed(fh, amplitude=bb.amplitude, omega=bb.omega, xi=bb.xi, zeta=bb.zeta, U=bb.U,
                                states=bb.states, H=bb.harmonics.H, N=bb.harmonics.N, output=np.array(bb.output),
                                num_dofs=q, output_names=np.array(names, dtype=str), **output_arrays(bb.outputs, q),
                                **({"pair_coords": np.asarray(bb.pair_coords)} if bb.pair_coords is not None else {}),
                                **({"pair_area_m2": np.asarray(bb.pair_areas)} if bb.pair_areas is not None else {}),
                                pair_names=np.array(bb.pair_names, dtype=str),
                                layout=np.array("harmonic-major: U[j*n + dof], j=0 const, 2k-1 cos k, 2k sin k"),
                                **{k: np.asarray(v) for k, v in arr.items()})

    atomic_write(out / "branch.npz", npz)
    save_shape(solution.structure, solution.rom, out)
    synth = None
    if np.any(np.abs(arr["modal_force_N"]) > 0):
        synth = synthesize_frf(bb)
    summary = {"scene": str(scene.path), "scene_data": scene.data, "kind": scene.kind, "method": method,
               "analysis": "nma", "mode": bb.mode, "output": bb.output,
               "damping_convention": "EPMC (Krack 2015): M u'' + (D - xi M) u' + K u + f_nl = 0, zeta = xi / (2 omega)",
               "self_excitation": bb.info["excitation"],
               "harmonics": bb.harmonics.H, "samples": bb.harmonics.N, "num_points": int(bb.num_points),
               "num_unknowns": bb.info["num_unknowns"], "status": bb.info["status"],
               **({"stop_reason": bb.info["stop_reason"]} if "stop_reason" in bb.info else {}),
               "linear": {"omega_rad_s": bb.info["linear_omega_rad_s"],
                          "freq_Hz": bb.info["linear_omega_rad_s"] / (2 * np.pi), "damping_ratio": bb.info["linear_zeta"]},
               "amplitude_range_m": [float(bb.amplitude[0]), float(bb.amplitude[-1])],
               "omega_range_rad_s": [float(bb.omega.min()), float(bb.omega.max())],
               "damping_ratio_range": [float(bb.zeta.min()), float(bb.zeta.max())],
               "harmonic_error_max": float(arr["harmonic_error"].max()),
               **({"warnings": bb.info["warnings"]} if "warnings" in bb.info else {}),
               "stability": bb.info["stability"], "continuation": bb.info["continuation"],
               "model": {"num_dofs": solution.structure.num_dofs, "num_pairs": solution.structure.num_pairs},
               "rom": {"method": method, "size_min": int(arr["rom_size"].min()), "size_max": int(arr["rom_size"].max()),
                       **({"offline_s": solution.rom.offline_s, "modes": rom_options.modes, "tvd": rom_options.tvd}
                          if solution.rom is not None and rom_options is not None else {})},
               "wall_s": {"build": solution.build_s, "setup": bb.info["time_setup_s"],
                          "continuation": bb.info["time_online_s"],
                          "total": time.perf_counter() - (wall_start if wall_start is not None else time.perf_counter())},
               "software": software()}
    if synth is not None:
        # the largest amplitude of the synthesised response (what frf_synthesized.png shows); where
        # it lies on a part detached from the one growing from rest, that one's peak beside it
        summary["synthesized_peak"] = {"amplitude_m": synth["peak_amplitude"], "omega_rad_s": synth["peak_omega"],
                                       "freq_Hz": synth["peak_omega"] / (2 * np.pi), "detached": synth["detached"],
                                       "beyond_backbone": synth["beyond_backbone"],
                                       **({"main_branch": {"amplitude_m": synth["main_peak_amplitude"],
                                                           "omega_rad_s": synth["main_peak_omega"]}}
                                          if synth["detached"] else {})}
    atomic_write(out / "summary.json", lambda p: Path(p).write_text(json.dumps(summary, indent=2, default=_json)))
    title = f"{scene.name}: mode {bb.mode} ({method}, H={bb.harmonics.H})"
    plot_backbone(bb, out / "backbone.png", title=title)
    if synth is not None:
        frf = None
        if frf_folder is not None:
            frf = load_branch(Path(frf_folder) / "branch.npz")
        plot_synthesized(bb, synth, out / "frf_synthesized.png", frf=frf, output=bb.output, title=title)
    return summary


def compare_nma_scene(scene: Scene, methods: str | None, defaults: RomOptions, *, out: Path, reference: str = "full",
                      progress=None) -> str:
    """``compare --analysis nma``: every method's backbone against the reference's (full order, or
    a method spec), errors in omega and zeta at amplitudes spread over the [nma] range; writes
    compare.csv, compare.md and compare_backbone.png into ``out`` and returns the Markdown."""
    from .analysis.compare import parse_method
    from .analysis.nma import compare_backbones
    from .plots import plot_compare_backbones
    from .results import atomic_write_text, write_table

    opts = nma_options(scene)
    specs = [parse_method(m, defaults) for m in (methods or COMPARE_METHODS).split(",") if m.strip()]
    check_solvable(scene)
    structure = create_structure(scene)
    specs, left_out = applicable_methods(specs, structure, given=methods is not None)
    check_nma(scene, structure, opts)
    results = compare_backbones(structure, specs, opts, reference=reference, progress=progress)
    rows = [r.row() for r in results]
    remove_stale(out, "compare")
    write_table(rows, out / "compare.csv")
    head = ("| method | size | status | points | offline s | online s | omega rel err | zeta rel err | "
            "amplitudes |")
    lines = [f"# {scene.name}: nonlinear mode {opts.mode}, every method against {results[0].label}", "",
             f"Scene {scene.path}, amplitude {opts.amplitude_start:g} to {opts.amplitude_end:g} m at "
             f"{opts.output or next(iter(structure.outputs))}, H = {opts.harmonics.H}, N = {opts.harmonics.N}, "
             f"self-excitation {opts.excitation}; errors are the largest over the amplitudes at which both were "
             f"solved exactly.", "", *((left_out, "") if left_out else ()), head, "|" + "---|" * 9]
    for r in rows:
        size = f"{r['size_min']}" if r["size_min"] == r["size_max"] else f"{r['size_min']}-{r['size_max']}"
        lines.append(f"| {r['method']} | {size} | {r['status']} | {r['points']} | {r['offline_s']:.2f} | "
                     f"{r['online_s']:.2f} | {r['omega_rel_err']:.2e} | {r['zeta_rel_err']:.2e} | "
                     f"{r['amplitudes_compared']} |" + (f" {r['failure']}" if r["failure"] else ""))
    md = "\n".join(lines) + "\n"
    atomic_write_text(out / "compare.md", md)
    plot_compare_backbones(results, out / "compare_backbone.png", title=f"{scene.name}: mode {opts.mode}")
    return md
