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

A peak is searched to its error bar, not beyond it (analysis.frf.peak_tolerance: a tenth of the
truncation error estimated at the largest point, in amplitude): the search stops once nothing can
beat the best point solved by more than that.  First by the cubics through the three points around
the largest (Hermite's, with the slopes of the smooth pieces; the tangents' meeting point where a
kink tops a cell), each solve placed where they top out, for MODEL_STEPS solves: where A is smooth
to the tolerance (the 25-pair lap joint's many shallow kinks at N = 256) that is a few solves
(6 against 22 by the branch and bound alone, and 126 to omega_rtol).  The kinks the points show
(a chord steeper or shallower than the slopes at its ends, a slope that rises towards the top) lift
every cell's bound; where they are deeper than the tolerance (the SDOF oscillator at N = 128, whose
top hides between two points whose slopes both fall) the cubics do not settle and the branch and
bound goes on from the points solved.

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

# points solved where the cubics through the points solved top out, before the branch and bound
# takes over (a peak searched to a tolerance; analysis.frf.peak_tolerance)
MODEL_STEPS = 10


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
    # located: the top exceeds this amplitude by at most this share of it (0: searched to omega_rtol)
    tolerance: float = 0.0
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
        self.tangents: dict[tuple[int, float], tuple[np.ndarray, float]] = {}
        self.solves = 0
        self.iterations = 0  # Newton's, over the solves

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
            start = self._predict(k, t)
            for _ in range(adapt.max_redo if adapt is not None else 1):
                try:
                    xs, ls, it, res = correct(self.fun, zp[:-1], float(zp[-1]), (chord[:-1], float(chord[-1])),
                                              **self.kw, select=self.problem.unknowns(), start=start)
                except ConvergenceError:
                    if start is None:
                        raise
                    start = None  # from the chord, as the sweep's corrector starts
                    xs, ls, it, res = correct(self.fun, zp[:-1], float(zp[-1]), (chord[:-1], float(chord[-1])),
                                              **self.kw, select=self.problem.unknowns())
                self.solves += 1
                self.iterations += it
                if adapt is None or not adapt.after_converge(xs, ls):
                    break
            self.cache[k, t] = (xs, float(ls), float(res))
        return self.cache[k, t]

    def _predict(self, k: int, t: float) -> tuple[np.ndarray, float] | None:
        """Newton's first iterate at t of segment k: the cubic through the nearest points solved on
        either side, with the branch's derivative at those that have it (Hermite; a quadratic with
        one, None with neither: the chord).  z(t) . chord is linear in t on the branch and in every
        such interpolant, so the iterate lies on the corrector's hyperplane.  Near the peak the
        interpolant's error is the branch's third derivative times the cell's width cubed: the
        corrector there takes 1-2 Newton iterations where it takes 3-4 from the chord."""
        known = [u for (kk, u) in self.cache if kk == k] + [0.0, 1.0]
        a, b = max(u for u in known if u < t), min(u for u in known if u > t)
        da, db = self.tangents.get((k, a)), self.tangents.get((k, b))
        if da is None and db is None:
            return None
        (xa, la, _), (xb, lb, _) = self.point(k, a), self.point(k, b)
        h, u = b - a, (t - a) / (b - a)
        za, zb = np.append(xa, la), np.append(xb, lb)
        if da is not None and db is not None:  # Hermite's cubic
            ma, mb = h * np.append(*da), h * np.append(*db)
            z = _hermite(u, za, ma, zb, mb)
        elif da is not None:  # the quadratic with z(a), z'(a) and z(b)
            ma = h * np.append(*da)
            z = za + u * ma + u ** 2 * (zb - za - ma)
        else:  # with z(a), z(b) and z'(b)
            mb = h * np.append(*db)
            z = za + u * (2 * (zb - za) - mb) + u ** 2 * (mb - (zb - za))
        return z[:-1], float(z[-1])

    def derivative(self, k: int, t: float) -> np.ndarray:
        """dx/dt at t in [0, 1] of segment k: the derivative of the smooth piece of the branch
        through that point (arclength.hyperplane_derivative along the chord of segment k)."""
        if (k, t) not in self.tangents:
            xs, ls, _ = self.point(k, t)
            chord = (self.x[k + 1] - self.x[k], float(self.lam[k + 1] - self.lam[k]))
            self.tangents[k, t] = hyperplane_derivative(self.fun, xs, ls, chord, x_scale=self.kw["x_scale"],
                                                        lam_scale=self.kw["lam_scale"],
                                                        select=self.problem.unknowns())
        return self.tangents[k, t][0]


def locate_peaks(problem: Problem, x: np.ndarray, lam: np.ndarray, residual: np.ndarray, records: list[PointRecord],
                 outputs: dict, *, scales: Scales, lam_scale: float, newton: NewtonOptions, grid: int = 4,
                 omega_rtol: float = 1e-8, amplitude_rtol: np.ndarray | None = None) -> dict[str, Peak]:
    """The peak of every output (name -> index or recovery row) on a branch of ``problem`` (points
    x (num_points, n) at lam, with their achieved residuals); the branch points solved between the
    recorded ones are shared by the outputs.

    ``amplitude_rtol`` (num_points, num_outputs): the search of an output whose largest point is i
    stops once nothing can beat the best point solved by more than amplitude_rtol[i, output] of its
    amplitude (None: by anything; the point kept is then within omega_rtol / 2 of the top)."""
    segments = _Segments(problem, x, lam, residual, scales=scales, lam_scale=lam_scale, newton=newton)
    peaks = {}
    for j, (name, dof) in enumerate(outputs.items()):
        before = segments.solves
        rtol = np.zeros(len(x)) if amplitude_rtol is None else np.asarray(amplitude_rtol)[:, j]
        peaks[name] = _locate(segments, records, dof, grid=grid, omega_rtol=omega_rtol, amplitude_rtol=rtol)
        peaks[name] = replace(peaks[name], solves=segments.solves - before)
    # one warning per failure: outputs that move together (the two beams' middles) share their top
    failed: dict[str, list[str]] = {}
    for name, p in peaks.items():
        if not p.located and not p.edge:
            failed.setdefault(p.reason, []).append(name)
    for reason, names in failed.items():
        log.warning("peak of %s not located %s", ", ".join(names), reason)
    log.debug("peaks: %d solves, %d Newton iterations", segments.solves, segments.iterations)
    return peaks


def _locate(segments: _Segments, records, dof, *, grid: int, omega_rtol: float, amplitude_rtol: np.ndarray) -> Peak:
    problem, x, lam = segments.problem, segments.x, segments.lam
    h = problem.harmonics
    amp = np.array([output_amplitude(xi, dof, h) for xi in x])
    i = int(np.argmax(amp))
    if i == 0 or i == amp.size - 1:
        return Peak(float(lam[i]), float(amp[i]), located=False, edge=True,
                    reason="largest amplitude at the end of the range: an edge, not a peak")
    adapt = problem.adaptation
    gain = 1.0 + float(amplitude_rtol[i])  # what the top may exceed the best point by, at most
    best = (float(amp[i]), float(lam[i]), float(segments.residual[i]), x[i])  # amplitude, omega, residual, x
    A: dict[float, float] = {}  # s -> amplitude of every point solved (s = k + t: t along segment k)
    D: dict[float, float] = {}  # s -> |dA/ds| there, of the smooth piece through the point
    states: dict[float, bytes] = {}  # s -> the contact states there, every sample of every group

    A_x: dict[float, np.ndarray] = {}  # s -> the solution there
    omega_at: dict[float, float] = {}

    def state(s: float) -> bytes:
        """The contact states at s (solved), every sample of every group: only the branch and bound
        asks (an evaluation of the point's contact forces)."""
        if s not in states:
            states[s] = b"".join(c.state_t.tobytes()
                                 for c in problem.evaluate(A_x[s], omega_at[s], jacobian=False).contact)
        return states[s]

    def value(s: float) -> None:
        """Solve the point at s; every point solved competes for the best."""
        nonlocal best
        k = min(int(np.floor(s)), amp.size - 2)
        xs, ls, res = segments.point(k, float(s - k))
        A_x[s], omega_at[s] = xs, ls
        A[s] = a = output_amplitude(xs, dof, h)
        if KINK_BOUND == "pieces":
            try:
                D[s] = abs(rise(s, k))
            except (np.linalg.LinAlgError, RuntimeError):  # singular bordered system (a bifurcation)
                D[s] = np.nan  # bounded as steeply as anywhere (below)
        if a > best[0]:
            best = (a, ls, res, xs)

    def restore(lo: int, hi: int) -> None:
        if adapt is not None:
            adapt.restore(np.logical_or.reduce([r.active for r in records[lo:hi + 1]]))

    def rise(s: float, k: int) -> float:
        """dA/dt at s (solved) in the parameter t of segment k: at a branch point between two
        segments the slope differs by the ratio of their chords."""
        return output_amplitude_derivative(A_x[s], segments.derivative(k, float(s - k)), dof, h)

    def model_top() -> tuple[float, float]:
        """(reach, s): the most A can reach over [i - 1, i + 1] by the points solved there, and where
        to solve next.  In each cell, from the amplitudes and slopes (of the smooth pieces) at its
        ends: the larger of Hermite's cubic, raised by its departure from the parabola through its
        ends and its left slope ((4 / 27) |m0 + m1 - 2 (a1 - a0)|: the cubic's own error is of higher
        order wherever A is near a parabola on the cell, as at a smooth top), and the meeting point
        of the two tangents where they rise into the cell (a kink at the top: exact for two straight
        pieces).  Raised further by SAFETY times the kinks seen: a cell whose chord's slope lies
        outside its ends' slopes holds a kink (A' is monotone on a smooth top), whose jump is at least
        that distance; a kink of jump J in a cell of width w lifts A above the pieces by at most
        J w / 4.  Where to solve next: at that top in the cell that reaches highest, or its middle
        where the top is at an end."""
        at = sorted(u for u in A if i - 1 <= u <= i + 1)
        cells = []
        jump = 0.0  # the largest kink seen, in dA/ds
        for u, v in zip(at[:-1], at[1:]):
            k = int(np.floor(u))
            w = v - u
            d0, d1, chord = rise(u, k), rise(v, k), (A[v] - A[u]) / w
            jump = max(jump, d1 - d0, min(d0, d1) - chord, chord - max(d0, d1))
            cells.append((u, w, A[u], A[v], w * d0, w * d1))
        top = (-np.inf, float(i))
        for u, w, a0, a1, m0, m1 in cells:
            # p(tau) on [0, 1] and the roots of p'(tau) = qa tau^2 + qb tau + qc inside it
            qa, qb, qc = 6 * a0 + 3 * m0 - 6 * a1 + 3 * m1, -6 * a0 - 4 * m0 + 6 * a1 - 2 * m1, m0
            taus = [0.0, 1.0] + [float(r.real) for r in np.roots([qa, qb, qc])
                                 if abs(r.imag) < 1e-12 and 0.0 < r.real < 1.0]
            p = [_hermite(t, a0, m0, a1, m1) for t in taus]
            j = int(np.argmax(p))
            reach, tau = p[j] + 4 / 27 * abs(m0 + m1 - 2 * (a1 - a0)), (taus[j] if 0.0 < taus[j] < 1.0 else 0.5)
            if m0 > 0.0 > m1:
                tent = (a1 - a0 - m1) / (m0 - m1)
                if 0.0 < tent < 1.0 and a0 + m0 * tent > reach:
                    reach, tau = a0 + m0 * tent, tent
            reach += SAFETY * jump * w / 4
            if reach > top[0]:
                top = (reach, u + tau * w)
        return top

    def by_model() -> bool:
        """The top located by the cubics alone (True) once nothing they can reach beats the best
        point solved by more than the tolerance: A is then smooth to the tolerance near the top (a
        sampled law's scallops shallower than it).  Else (scallops deeper than the tolerance, kinks,
        a top beyond the neighbours) the branch and bound goes on from the points solved, after
        MODEL_STEPS.  Only where A rises into the range at both ends: else its top may lie beyond."""
        try:
            if rise(float(i - 1), i - 1) <= 0.0 or rise(float(i + 1), i) >= 0.0:
                return False
            for _ in range(MODEL_STEPS):
                reach, s = model_top()
                if reach <= best[0] * gain:
                    return True
                if s in A:
                    return False
                value(s)
        except (np.linalg.LinAlgError, RuntimeError):  # a tangent refused (a bifurcation): no slopes
            pass
        return False

    # the width in s below which a cell of segment k is not split: omega_rtol / 2 of omega, so that
    # the point kept lies within that of the top, and two searches of the branch agree to omega_rtol
    width = [min(0.5 * omega_rtol * abs(lam[i]) / max(abs(lam[k + 1] - lam[k]), 1e-300), 1e-3)
             for k in range(amp.size - 1)]
    lo, hi = i - 1, i + 1  # the segments searched: from point lo to point hi
    try:
        restore(lo, hi)
        for k in (i - 1, i, i + 1):
            value(float(k))
        if gain > 1.0 and by_model():
            return Peak(best[1], best[0], located=True, residual=best[2], x=np.array(best[3]), tolerance=gain - 1.0)
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
            smooth = np.array([state(u) == state(v) for u, v in zip(at[:-1], at[1:])]) & (ds * grid < 0.75)
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
            if max(reach[c], below, above) <= best[0] * gain:
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
        return Peak(float(lam[i]), float(amp[i]), located=False,
                    reason=f"between omega = {lam[lo]:.9g} and {lam[hi]:.9g}: {exc}")
    return Peak(best[1], best[0], located=True, residual=best[2], x=np.array(best[3]), tolerance=gain - 1.0)


def _hermite(u: float, a0, m0, a1, m1):
    """Hermite's cubic at u in [0, 1] with values a0, a1 and derivatives m0, m1 (in u) at its ends."""
    return ((2 * u ** 3 - 3 * u ** 2 + 1) * a0 + (u ** 3 - 2 * u ** 2 + u) * m0
            + (-2 * u ** 3 + 3 * u ** 2) * a1 + (u ** 3 - u ** 2) * m1)


def _with_neighbours(v: np.ndarray) -> np.ndarray:
    """Per cell, the largest of v over it and its two neighbouring cells."""
    return np.maximum(v, np.maximum(np.append(v[1:], 0.0), np.append(0.0, v[:-1])))
