"""Peaks located to the solver's tolerance, not to the spacing of the points.

The first-harmonic amplitude A of an output is largest at some point i of a branch.  Each
segment between consecutive points from i-2 to i+2 is parametrised by t in [0, 1]: the branch
point where it crosses the hyperplane through (1 - t) z_k + t z_k+1 normal to the chord
z_k+1 - z_k (in the continuation's scaled variables; continuation.correct).  Every evaluation is
a solved branch point, so the peak's amplitude and frequency are those of a solution, whether or
not the branch folds near it.

With a sampled friction law, A is not smooth near a peak: a time sample that changes state puts a
kink in it, and between kinks the curve sags (scallops, about 1e-4 of the amplitude at N = 128),
so its largest value sits on a kink, and there may be several local maxima close together.  The
search therefore samples each segment at ``grid`` values of t, and runs Brent's bounded search
(scipy.optimize.minimize_scalar, robust to kinks in a unimodal interval) around every local
maximum of the samples that could still beat the best one (a scallop rises to its kink at most as
steeply as between its samples: a local maximum v_j can reach v_j + max(|v_j - v_j-1|,
|v_j+1 - v_j|)), until omega is known to ``omega_rtol``; the largest result is the peak.

A largest amplitude at the first or last point is an *edge* of the range, not a peak, and is
reported as such.
"""
from __future__ import annotations

import logging
from dataclasses import asdict, dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from ..continuation.arclength import ContinuationError, ConvergenceError, NewtonOptions, correct
from ..hbm.problem import PointRecord, Problem, Scales, newton_system

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Peak:
    """omega (rad/s) and first-harmonic amplitude (m) of an output's largest response.

    located: solved to the Newton tolerance between the branch points (False: the largest point,
    with ``reason``).  edge: the largest amplitude is at the end of the branch (no peak inside).
    """

    omega: float
    amplitude: float
    located: bool
    edge: bool = False
    solves: int = 0  # corrector solves spent
    residual: float = 0.0  # achieved max|R|/r_scale at the located point
    reason: str = ""

    def as_dict(self) -> dict:
        return asdict(self)


def output_amplitude(x: np.ndarray, dof, num_hc: int) -> float:
    """First-harmonic amplitude of an output (index or recovery row) of coefficients x."""
    X = x.reshape(num_hc, -1)
    c = X[1] @ dof if np.ndim(dof) else X[1, dof]
    s = X[2] @ dof if np.ndim(dof) else X[2, dof]
    return float(np.hypot(c, s))


def locate_peak(problem: Problem, x: np.ndarray, lam: np.ndarray, records: list[PointRecord], dof, *,
                scales: Scales, lam_scale: float, newton: NewtonOptions, grid: int = 6,
                omega_rtol: float = 1e-9) -> Peak:
    """The peak of the output ``dof`` on a branch of ``problem`` (points x (num_points, n) at lam)."""
    nh = problem.harmonics.num_hc
    amp = np.array([output_amplitude(xi, dof, nh) for xi in x])
    i = int(np.argmax(amp))
    if i == 0 or i == amp.size - 1:
        return Peak(float(lam[i]), float(amp[i]), located=False, edge=True,
                    reason="largest amplitude at the end of the range: an edge, not a peak")
    fun = newton_system(problem)
    adapt = problem.adaptation
    lo, hi = max(i - 2, 0), min(i + 2, amp.size - 1)
    if adapt is not None:
        adapt.restore(np.logical_or.reduce([r.active for r in records[lo:hi + 1]]))
    solves = 0
    best = (float(amp[i]), float(lam[i]), 0.0)  # amplitude, omega, residual

    def search(k: int) -> None:
        """Search the segment between points k and k+1."""
        nonlocal best, solves
        za, zb = np.append(x[k], lam[k]), np.append(x[k + 1], lam[k + 1])
        chord = zb - za
        cache: dict[float, tuple[float, float, float]] = {0.0: (float(amp[k]), float(lam[k]), 0.0),
                                                          1.0: (float(amp[k + 1]), float(lam[k + 1]), 0.0)}

        def f(t: float) -> float:
            nonlocal solves
            if t not in cache:
                zp = za + t * chord
                for _ in range(adapt.max_redo if adapt is not None else 1):
                    xs, ls, _, res = correct(fun, zp[:-1], float(zp[-1]), (chord[:-1], float(chord[-1])),
                                             x_scale=scales.x, lam_scale=lam_scale, r_scale=scales.r, options=newton)
                    solves += 1
                    if adapt is None or not adapt.after_converge(xs, ls):
                        break
                cache[t] = (output_amplitude(xs, dof, nh), float(ls), float(res))
            return -cache[t][0]

        ts = np.linspace(0.0, 1.0, grid + 1)
        A = -np.array([f(float(t)) for t in ts])
        for a, w, res in cache.values():
            if a > best[0]:
                best = (a, w, res)
        xatol = omega_rtol * abs(lam[k]) / max(abs(chord[-1]), 1e-300)
        for j in sorted(range(1, grid), key=lambda j: -A[j]):
            reach = A[j] + max(abs(A[j] - A[j - 1]), abs(A[j + 1] - A[j]))
            if A[j] >= A[j - 1] and A[j] >= A[j + 1] and reach > best[0]:  # a local maximum that may win
                r = minimize_scalar(f, bounds=(float(ts[j - 1]), float(ts[j + 1])), method="bounded",
                                    options={"xatol": min(xatol, 1e-3)})
                a, w, res = cache[float(r.x)] if float(r.x) in cache else (-r.fun, best[1], best[2])
                if a > best[0]:
                    best = (a, w, res)

    try:
        for k in range(lo, hi):
            search(k)
    except (ConvergenceError, ContinuationError, np.linalg.LinAlgError, RuntimeError) as exc:
        log.warning("peak not located between omega = %.9g and %.9g: %s", lam[lo], lam[hi], exc)
        return Peak(float(lam[i]), float(amp[i]), located=False, solves=solves, reason=str(exc))
    return Peak(best[1], best[0], located=True, solves=solves, residual=best[2])
