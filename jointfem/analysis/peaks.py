"""Peaks located to the solver's tolerance, not to the spacing of the points.

The first-harmonic amplitude A of an output is largest at some point i of a branch.  Each of the
two segments between points i-1, i and i+1 is parametrised by t in [0, 1]: the branch
point where it crosses the hyperplane through (1 - t) z_k + t z_k+1 normal to the chord
z_k+1 - z_k (in the continuation's scaled variables; continuation.correct).  Every evaluation is
a solved branch point, so the peak's amplitude and frequency are those of a solution, whether or
not the branch folds near it.

With a sampled friction law, A is not smooth near a peak: a time sample that changes state puts a
kink in it, and between kinks the curve sags (scallops, about 1e-4 of the amplitude at N = 128;
4e-6 on the BRB's quick penalty ROM at N = 256, one scallop per 0.077 rad/s, about a step of the
continuation), so its largest value sits on a kink, there are several local maxima close together,
and the top's kink may lie on either side of a branch point, between two samples neither of which
is a local maximum, or beyond the largest point's neighbours (a scallop can be deeper than the
curve falls over a step).  Where the branch points fall is a matter of round-off (K's entries
changed by 1e-15 of themselves change the steps), so the search must not depend on them.

The segments from point i-1 to i+1 are one curve in s = k + t, sampled at ``grid`` values of t per
segment (the branch points among the samples), and searched for its maximum by Piyavskii-Shubert
branch and bound: a cell between solved points a and b can reach (A_a + A_b + L (b - a)) / 2,
where L bounds |dA/ds| in it.  A cell whose two ends have the same contact states (every sample of
every pair) holds no kink once it is narrower than the first samples' spacing: A is smooth there,
and L is the steepest slope across it or its neighbours (where A is concave its slope lies between
theirs; where it is convex its largest value is at an end).  Any other cell may hold kinks, and L
is SAFETY times the steepest slope of the pieces near it: |dA/ds| at its ends and its neighbours'
far ends (each from the branch's tangent there: the slope of the smooth piece through that point,
which a chord across several scallops averages away), and across those cells.  A range that ends
at point a can reach A_a + SAFETY S / grid within a sample beyond it, S the steepest slope between
neighbouring points solved anywhere so far.  The cell that can reach highest
is halved (the range goes on by a segment when an end can), until nothing that could beat the best
point solved is wider than ``omega_rtol / 2`` of omega: the point kept is within that of the top's
omega, and two searches of the same branch, whatever its points, agree to ``omega_rtol`` (on a flat
top, as far as the amplitudes solved can tell: on lap2d's exact condensation they scatter by
2.4e-12 of themselves near the top, which with the curvature there blurs its omega by about 3.5e-8).

A largest amplitude at the first or last point is an *edge* of the range, not a peak, and is
reported as such.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np

from ..continuation.arclength import (ContinuationError, ConvergenceError, NewtonOptions, correct,
                                    hyperplane_derivative)
from ..harmonics import Harmonics
from ..hbm.problem import PointRecord, Problem, Scales, newton_system

log = logging.getLogger(__name__)

# Where a cell may hold a kink, A may rise in it twice as steeply as anywhere seen so far (with 1,
# the SDOF oscillator at N = 64, F = 0.2 kept a branch point 2.3e-5 below the top in amplitude: the
# fall past the top's kink, 8.4e-3 per unit of s, was steeper than any slope between the points
# solved, 7.4e-3)
SAFETY = 2.0

# The slope that bounds a cell that may hold kinks: "pieces", SAFETY times the steepest of the
# slopes of the smooth pieces through its ends and its neighbours' ends (dA/ds from the branch's
# tangent there) and of the chords across them; "steepest", SAFETY times the steepest chord slope
# anywhere.  Both locate the same peaks on the tests' branches; on a flat top covered with kinks
# (the 25-pair lap joint's exact condensation) "steepest" takes 375 solves where "pieces" takes 70,
# each a tangent dearer.  "steepest" is kept as the reference that tests/test_peaks.py compares with.
KINK_BOUND = "pieces"


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
    x: np.ndarray | None = field(default=None, repr=False, compare=False)  # the solution there (located)


def output_signal(x: np.ndarray, dof, harmonics: Harmonics) -> np.ndarray:
    """An output's harmonic coefficients (num_hc,) from coefficients x (index or recovery row)."""
    X = x.reshape(harmonics.num_hc, -1)
    return X @ dof if np.ndim(dof) else X[:, dof]


def output_amplitude(x: np.ndarray, dof, harmonics: Harmonics) -> float:
    """First-harmonic amplitude of an output (index or recovery row) of coefficients x."""
    return float(harmonics.amplitude(output_signal(x, dof, harmonics), 1))


def output_amplitude_derivative(x: np.ndarray, dx: np.ndarray, dof, harmonics: Harmonics) -> float:
    """d/de of output_amplitude(x + e dx) at e = 0 (the amplitude sqrt(c^2 + s^2) of the first
    harmonic's coefficients, linear in x)."""
    (c, s), (dc, ds) = ((float(np.squeeze(o[harmonics.block_cos(1)])), float(np.squeeze(o[harmonics.block_sin(1)])))
                        for o in (output_signal(x, dof, harmonics), output_signal(dx, dof, harmonics)))
    a = np.hypot(c, s)
    return float((c * dc + s * ds) / a) if a > 0 else float(np.hypot(dc, ds))


class _Segments:
    """Branch points between recorded points, solved once and shared by every output: the point
    where the branch crosses the hyperplane at t along the chord of segment k (k to k+1)."""

    def __init__(self, problem: Problem, x, lam, residual, *, scales: Scales, lam_scale: float,
                 newton: NewtonOptions):
        self.problem, self.x, self.lam, self.residual = problem, x, lam, residual
        self.fun = newton_system(problem)
        self.kw = dict(x_scale=scales.x, lam_scale=lam_scale, r_scale=scales.r, options=newton)
        self.cache: dict[tuple[int, float], tuple[np.ndarray, float, float]] = {}
        self.tangents: dict[tuple[int, float], np.ndarray] = {}
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

    def derivative(self, k: int, t: float) -> np.ndarray:
        """dx/dt at t in [0, 1) of segment k: the derivative of the smooth piece of the branch
        through that point (arclength.hyperplane_derivative along the chord of segment k)."""
        if (k, t) not in self.tangents:
            xs, ls, _ = self.point(k, t)
            chord = (self.x[k + 1] - self.x[k], float(self.lam[k + 1] - self.lam[k]))
            self.tangents[k, t] = hyperplane_derivative(self.fun, xs, ls, chord, x_scale=self.kw["x_scale"],
                                                        lam_scale=self.kw["lam_scale"],
                                                        select=self.problem.unknowns())[0]
        return self.tangents[k, t]


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
    adapt = problem.adaptation
    best = (float(amp[i]), float(lam[i]), float(segments.residual[i]), x[i])  # amplitude, omega, residual, x
    A: dict[float, float] = {}  # s -> amplitude of every point solved (s = k + t: t along segment k)
    D: dict[float, float] = {}  # s -> |dA/ds| there, of the smooth piece through the point
    states: dict[float, bytes] = {}  # s -> the contact states there, every sample of every group

    def value(s: float) -> None:
        """Solve the point at s; every point solved competes for the best."""
        nonlocal best
        k = min(int(np.floor(s)), amp.size - 2)
        xs, ls, res = segments.point(k, float(s - k))
        A[s] = a = output_amplitude(xs, dof, h)
        if KINK_BOUND == "pieces":
            try:
                D[s] = abs(output_amplitude_derivative(xs, segments.derivative(k, float(s - k)), dof, h))
            except (np.linalg.LinAlgError, RuntimeError):  # singular bordered system (a bifurcation)
                D[s] = np.nan  # bounded as steeply as anywhere (below)
        states[s] = b"".join(c.state_t.tobytes() for c in problem.evaluate(xs, ls, jacobian=False).contact)
        if a > best[0]:
            best = (a, ls, res, xs)

    def restore(lo: int, hi: int) -> None:
        if adapt is not None:
            adapt.restore(np.logical_or.reduce([r.active for r in records[lo:hi + 1]]))

    # the width in s below which a cell of segment k is not split: omega_rtol / 2 of omega, so that
    # the point kept lies within that of the top, and two searches of the branch agree to omega_rtol
    width = [min(0.5 * omega_rtol * abs(lam[i]) / max(abs(lam[k + 1] - lam[k]), 1e-300), 1e-3)
             for k in range(amp.size - 1)]
    lo, hi = i - 1, i + 1  # the segments searched: from point lo to point hi
    try:
        restore(lo, hi)
        for k in range(lo, hi):
            for j in range(grid + (k == hi - 1)):
                value(k + j / grid)
        slope = 0.0  # the steepest |dA/ds| between neighbouring points solved so far
        while True:
            at = np.array(sorted(A))
            a, ds = np.array([A[v] for v in at]), np.diff(at)
            cell = np.abs(np.diff(a)) / ds  # |dA/ds| across each cell
            slope = max(slope, float(cell.max()))
            # A cell narrower than the first samples' spacing whose ends have the same contact
            # states holds no kink: A is smooth there, and rises at most as steeply as across its
            # neighbours (concave: its slope lies between theirs; convex: its largest value is at
            # an end).  Any other cell may hold a kink, up to which A may rise as steeply as it
            # does anywhere.
            near = _with_neighbours(cell)
            smooth = np.array([states[u] == states[v] for u, v in zip(at[:-1], at[1:])]) & (ds * grid < 0.75)
            # A cell that may hold kinks: A rises in it at most SAFETY times as steeply as the
            # pieces through its ends and its neighbours' far ends do, or as across them
            if KINK_BOUND == "pieces":
                d = np.array([D[v] for v in at])
                d[np.isnan(d)] = slope
                kink = SAFETY * np.maximum(near, _with_neighbours(np.maximum(d[:-1], d[1:])))
            else:  # "steepest": as steeply as anywhere
                kink = SAFETY * slope
            bound = np.where(smooth, near, kink)
            # the most A can reach in a cell (Piyavskii-Shubert; not a cell narrow enough already),
            # and within a sample beyond either end of the range
            reach = (a[:-1] + a[1:] + bound * ds) / 2
            reach[ds <= np.array([width[int(v)] for v in at[:-1]])] = -np.inf
            below = a[0] + SAFETY * slope / grid if lo > 0 else -np.inf
            above = a[-1] + SAFETY * slope / grid if hi < amp.size - 1 else -np.inf
            c = int(np.argmax(reach))
            if max(reach[c], below, above) <= best[0]:
                break
            if below >= max(reach[c], above):  # the range goes on by a segment below
                lo -= 1
                restore(lo, hi)
                for j in range(grid):
                    value(lo + j / grid)
            elif above >= reach[c]:  # or above
                hi += 1
                restore(lo, hi)
                for j in range(1, grid + 1):
                    value(hi - 1 + j / grid)
            else:  # the cell that can reach highest is halved
                value(float((at[c] + at[c + 1]) / 2))
    except (ConvergenceError, ContinuationError, np.linalg.LinAlgError, RuntimeError) as exc:
        log.warning("peak not located between omega = %.9g and %.9g: %s", lam[lo], lam[hi], exc)
        return Peak(float(lam[i]), float(amp[i]), located=False, reason=str(exc))
    return Peak(best[1], best[0], located=True, residual=best[2], x=np.array(best[3]))


def _with_neighbours(v: np.ndarray) -> np.ndarray:
    """Per cell, the largest of v over it and its two neighbouring cells."""
    return np.maximum(v, np.maximum(np.append(v[1:], 0.0), np.append(0.0, v[:-1])))
