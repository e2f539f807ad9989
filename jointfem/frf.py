"""Full-order nonlinear frequency response: HBM residual + arclength continuation."""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from .contact.jenkins import pair_summary
from .continuation.arclength import ContinuationOptions, ContinuationPoint, continue_branch
from .hbm.harmonics import Harmonics
from .hbm.residual import HBMResidual
from .models.structure import Structure
from .results import FrequencyResponse

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SweepOptions:
    omega_start: float  # rad/s
    omega_end: float  # rad/s (smaller than omega_start for a downward sweep)
    harmonics: Harmonics = Harmonics(5, 256)
    continuation: ContinuationOptions = field(default_factory=ContinuationOptions)


def newton_system(problem):
    """``(U, omega) -> (R, dR/dU, dR/domega)`` of a problem with ``evaluate`` (HBMResidual, a ROM):
    the function ``solve_newton`` and the continuation take."""
    def fun(U, omega):
        ev = problem.evaluate(U, omega, jacobian=True)
        return ev.R, ev.J, ev.dR_domega
    return fun


def compute_scales(structure: Structure, omega_start: float, omega_end: float, *, num: int = 201) -> np.ndarray:
    """Per-DOF displacement scale: the largest stuck linear amplitude over the range, m.

    DOFs that barely move linearly (rotations, constrained directions) get a floor of
    1e-6 of the largest, so that every unknown is O(1) in the continuation.
    """
    w = np.linspace(min(omega_start, omega_end), max(omega_start, omega_end), num)
    X = np.abs(structure.linear_response(w)).max(axis=0)
    top = X.max()
    if not np.isfinite(top) or top <= 0:
        top = 1.0
    return np.maximum(X, 1e-6 * top)


def compute_rom_scales(structure: Structure, T: np.ndarray, omega_start: float, omega_end: float, *,
                       num: int = 101, displacements: np.ndarray | None = None) -> np.ndarray:
    """Scale per ROM coordinate: its stuck linear amplitude, but at least the amplitude at which
    its basis vector alone reaches the largest linear displacement of the structure.

    A mode far from the range barely moves linearly, yet a joint that slips or opens excites it
    to displacements of the size of the response: scaled by its linear amplitude alone, it
    would dominate the arclength and shrink every step.
    Coordinates listed in ``displacements`` are displacements themselves (the penalty ROM's
    internal variables p): their scale is the largest displacement.
    """
    w = np.linspace(min(omega_start, omega_end), max(omega_start, omega_end), num)
    X = np.abs(structure.linear_response(w))  # (num, q)
    top = np.abs(X @ T.T).max()
    if not np.isfinite(top) or top <= 0:
        top = 1.0
    col = np.abs(T).max(axis=0)
    zs = np.maximum(X.max(axis=0), top / np.where(col > 0, col, 1.0))
    if displacements is not None:
        zs[displacements] = top
    return zs


class StructureProblem:
    """HBM of a Structure: a physical model, or the Galerkin projection of one (CMS, tvd)."""

    adapt = None

    def __init__(self, structure: Structure, harmonics: Harmonics, basis: np.ndarray | None = None):
        self.structure, self.harmonics, self.basis = structure, harmonics, basis
        self.hbm = HBMResidual(structure, harmonics)
        self.num_unknowns = self.hbm.num_unknowns
        self.size = structure.num_dofs
        self.num_pairs = structure.num_pairs

    def evaluate(self, U, omega, *, jacobian=True):
        return self.hbm.evaluate(U, omega, jacobian=jacobian)

    def linear_solution(self, omega):
        return self.hbm.linear_solution(omega)

    def scales(self, omega_start, omega_end):
        if self.basis is not None:
            return compute_rom_scales(self.structure, self.basis, omega_start, omega_end)
        return compute_scales(self.structure, omega_start, omega_end)

    def states(self, U, omega, contact=None):
        if contact is None:
            contact = self.evaluate(U, omega, jacobian=False).contact
        if not contact:
            return np.zeros((self.harmonics.N, 0), dtype=np.int8)
        return np.concatenate([c.state_t for c in contact], axis=1)


def make_problem(model, harmonics: Harmonics):
    """The HBM problem of a Structure, a ReducedModel, a PenaltyROM or an ExactModel."""
    from .hbm.condensed import CondensedProblem
    from .rom.common import ExactModel, ReducedModel
    from .rom.penalty import PenaltyProblem, PenaltyROM

    if isinstance(model, ExactModel):
        return CondensedProblem(model.full, harmonics)
    if isinstance(model, PenaltyROM):
        return PenaltyProblem(model, harmonics)
    if isinstance(model, ReducedModel):
        return StructureProblem(model.structure, harmonics, model.T)
    return StructureProblem(model, harmonics)


def compute_frf(model, options: SweepOptions, *,
                callback: Callable[[ContinuationPoint], None] | None = None) -> FrequencyResponse:
    """Nonlinear FRF from the stuck linear solution at omega_start.

    ``model``: a Structure (full order), a ReducedModel (CMS, tvd), a PenaltyROM or an
    ExactModel (exact condensation on the contact gaps).
    """
    h = options.harmonics
    t0 = time.perf_counter()
    problem = make_problem(model, h)
    structure = problem.structure
    nh = h.num_hc
    q = problem.num_unknowns // nh
    dof_scale = problem.scales(options.omega_start, options.omega_end)
    # Unit scaled norm for a response of the size of the largest linear one.
    x_scale = np.tile(dof_scale, nh) * np.sqrt(q)
    if hasattr(problem, "force_scale"):
        r_scale = problem.force_scale()
    else:
        r_scale = float(max(np.abs(np.concatenate([structure.fc, structure.fs])).max(), 1e-300))
    lam_scale = abs(options.omega_end - options.omega_start)
    t_setup = time.perf_counter() - t0

    def evaluate(U, omega, jacobian):
        return problem.evaluate(U, omega, jacobian=jacobian)  # HBMResidual keeps the last one

    fun = newton_system(problem)

    def extra(U, omega):
        mask = getattr(problem, "mask", None)
        contact = evaluate(U, omega, False).contact
        if hasattr(problem, "pair_summary"):
            summary = problem.pair_summary(U, omega, contact)
        else:
            summary = (np.concatenate([pair_summary(c, g.pairs) for c, g in zip(contact, structure.contacts)])
                       if contact else np.zeros((0, 3)))
        return (problem.states(U, omega, contact), problem.size, None if mask is None else mask.copy(), summary)

    # a frequency response lives at positive omega: a branch that leaves twice the sweep's span
    # around it has turned back for good (folds inside that margin are followed)
    lo, hi = sorted((options.omega_start, options.omega_end))
    cont = options.continuation
    floor = getattr(problem, "tol_floor", 0.0)
    if cont.newton.tol < floor:
        log.warning("Newton tolerance %.1e raised to %.1e, the round-off floor of this method", cont.newton.tol, floor)
        cont = replace(cont, newton=replace(cont.newton, tol=floor))
    if cont.lam_bounds is None:
        cont = replace(cont, lam_bounds=(max(lo - (hi - lo), 0.0), hi + (hi - lo)))
    if cont.max_rel_change is None:
        # a forced response never passes through zero: a step that flips its sign went through an
        # unbounded (undamped) resonance or onto another branch, and is refused however short
        cont = replace(cont, max_rel_change=1.0)
    U0 = problem.linear_solution(options.omega_start)
    t1 = time.perf_counter()
    points = continue_branch(fun, U0, options.omega_start, options.omega_end, x_scale=x_scale,
                             lam_scale=lam_scale, r_scale=r_scale, options=cont,
                             callback=callback, extra=extra, adapt=problem.adapt)
    t_online = time.perf_counter() - t1
    physical = problem.rom.full if problem.adapt is not None else structure
    pair_names = tuple(nm for g in physical.contacts for nm in (g.names or
                       [f"pair{i}" for i in range(g.pairs.num_pairs)]))
    info = {"time_setup_s": t_setup, "time_online_s": t_online, "num_unknowns": problem.num_unknowns,
            "newton_tol": cont.newton.tol,
            # achieved max|R| / max|F| per point: below the Newton tol, or below kink_tol where a
            # root on a kink of the sampled law stalled Newton (docs/theory.md)
            "arrays": {"residual": np.array([p.residual for p in points]),
                       "rom_size": np.array([p.extra[1] for p in points]),
                       # per point and pair: dissipated energy per cycle (J), tangential relative
                       # displacement amplitude (m), peak normal force (N); contact.jenkins.pair_summary
                       "pair_energy_J": np.array([p.extra[3][:, 0] for p in points]),
                       "pair_tangential_amp_m": np.array([p.extra[3][:, 1] for p in points]),
                       "pair_peak_normal_N": np.array([p.extra[3][:, 2] for p in points])}}
    coords = [g.coords for g in physical.contacts]
    if coords and all(c is not None for c in coords):
        info["pair_coords"] = np.concatenate(coords)
    if problem.adapt is not None:
        info["active_set_events"] = dict(problem.events)
        # active internal variables per point (penalty ROM), in the order of the contact components
        info["arrays"]["active"] = np.array([p.extra[2] for p in points])
    return FrequencyResponse(
        omega=np.array([p.lam for p in points]),
        U=np.array([p.x for p in points]),
        iterations=np.array([p.iterations for p in points]),
        states=np.array([p.extra[0] for p in points], dtype=np.int8),
        harmonics=h, num_dofs=q, outputs=dict(structure.outputs), dof_names=structure.dof_names,
        pair_names=pair_names, info=info,
    )
