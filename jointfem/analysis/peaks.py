"""Peaks located to the solver's tolerance, not to the spacing of the points.

The first-harmonic amplitude A of an output is largest at some point i of a branch.  Each of the
two segments between points i-1, i and i+1 is parametrised by t in [0, 1]: the branch
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
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import minimize_scalar

from ..continuation.arclength import ContinuationError, ConvergenceError, NewtonOptions, correct
from ..harmonics import Harmonics
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


def output_amplitude(x: np.ndarray, dof, harmonics: Harmonics) -> float:
    """First-harmonic amplitude of an output (index or recovery row) of coefficients x."""
    X = x.reshape(harmonics.num_hc, -1)
    out = X @ dof if np.ndim(dof) else X[:, dof]
    return float(harmonics.amplitude(out, 1))


class _Segments:
    """Branch points between recorded points, solved once and shared by every output: the point
    where the branch crosses the hyperplane at t along the chord of segment k (k to k+1)."""

    def __init__(self, problem: Problem, x, lam, residual, *, scales: Scales, lam_scale: float,
                 newton: NewtonOptions):
        self.problem, self.x, self.lam, self.residual = problem, x, lam, residual
        self.fun = newton_system(problem)
        self.kw = dict(x_scale=scales.x, lam_scale=lam_scale, r_scale=scales.r, options=newton)
        self.cache: dict[tuple[int, float], tuple[np.ndarray, float, float]] = {}
        self.solves = 0

    def point(self, k: int, t: float) -> tuple[np.ndarray, float, float]:
        """(x, omega, achieved residual) at t in [0, 1] of segment k."""
        if t == 0.0:
            return self.x[k], float(self.lam[k]), float(self.residual[k])
        if t == 1.0:
            return self.x[k + 1], float(self.lam[k + 1]), float(self.residual[k + 1])
        if (k, t) not in self.cache:
            za, zb = np.append(self.x[k], self.lam[k]), np.append(self.x[k + 1], self.lam[k + 1])
            chord = zb - za
            zp = za + t * chord
            adapt = self.problem.adaptation
            for _ in range(adapt.max_redo if adapt is not None else 1):
                xs, ls, _, res = correct(self.fun, zp[:-1], float(zp[-1]), (chord[:-1], float(chord[-1])), **self.kw,
                                         select=self.problem.unknowns())
                self.solves += 1
                if adapt is None or not adapt.after_converge(xs, ls):
                    break
            self.cache[k, t] = (xs, float(ls), float(res))
        return self.cache[k, t]


def locate_peaks(problem: Problem, x: np.ndarray, lam: np.ndarray, residual: np.ndarray, records: list[PointRecord],
                 outputs: dict, *, scales: Scales, lam_scale: float, newton: NewtonOptions, grid: int = 4,
                 omega_rtol: float = 1e-8) -> dict[str, Peak]:
    """The peak of every output (name -> index or recovery row) on a branch of ``problem`` (points
    x (num_points, n) at lam, with their achieved residuals); the branch points solved between the
    recorded ones are shared by the outputs."""
    segments = _Segments(problem, x, lam, residual, scales=scales, lam_scale=lam_scale, newton=newton)
    peaks = {}
    for name, dof in outputs.items():
        before = segments.solves
        peaks[name] = _locate(segments, records, dof, grid=grid, omega_rtol=omega_rtol)
        peaks[name] = replace(peaks[name], solves=segments.solves - before)
    return peaks


def _locate(segments: _Segments, records, dof, *, grid: int, omega_rtol: float) -> Peak:
    problem, x, lam = segments.problem, segments.x, segments.lam
    h = problem.harmonics
    amp = np.array([output_amplitude(xi, dof, h) for xi in x])
    i = int(np.argmax(amp))
    if i == 0 or i == amp.size - 1:
        return Peak(float(lam[i]), float(amp[i]), located=False, edge=True,
                    reason="largest amplitude at the end of the range: an edge, not a peak")
    lo, hi = i - 1, i + 1  # the two segments around the largest point
    if problem.adaptation is not None:
        problem.adaptation.restore(np.logical_or.reduce([r.active for r in records[lo:hi + 1]]))
    best = (float(amp[i]), float(lam[i]), float(segments.residual[i]))  # amplitude, omega, residual

    def search(k: int) -> None:
        """Search the segment between points k and k+1."""
        nonlocal best

        def f(t: float) -> float:
            xs, ls, res = segments.point(k, float(t))
            return -output_amplitude(xs, dof, h)

        def take(t: float) -> None:
            nonlocal best
            xs, ls, res = segments.point(k, t)
            a = output_amplitude(xs, dof, h)
            if a > best[0]:
                best = (a, ls, res)

        ts = np.linspace(0.0, 1.0, grid + 1)
        A = -np.array([f(t) for t in ts])
        for t in ts:
            take(float(t))
        xatol = omega_rtol * abs(lam[k]) / max(abs(lam[k + 1] - lam[k]), 1e-300)
        for j in sorted(range(1, grid), key=lambda j: -A[j]):
            reach = A[j] + max(abs(A[j] - A[j - 1]), abs(A[j + 1] - A[j]))
            if A[j] >= A[j - 1] and A[j] >= A[j + 1] and (reach > best[0] or A[j] == best[0]):  # may win
                r = minimize_scalar(f, bounds=(float(ts[j - 1]), float(ts[j + 1])), method="bounded",
                                    options={"xatol": min(xatol, 1e-3)})
                take(float(r.x))

    try:
        for k in range(lo, hi):
            search(k)
    except (ConvergenceError, ContinuationError, np.linalg.LinAlgError, RuntimeError) as exc:
        log.warning("peak not located between omega = %.9g and %.9g: %s", lam[lo], lam[hi], exc)
        return Peak(float(lam[i]), float(amp[i]), located=False, reason=str(exc))
    return Peak(best[1], best[0], located=True, residual=best[2])
