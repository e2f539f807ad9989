"""Full-order nonlinear frequency response: HBM residual + arclength continuation."""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

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


def compute_frf(structure: Structure, options: SweepOptions, *,
                callback: Callable[[ContinuationPoint], None] | None = None) -> FrequencyResponse:
    """Nonlinear FRF of the full structure from the stuck linear solution at omega_start."""
    h = options.harmonics
    t0 = time.perf_counter()
    hbm = HBMResidual(structure, h)
    n = structure.num_dofs
    dof_scale = compute_scales(structure, options.omega_start, options.omega_end)
    # Unit scaled norm for a response of the size of the largest linear one.
    x_scale = np.tile(dof_scale, h.num_hc) * np.sqrt(n)
    r_scale = float(max(np.abs(hbm.F_ext).max(), 1e-300))
    lam_scale = abs(options.omega_end - options.omega_start)
    t_setup = time.perf_counter() - t0

    # The continuation evaluates an accepted point again for its tangent and for its contact
    # states: keep the last evaluation instead of running the AFT three times.
    last = {"key": None, "ev": None}

    def evaluate(U, omega, jacobian):
        key = (float(omega), U.tobytes())
        ev = last["ev"]
        if last["key"] != key or (jacobian and ev.J is None):
            ev = hbm.evaluate(U, omega, jacobian=jacobian)
            last.update(key=key, ev=ev)
        return ev

    def fun(U, omega):
        ev = evaluate(U, omega, True)
        return ev.R, ev.J, ev.dR_domega

    def states(U, omega):
        ev = evaluate(U, omega, False)
        if not ev.contact:
            return np.zeros((h.N, 0), dtype=np.int8)
        return np.concatenate([c.state_t for c in ev.contact], axis=1)

    U0 = hbm.linear_solution(options.omega_start)
    t1 = time.perf_counter()
    points = continue_branch(fun, U0, options.omega_start, options.omega_end, x_scale=x_scale,
                             lam_scale=lam_scale, r_scale=r_scale, options=options.continuation,
                             callback=callback, extra=states)
    t_online = time.perf_counter() - t1
    pair_names = tuple(nm for g in structure.contacts for nm in (g.names or
                       [f"pair{i}" for i in range(g.pairs.num_pairs)]))
    return FrequencyResponse(
        omega=np.array([p.lam for p in points]),
        U=np.array([p.x for p in points]),
        iterations=np.array([p.iterations for p in points]),
        states=np.array([p.extra for p in points], dtype=np.int8),
        harmonics=h, num_dofs=n, outputs=dict(structure.outputs), dof_names=structure.dof_names,
        pair_names=pair_names,
        info={"time_setup_s": t_setup, "time_online_s": t_online, "num_unknowns": hbm.num_unknowns,
              # achieved max|R| / max|F| per point: below the Newton tol, or below kink_tol where a
              # root on a kink of the sampled law stalled Newton (docs/theory.md)
              "arrays": {"residual": np.array([p.residual for p in points])}},
    )
