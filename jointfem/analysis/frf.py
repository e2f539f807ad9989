"""The nonlinear frequency response: arclength continuation in omega of any HBM problem."""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from ..continuation.arclength import (ContinuationError, ContinuationOptions, ContinuationPoint, NewtonOptions,
                                     continue_branch, solve_adaptive)
from ..harmonics import Harmonics
from ..hbm.forced import ForcedProblem
from ..hbm.problem import Problem, newton_system
from ..linalg import with_sweep_blas
from ..models.structure import Structure
from ..results import FrequencyResponse
from ..rom.common import Reduction
from .adaptive import HarmonicAdaptation, enough_harmonics, resize, trace
from .convergence import PEAK_SPAN, TruncationEstimator, amplitude_and_rms, top_harmonic_share
from .peaks import locate_peaks, output_amplitude, output_signal
from .stability import ExponentTracker, is_stable

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SweepOptions:
    omega_start: float  # rad/s
    omega_end: float  # rad/s (smaller than omega_start for a downward sweep)
    harmonics: Harmonics = Harmonics(5, 256)
    continuation: ContinuationOptions = field(default_factory=ContinuationOptions)
    locate_peaks: bool = True  # every output's peak solved to the Newton tolerance (analysis.peaks)
    # each peak located until nothing can beat its best point by more than this share of its error
    # bar (peak_tolerance); 0: to omega_rtol in omega (analysis.peaks), whatever the error bar
    peak_share: float = 0.1
    # Floquet exponents of every point by Hill's method (analysis.stability): dense up to
    # stability.DENSE_LIMIT first-order unknowns, else those near zero by shift-invert Arnoldi.  True
    # always, False never, None ("auto") wherever the problem has Hill matrices and computes them by
    # default (Problem.stability_not_by_default), up to stability_auto_unknowns (Problem.hill_size)
    # when that is set
    stability: bool | None = None
    stability_auto_unknowns: int | None = None
    # the exponents with the contact laws' memory where the problem knows it (stability.with_memory);
    # False: Hill's matrix as it is (on the lap2d penalty ROM 1.92 times the sweep against 4.23)
    stability_memory: bool = True
    # warn when a point's harmonic truncation estimate (analysis.convergence) passes this: the
    # first harmonic then changes by about e^2 / 4 when H grows by 2 (SDOF Jenkins, measured)
    harmonic_tol: float = 0.05
    # the band (rad/s) the branch may leave the window into at a fold and still come back from; None:
    # the window widened by its span on each side (continuation.lam_bounds, if set, wins)
    omega_limits: tuple[float, float] | None = None
    # each located peak's truncation error: the same peak at (3H, 2N) by analysis.convergence's
    # TruncationEstimator.peak (info["peak_errors"]); off by default: on the beam at 3 N it costs
    # 30-230 s a peak beside a 8-40 s sweep (docs/benchmarks_truncation.md)
    peak_error: bool = False
    # H chosen along the branch from harmonics.H (analysis.adaptive; the same N at every H): raised
    # where a point's truncation estimate passes the target, lowered where it is far below; None:
    # harmonics.H everywhere
    harmonic_adaptation: HarmonicAdaptation | None = None


# the least relative amplitude tolerance of a located peak: below every truncation error recorded at a
# located peak (5e-6 of it, the SDOF oscillator at H = 9; docs/benchmarks_truncation.md), and 1000
# times the amplitude's round-off at the Newton tolerance
PEAK_RTOL_MIN = 1e-7


def peak_tolerance(X: np.ndarray, harmonic_error: np.ndarray, amplitude_change: np.ndarray | None, outputs: dict,
                   harmonics: Harmonics, share: float) -> np.ndarray:
    """(num_points, num_outputs): the relative amplitude tolerance to which a peak at each point is
    located, ``share`` of the point's error bar, at least PEAK_RTOL_MIN.  The error bar: the change of
    the output's amplitude to the point at H + step where the adaptive sweep solved it
    (``amplitude_change``, NaN elsewhere), else the truncation estimate e read as a relative change
    e^2 / 4 (SweepOptions.harmonic_tol; measured on the SDOF oscillator).  Where e^2 / 4 is below the
    truth (the beam at H = 5: 9e-6 for a 5.1 % error, docs/theory.md) the tolerance is tighter, not
    looser."""
    bar = np.repeat((np.asarray(harmonic_error, float) ** 2 / 4)[:, None], len(outputs), axis=1)
    if amplitude_change is not None:
        amp = np.array([[output_amplitude(x, dof, harmonics) for dof in outputs.values()] for x in X])
        known = np.isfinite(amplitude_change) & (amp > 0)
        bar[known] = np.abs(amplitude_change[known]) / amp[known]
    return np.maximum(PEAK_RTOL_MIN, share * np.nan_to_num(bar, nan=0.0))


def _stability_of(points, H_of, problem_at, tracker_of, stopped, progress=None):
    """The Floquet exponents of an auto sweep's final points, each in the problem of its own H, in
    the branch's order (each H's ExponentTracker warm from its previous point).  Computed once the
    branch is traced, not as each point is accepted: a point solved at an H that is then raised, or
    only to lift the branch, is dropped (on the beam at 3 N, exact condensation, each accepted point
    having its exponents made stability cost 3.5 times the sweep; docs/theory.md).  Ctrl-C here
    leaves the rest without exponents and the sweep interrupted: its points are kept.
    ``progress(done, total)`` after each point's exponents."""
    out = []
    if progress is not None:
        progress(0, len(points))
    try:
        for p, H in zip(points, H_of):
            pb = problem_at(int(H))
            x = resize(p.x, pb.num_coefficients // pb.harmonics.num_hc, int(H))
            if pb.adaptation is not None:
                pb.adaptation.restore(pb.adaptation.state_of(x))
            ev = pb.evaluate(x, p.lam, jacobian=True)
            lead, method = tracker_of(pb)(x, p.lam, ev)
            out.append(replace(p, extra=replace(p.extra, stability=lead, stability_method=method)))
            if progress is not None:
                progress(len(out), len(points))
    except KeyboardInterrupt:
        log.warning("stability interrupted (Ctrl-C): %d of %d points have their exponents", len(out), len(points))
        if stopped is None:
            stopped = ContinuationError("stability interrupted (Ctrl-C)", points=points, interrupted=True)
        out += points[len(out):]
    return out, stopped


def peak_change(peak, omega: np.ndarray, X: np.ndarray, dof, h: Harmonics, change: np.ndarray) -> float | None:
    """The error bar of a located peak of an auto sweep: the largest |change| of the first-harmonic
    amplitude at H + step (analysis.adaptive's check) over the branch point nearest the peak (in
    omega and amplitude, each over its range on the branch) and its two neighbours, or None where
    none of them was checked (the estimate e did not call for it).  ``X``: the points at ``h``."""
    amp = np.array([amplitude_and_rms(output_signal(x, dof, h), h)[0] for x in X])
    w_scale, a_scale = max(np.ptp(omega), 1e-300), max(np.ptp(amp), 1e-300)
    i = int(np.argmin(((omega - peak.omega) / w_scale) ** 2 + ((amp - peak.amplitude) / a_scale) ** 2))
    near = np.abs(change[max(i - 1, 0):i + 2])
    near = near[np.isfinite(near)]
    return float(near.max()) if near.size else None


class SweepIncomplete(ContinuationError):
    """A sweep that stopped before omega_end (a stall, a budget, Ctrl-C): ``frf`` holds the points
    converged before it, with info["status"] = "incomplete" and info["stop_reason"]."""

    def __init__(self, message: str, *, frf: FrequencyResponse, points: list | None = None,
                 interrupted: bool = False):
        super().__init__(message, points=points, interrupted=interrupted)
        self.frf = frf


def create_problem(model: Structure | Reduction, harmonics: Harmonics) -> Problem:
    """The forced-response problem of a physical Structure (full order) or of a reduced model
    (its own ``create_problem``: a Galerkin ROM, the penalty ROM, the exact condensation)."""
    if isinstance(model, Structure):
        return ForcedProblem(model, harmonics)
    if isinstance(model, Reduction):
        return model.create_problem(harmonics)
    raise TypeError(f"compute_frf: expected a Structure or a reduced model, got {type(model).__name__}")


@dataclass(frozen=True)
class Resume:
    """A branch that stopped (branch.npz of an incomplete sweep): its points and the step the
    continuation would have taken from the last one."""

    omega: np.ndarray  # rad/s, per point
    U: np.ndarray  # (points, unknowns)
    iterations: np.ndarray
    residual: np.ndarray
    ds_next: float
    # per point, the H it was solved at (a branch whose H changes along it: U holds every point at
    # the largest H, the harmonics above a point's own zero); None: one H
    harmonics: np.ndarray | None = None


def resumed_points(problem: Problem, lam: np.ndarray, X: np.ndarray, residual: np.ndarray, record, *,
                   iterations: np.ndarray | None = None, ds_next: np.ndarray | None = None):
    """The points of a stopped branch (parameter ``lam``, coefficients ``X`` per point) but its last,
    recorded again as ContinuationPoints (each in the active set it was solved in), the last point
    (x, lam) to continue from with the problem restored to its state there, and the heading there
    (the secant of the last step), for continue_branch's ``resume``.  Shared by the sweeps in omega
    and in force that --resume continues."""
    X, lam = np.asarray(X, float), np.asarray(lam, float)
    if X.ndim != 2 or X.shape[1] != problem.num_coefficients or lam.size < 2:
        raise ValueError(f"resume: a branch of {X.shape} coefficients and {lam.size} points cannot go on in a "
                         f"problem of {problem.num_coefficients} coefficients")
    adapt = problem.adaptation
    before = []
    for i in range(lam.size - 1):
        if adapt is not None:  # (each point is recorded in the state it was solved in)
            adapt.restore(adapt.state_of(X[i]))
        before.append(ContinuationPoint(X[i], float(lam[i]), 0 if iterations is None else int(iterations[i]), 0.0,
                                        record(X[i], float(lam[i])), residual=float(residual[i]),
                                        ds_next=0.0 if ds_next is None else float(ds_next[i])))
    if adapt is not None:
        adapt.restore(adapt.state_of(X[-1]))
    return before, (X[-1], float(lam[-1])), (X[-1] - X[-2], lam[-1] - lam[-2])


def default_omega_limits(omega_min: float, omega_max: float) -> tuple[float, float]:
    """The band [rad/s] a sweep's branch may leave its window into at a fold and still come back
    from, when the scene gives no [solver] omega_limits: an octave each side of the window."""
    return 0.5 * omega_min, 2.0 * omega_max


@with_sweep_blas
def compute_frf(model: Structure | Reduction, options: SweepOptions, *,
                callback: Callable[[ContinuationPoint], None] | None = None,
                resume: Resume | None = None,
                stability_progress: Callable[[int, int], None] | None = None) -> FrequencyResponse:
    """Nonlinear FRF from the stuck linear solution at omega_start.

    ``callback(point)`` per accepted point; ``stability_progress(done, total)`` as an auto sweep's
    stability is made, once its branch is traced (points with exponents, of the branch's).
    ``model``: a Structure (full order), or what jointfem.rom.build_rom returns (a Galerkin ROM:
    CMS or tvd; the penalty ROM; the exact condensation on the contact gaps).
    ``resume``: go on with a branch that stopped, from its last point, with the step it would have
    taken (the result holds its points and the new ones).
    """
    h = options.harmonics
    t0 = time.perf_counter()
    problem = create_problem(model, h)
    nh = h.num_hc
    q = problem.num_coefficients // nh
    scales = problem.scales(options.omega_start, options.omega_end)
    lam_scale = abs(options.omega_end - options.omega_start)
    t_setup = time.perf_counter() - t0

    # Hill's method needs the Jacobian at the point, which the continuation has just evaluated for
    # the tangent (the problem returns it again from its last evaluation)
    # (decided once, on the largest system the problem can have: the penalty ROM's grows, and so
    # does every problem's where H changes along the branch)
    adaptation = options.harmonic_adaptation
    if resume is not None and (adaptation is None) != (resume.harmonics is None):
        raise ValueError("compute_frf: a branch whose H changes along it resumes as one, and only as one")
    H_most = h.H if adaptation is None else max(h.H, adaptation.H_max)
    if options.stability is not None:
        stability = options.stability
    else:
        stability = problem.stability_not_by_default is None and (
            options.stability_auto_unknowns is None
            or problem.hill_size * (2 * H_most + 1) // nh <= options.stability_auto_unknowns)
    problems = {h.H: problem}
    recorders = {}
    trackers: dict[int, ExponentTracker] = {}  # id(problem) -> its tracker along the branch
    # each point's exponents as it is accepted; an auto sweep's are made for its final points
    # once the branch is traced (_stability_of)
    each_point = stability and adaptation is None

    def problem_at(H: int) -> Problem:
        if H not in problems:
            problems[H] = create_problem(model, Harmonics(H, h.N))
        return problems[H]

    def tracker_of(pb: Problem) -> ExponentTracker:
        if id(pb) not in trackers:
            trackers[id(pb)] = ExponentTracker(pb, memory=options.stability_memory)
        return trackers[id(pb)]

    def recorder(pb: Problem):
        if id(pb) in recorders:
            return recorders[id(pb)]
        hh = pb.harmonics
        exponent = tracker_of(pb)

        def record(U, omega):
            # (called as the continuation accepts a point: the unknowns now are those it was solved in)
            ev = pb.evaluate(U, omega, jacobian=each_point)
            rec = replace(pb.record(U, omega, ev), harmonic_error=top_harmonic_share(ev.contact, hh),
                          unknowns=pb.num_unknowns, harmonics=hh.H)
            if adaptation is not None:
                rec = replace(rec, harmonics_enough=enough_harmonics(ev.contact, hh, adaptation))
            if each_point:
                lead, method = exponent(U, omega, ev)
                rec = replace(rec, stability=lead, stability_method=method)
            return rec

        recorders[id(pb)] = record
        return record

    record = recorder(problem)

    # a frequency response lives at positive omega: a branch that leaves the octave around the
    # window (omega_min / 2 to 2 omega_max) has turned back for good (folds inside it are followed;
    # the window widened by its span each side was too narrow for the 3D lap joint at 5 N, whose
    # separated loop folds at 1290 rad/s below a window of 1620-1780 rad/s, issue 14)
    lo, hi = sorted((options.omega_start, options.omega_end))
    cont = options.continuation
    if cont.newton.tol < problem.tol_floor:
        log.warning("Newton tolerance %.1e raised to %.1e, the round-off floor of this method", cont.newton.tol,
                    problem.tol_floor)
        cont = replace(cont, newton=replace(cont.newton, tol=problem.tol_floor))
    if cont.lam_bounds is None:
        cont = replace(cont, lam_bounds=options.omega_limits or default_omega_limits(lo, hi))
    if cont.max_rel_change is None:
        # a forced response never passes through zero: a step that flips its sign went through an
        # unbounded (undamped) resonance or onto another branch, and is refused however short
        cont = replace(cont, max_rel_change=1.0)
    U0, omega0, before, heading = problem.initial_guess(options.omega_start), options.omega_start, [], None
    if resume is not None and adaptation is None:
        before, (U0, omega0), heading = resumed_points(problem, resume.omega, resume.U, resume.residual, record,
                                                       iterations=resume.iterations)
        heading = heading, resume.ds_next
    t1 = time.perf_counter()
    steps = {}
    stopped = None
    adaptive = None
    if adaptation is not None:
        earlier = None
        if resume is not None:  # each point recorded again in the problem of its H
            earlier = []
            for i, H_i in enumerate(np.asarray(resume.harmonics, int)):
                pb = problem_at(int(H_i))
                x_i = resize(np.asarray(resume.U[i], float), pb.num_coefficients // pb.harmonics.num_hc, int(H_i))
                if pb.adaptation is not None:
                    pb.adaptation.restore(pb.adaptation.state_of(x_i))
                w_i = float(resume.omega[i])
                earlier.append(ContinuationPoint(x_i, w_i, int(resume.iterations[i]), 0.0, recorder(pb)(x_i, w_i),
                                                 residual=float(resume.residual[i]), ds_next=resume.ds_next))
            earlier = (earlier, [int(H_i) for H_i in resume.harmonics])
        adaptive = trace(problem_at, h.H, adaptation, omega_start=options.omega_start, omega_end=options.omega_end,
                         x0=U0, options=cont, record_at=recorder, callback=callback, resume=earlier)
        if adaptive.stopped is not None and len(adaptive.points) < 2:
            raise adaptive.stopped
        points, stopped, steps = adaptive.points, adaptive.stopped, adaptive.stats
        if stability:
            points, stopped = _stability_of(points, adaptive.H_of, problem_at, tracker_of, stopped,
                                            stability_progress)
        # the branch's points are at its largest H: so are its peaks, layout and result
        problem = problem_at(adaptive.H_top)
        h, nh = problem.harmonics, problem.harmonics.num_hc
        q = problem.num_coefficients // nh
        scales = problem.scales(options.omega_start, options.omega_end)
    else:
        try:
            points = continue_branch(newton_system(problem), U0, omega0, options.omega_end,
                                     x_scale=scales.x, lam_scale=lam_scale, r_scale=scales.r, options=cont,
                                     callback=callback, extra=record, adapt=problem.adaptation, stats=steps,
                                     resume=heading, traced=before)
        except ContinuationError as exc:
            if len(before) + len(exc.points) < 2:
                raise
            # the branch so far is a result: kept, marked incomplete, and raised with it below
            points, stopped = exc.points, exc
        points = before + points
    records = [p.extra for p in points]
    layout = problem.layout
    omega, X = np.array([p.lam for p in points]), np.array([p.x for p in points])
    residual = np.array([p.residual for p in points])
    peaks = {}
    t_peaks = time.perf_counter()
    if options.locate_peaks and not (stopped is not None and stopped.interrupted):  # Ctrl-C: no more solves
        rtol = None
        if options.peak_share > 0:
            change = None if adaptive is None else adaptive.amplitude_change
            rtol = peak_tolerance(X, np.array([r.harmonic_error for r in records]), change, layout.outputs, h,
                                  options.peak_share)
        peaks = locate_peaks(problem, X, omega, residual, records, layout.outputs, scales=scales,
                             lam_scale=lam_scale, newton=cont.newton, amplitude_rtol=rtol)
    t_online = time.perf_counter() - t1
    t_peaks = time.perf_counter() - t_peaks
    peak_errors = {}
    if options.peak_error and any(p.located for p in peaks.values()):
        t_err = time.perf_counter()
        estimate = TruncationEstimator(lambda hh: create_problem(model, hh), h, layout.outputs,
                                       window=(options.omega_start, options.omega_end), newton=cont.newton)
        peak_errors = {name: estimate.peak(p.x, p.omega, name, span=PEAK_SPAN * p.omega)
                       for name, p in peaks.items() if p.located}
        t_err = time.perf_counter() - t_err
    unknowns = np.array([r.unknowns for r in records])
    # the largest system Newton solved on the branch (the penalty ROM's changes along it: per point
    # in arrays["unknowns"])
    # time_online_s: the sweep and the peak search; time_peaks_s: the peak search alone (its corrector
    # solves are in info["peaks"][name].solves)
    info = {"time_setup_s": t_setup, "time_online_s": t_online, "time_peaks_s": t_peaks, "num_unknowns": int(unknowns.max()),
            "newton_tol": cont.newton.tol, "continuation": steps,
            # achieved max|R| / max|F| per point: below the Newton tol, or below kink_tol where a
            # root on a kink of the sampled law stalled Newton (docs/theory.md)
            "arrays": {"residual": residual,
                       # the step the continuation takes from each point (compute_frf's ``resume``)
                       "ds_next": np.array([p.ds_next for p in points]),
                       "rom_size": np.array([r.size for r in records]),
                       "unknowns": unknowns,
                       # per point and pair: dissipated energy per cycle (J), tangential relative
                       # displacement amplitude (m), peak normal force (N); ContactLaw.summary
                       "pair_energy_J": np.array([r.pair_summary[:, 0] for r in records]),
                       "pair_tangential_amp_m": np.array([r.pair_summary[:, 1] for r in records]),
                       "pair_peak_normal_N": np.array([r.pair_summary[:, 2] for r in records])}}
    if peaks:
        info["peaks"] = peaks
    if peak_errors:
        info["peak_errors"] = peak_errors  # name -> analysis.convergence.PeakError
        info["time_peak_error_s"] = t_err
    he = np.array([r.harmonic_error for r in records])
    info["arrays"]["harmonic_error"] = he
    info["arrays"]["harmonics"] = np.array([r.harmonics for r in records])
    tol = options.harmonic_tol if adaptation is None else adaptation.target
    if adaptive is not None:
        H_of = adaptive.H_of
        info["harmonics_adaptive"] = {
            "target": adaptation.target, "H_start": options.harmonics.H, "H_min": adaptation.H_min,
            "H_max": adaptation.H_max, "H_top": adaptive.H_top, "reached": bool(he.max() <= tol),
            "points_per_H": {int(H): int((H_of == H).sum()) for H in np.unique(H_of)},
            "changes": [{"omega_rad_s": w, "from": a, "to": b} for w, a, b in adaptive.changes],
            "lowering_refused": [{"omega_rad_s": w, "from": a, "to": b, "why": why} for w, a, b, why in adaptive.refused]}
        # per point: the largest change of an output from H to H + step over the branch's largest
        # amplitude so far (analysis.adaptive's check; NaN where the estimate did not call for it)
        info["arrays"]["harmonic_check"] = adaptive.check
        # per point and output: the change of the first-harmonic amplitude (m) from the point to the
        # point solved at H + step (NaN where not checked): the error bars of frf.png, and each
        # located peak's (info["peak_changes"])
        info["arrays"]["amplitude_change_m"] = adaptive.amplitude_change
        info["peak_changes"] = {
            name: peak_change(peaks[name], omega, X, dof, h, adaptive.amplitude_change[:, j])
            for j, (name, dof) in enumerate(layout.outputs.items()) if name in peaks and peaks[name].located}
    if he.max() > tol:
        k = int(np.argmax(he))
        at = f"H = {h.H}" if adaptive is None else f"at H = {int(info['arrays']['harmonics'][k])}, harmonics_max"
        info["harmonic_warning"] = (f"harmonic truncation estimate {he[k]:.3g} > {tol:g} at omega = "
                                    f"{points[k].lam:.6g} rad/s ({int((he > tol).sum())} of "
                                    f"{he.size} points): more harmonics are needed there ({at})")
        log.warning(info["harmonic_warning"])
    lead = np.array([np.nan if r.stability is None else r.stability for r in records], dtype=complex)
    re = lead.real
    if np.isfinite(re).all():
        info["stability"] = "computed"
        stable = np.array([is_stable(r, w) for r, w in zip(re, omega)])
        info["arrays"]["floquet_max_real"] = re  # 1/s: the largest real part of the Floquet exponents
        # 1/s: its imaginary part (>= 0): zero where a real exponent leads (a fold's kind of loss of
        # stability), else a complex pair (a Neimark-Sacker or, near omega / 2, a period-doubling
        # kind), from which the motion may settle on a nearby torus or period-doubled orbit
        # (docs/theory.md, Stability of every point)
        info["arrays"]["floquet_leading_imag"] = lead.imag
        # per point, how: Hill's matrix as it is ("hill"), or with the contact laws' memory
        # ("hill-memory": the stuck sliders' e^{-s tau}; docs/theory.md, Stability with slip)
        info["arrays"]["floquet_method"] = np.array([r.stability_method or "hill" for r in records])
        info["arrays"]["stable"] = stable
        # where the stability changes between two points: a fold (omega turns back) or a bifurcation
        turn = np.zeros(omega.size, bool)
        d = np.sign(np.diff(omega))
        turn[1:-1] = d[1:] * d[:-1] < 0
        info["arrays"]["fold"] = turn
        change = np.zeros(omega.size, bool)
        change[1:] = stable[1:] != stable[:-1]
        info["arrays"]["stability_change"] = change
    elif options.stability is False:
        info["stability"] = "not computed (stability off)"
    elif not stability and problem.stability_not_by_default is not None:
        info["stability"] = f"not computed: {problem.stability_not_by_default}"
    elif not stability:
        info["stability"] = (f"not computed: {problem.hill_size} unknowns > {options.stability_auto_unknowns}, "
                             f"the automatic limit (an eigensolve of twice the unknowns of Hill's problem per "
                             f"point; --stability on computes it)")
    elif stability and stopped is not None and stopped.interrupted:
        info["stability"] = (f"not computed: interrupted (Ctrl-C) with {int(np.isfinite(re).sum())} of {omega.size} "
                             f"points' exponents made")
    elif failures := [f for t in trackers.values() for f in t.failures]:
        w_fail, what = failures[0]
        info["stability"] = (f"not computed: Hill's eigensolve failed at {len(failures)} of {omega.size} "
                             f"points (first at omega = {w_fail:.6g} rad/s: {what})")
        log.warning(info["stability"])
    else:
        info["stability"] = f"not computed: {problem.no_stability or 'this problem has no Hill operators'}"
    if layout.pair_coords is not None:
        info["pair_coords"] = layout.pair_coords
    if layout.pair_areas is not None:
        info["pair_area_m2"] = layout.pair_areas
    info.update(problem.branch_info())
    if all(r.active is not None for r in records):
        # active internal variables per point (penalty ROM), in the order of the contact components
        info["arrays"]["active"] = np.array([r.active for r in records])
    info["status"] = "complete" if stopped is None else "incomplete"
    if stopped is not None:
        info["stop_reason"] = (str(stopped).replace("lam = ", "omega [rad/s] = ").replace("lam_end", "omega_end")
                               .replace("(lam_bounds)", "(widen [solver] omega_limits to follow it)"))
    frf = FrequencyResponse(
        omega=omega,
        U=X,
        iterations=np.array([p.iterations for p in points]),
        states=np.array([r.states for r in records], dtype=np.int8),
        harmonics=h, num_dofs=q, outputs=dict(layout.outputs), dof_names=layout.dof_names,
        pair_names=layout.pair_names, info=info,
    )
    if stopped is not None:  # (the continuation's lam is omega here)
        raise SweepIncomplete(info["stop_reason"], frf=frf, points=points, interrupted=stopped.interrupted)
    return frf


@dataclass(frozen=True)
class Solution:
    """One periodic solution at a fixed omega (``solve_at``)."""

    omega: float  # rad/s
    U: np.ndarray  # the problem's harmonic coefficients (layout: problem.layout)
    amplitudes: dict  # output name -> first-harmonic amplitude, m
    record: object  # the problem's PointRecord: contact states, pair summary, size
    iterations: int
    residual: float  # achieved max|R| / max|F|


def solve_at(model: Structure | Reduction, omega: float, harmonics: Harmonics, *, guess: np.ndarray | None = None,
             newton: NewtonOptions = NewtonOptions()) -> Solution:
    """The periodic response at one omega (rad/s) by Newton, from ``guess`` or the stuck linear
    solution.  Where the response is multi-valued (past a fold), which solution Newton finds
    depends on the guess: give one from a branch (FrequencyResponse.U) to pick it.  Raises
    ConvergenceError with the last residual if Newton fails."""
    problem = create_problem(model, harmonics)
    scales = problem.scales(omega, omega * (1 + 1e-3))
    U0 = problem.initial_guess(omega) if guess is None else np.asarray(guess, float)
    opts = replace(newton, tol=max(newton.tol, problem.tol_floor))
    adapt = problem.adaptation
    if adapt is not None and guess is not None:
        adapt.restore(adapt.state_of(U0))  # every coefficient of the guess that is not zero is solved
    # (the penalty ROM: solved again while an inactive pair breaks its law)
    U, it = solve_adaptive(newton_system(problem), U0, omega, adapt=adapt, x_scale=scales.x, r_scale=scales.r,
                           options=opts)
    ev = problem.evaluate(U, omega, jacobian=False)
    nh = harmonics.num_hc
    q = problem.num_coefficients // nh
    amps = {}
    for name, out in problem.layout.outputs.items():
        c, s_ = U[harmonics.cos(1, q)], U[harmonics.sin(1, q)]
        amps[name] = float(np.hypot(out @ c, out @ s_) if np.ndim(out) else np.hypot(c[out], s_[out]))
    res = float(np.max(np.abs(ev.R)) / np.max(np.abs(scales.r))) if ev.R.size else 0.0
    return Solution(omega, U, amps, replace(problem.record(U, omega, ev), unknowns=problem.num_unknowns), it, res)
