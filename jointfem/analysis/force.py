"""The response against the force's amplitude at a fixed omega: continuation in a force scale.

Every external force of the model (harmonic and static) is multiplied by ``lam``; omega stays
fixed.  This follows a joint from stuck (small forces: the response grows linearly) through
microslip to gross slip or separation at one frequency, the way a stepped-sine test at rising
level does.  The contact forces vanish at zero gaps (f(0) = f0, balanced by the preload), so the
residual at x = 0 is minus the external force, R(0) = -F, and the scaled residual is

    R_lam(x) = R(x) - (1 - lam) R(0),     dR_lam/dlam = -F = R(0),

for any problem of the protocol (hbm.problem), the penalty ROM included: its force changes with
its active set, and R(0) is taken again whenever that changes.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from ..continuation.arclength import Adaptive, ContinuationError, ContinuationOptions, continue_branch
from ..harmonics import Harmonics
from ..hbm.problem import Evaluation, Problem, Scales, newton_system
from ..linalg import with_sweep_blas
from ..models.structure import Structure
from ..results import first_harmonic_amplitude
from ..rom.common import Reduction
from .frf import create_problem, resumed_points


class ForceScaled(Problem):
    """A forced problem at fixed ``omega`` whose parameter is the force scale."""

    def __init__(self, inner: Problem, omega: float):
        self.inner, self.omega = inner, float(omega)
        self.harmonics, self.layout, self.tol_floor = inner.harmonics, inner.layout, inner.tol_floor
        self.adaptation = None if inner.adaptation is None else _AtOmega(self)
        self._minus_F = None

    @property
    def num_coefficients(self) -> int:
        return self.inner.num_coefficients

    def unknowns(self):
        return self.inner.unknowns()

    def minus_force(self) -> np.ndarray:
        """R(0) = -F, taken again after the inner problem changed (the penalty ROM's active set)."""
        if self._minus_F is None:
            self._minus_F = self.inner.evaluate(np.zeros(self.num_coefficients), self.omega, jacobian=False).R.copy()
        return self._minus_F

    def evaluate(self, x, lam, *, jacobian=True) -> Evaluation:
        r0 = self.minus_force()
        ev = self.inner.evaluate(x, self.omega, jacobian=jacobian)
        return Evaluation(ev.R - (1.0 - lam) * r0, ev.J, r0 if jacobian else None, ev.contact)

    def initial_guess(self, lam):
        return lam * self.inner.initial_guess(self.omega)

    def scales(self, lam_start, lam_end) -> Scales:
        s = self.inner.scales(self.omega, self.omega * (1.0 + 1e-6))
        big = max(abs(lam_start), abs(lam_end), 1e-300)
        return Scales(s.x * big, s.r * big)

    def record(self, x, lam, evaluation):
        return self.inner.record(x, self.omega, evaluation)

    def branch_info(self) -> dict:
        return self.inner.branch_info()

    def hill_operators(self, lam):
        return self.inner.hill_operators(self.omega)

    def num_dynamic(self):
        return self.inner.num_dynamic()


class _AtOmega(Adaptive):
    """The inner problem's hooks, at the fixed omega; a change makes the force be taken again."""

    def __init__(self, outer: ForceScaled):
        self.outer = outer
        self.max_redo = outer.inner.adaptation.max_redo

    def unknowns(self):
        return self.outer.inner.adaptation.unknowns()

    def state_of(self, x):
        return self.outer.inner.adaptation.state_of(x)

    def before_step(self, x, lam) -> bool:
        changed = self.outer.inner.adaptation.before_step(x, self.outer.omega)
        if changed:
            self.outer._minus_F = None
        return changed

    def after_converge(self, x, lam) -> bool:
        changed = self.outer.inner.adaptation.after_converge(x, self.outer.omega)
        if changed:
            self.outer._minus_F = None
        return changed

    def restore(self, state) -> None:
        self.outer.inner.adaptation.restore(state)
        self.outer._minus_F = None


@dataclass
class ForceResponse:
    """A branch against the force scale at fixed omega."""

    omega: float  # rad/s
    scale: np.ndarray  # the force scale per point (1 = the scene's forces)
    U: np.ndarray
    states: np.ndarray  # (points, N, pairs) int8
    harmonics: Harmonics
    outputs: dict  # name -> index or recovery row
    info: dict
    pair_names: tuple = ()
    pair_coords: np.ndarray | None = None  # (pairs, 3) m, for the interface pictures
    pair_areas: np.ndarray | None = None  # (pairs,) m^2, for the per-area quantities

    def amplitude(self, name: str) -> np.ndarray:
        """First-harmonic amplitude of an output at every point, m."""
        return first_harmonic_amplitude(self.U, self.harmonics, self.outputs[name])


class ForceIncomplete(ContinuationError):
    """A force sweep that stopped before scale_end (a stall, a budget, Ctrl-C): ``response`` holds the
    points converged before it, with info["status"] = "incomplete" and info["stop_reason"]."""

    def __init__(self, message: str, *, response: ForceResponse, points: list | None = None,
                 interrupted: bool = False):
        super().__init__(message, points=points, interrupted=interrupted)
        self.response = response


@with_sweep_blas
def compute_force_response(model: Structure | Reduction, omega: float, harmonics: Harmonics, scale_start: float,
                           scale_end: float, continuation: ContinuationOptions = ContinuationOptions(), *,
                           callback=None, resume: dict | None = None) -> ForceResponse:
    """Continue the response at ``omega`` (rad/s) in the force scale from ``scale_start`` (the
    stuck linear solution there) to ``scale_end``.

    A branch that cannot go on (a stall, a budget, Ctrl-C) after at least two points raises
    ForceIncomplete with its points as a ForceResponse (status "incomplete"); with fewer, the
    ContinuationError.  ``resume``: the arrays of such a branch (branch.npz: ``scale``, ``U``,
    ``residual``, ``ds_next``), continued from its last point with the step it would have taken,
    so that the result is the whole branch, as if it had not stopped."""
    if not scale_start > 0 or not scale_end > scale_start:
        raise ValueError(f"force scales must be 0 < start < end, got {scale_start}, {scale_end}")
    t0 = time.perf_counter()
    problem = ForceScaled(create_problem(model, harmonics), omega)
    sc = problem.scales(scale_start, scale_end)
    cont = replace(continuation, max_rel_change=continuation.max_rel_change or 1.0,
                   lam_bounds=continuation.lam_bounds or (0.0, 2 * scale_end))
    if cont.newton.tol < problem.tol_floor:
        cont = replace(cont, newton=replace(cont.newton, tol=problem.tol_floor))

    def record(x, lam):
        return replace(problem.record(x, lam, problem.evaluate(x, lam, jacobian=False)), unknowns=problem.num_unknowns)

    x0, lam0, before, heading = problem.initial_guess(scale_start), scale_start, [], None
    if resume is not None:
        before, (x0, lam0), heading = resumed_points(problem, resume["scale"], resume["U"], resume["residual"], record,
                                                     ds_next=resume["ds_next"])
        heading = heading, float(resume["ds_next"][-1])
    steps = {}
    stopped = None
    try:
        points = continue_branch(newton_system(problem), x0, lam0, scale_end,
                                 x_scale=sc.x, lam_scale=scale_end - scale_start, r_scale=sc.r, options=cont,
                                 callback=callback, adapt=problem.adaptation, stats=steps, extra=record,
                                 resume=heading, traced=before)
    except ContinuationError as exc:
        if len(before) + len(exc.points) < 2:
            raise
        points, stopped = exc.points, exc  # the branch so far is a result: kept, marked incomplete
    points = before + points
    records = [p.extra for p in points]
    unknowns = np.array([r.unknowns for r in records])
    info = {"continuation": steps, "num_unknowns": int(unknowns.max()), "time_s": time.perf_counter() - t0,
            "arrays": {"residual": np.array([p.residual for p in points]),
                       # the step the continuation takes from each point (``resume``)
                       "ds_next": np.array([p.ds_next for p in points]),
                       "rom_size": np.array([r.size for r in records]), "unknowns": unknowns,
                       "pair_energy_J": np.array([r.pair_summary[:, 0] for r in records]),
                       "pair_tangential_amp_m": np.array([r.pair_summary[:, 1] for r in records]),
                       "pair_peak_normal_N": np.array([r.pair_summary[:, 2] for r in records])}}
    layout = problem.layout
    response = ForceResponse(omega, np.array([p.lam for p in points]), np.array([p.x for p in points]),
                             np.array([r.states for r in records], dtype=np.int8), harmonics,
                             dict(layout.outputs), info, layout.pair_names, layout.pair_coords, layout.pair_areas)
    if stopped is not None:
        info.update(status="incomplete", stop_reason=str(stopped))
        raise ForceIncomplete(str(stopped), response=response, points=points, interrupted=stopped.interrupted)
    return response


__all__ = ["ForceScaled", "ForceResponse", "ForceIncomplete", "compute_force_response", "ContinuationError"]
