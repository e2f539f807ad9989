"""How far a point is from harmonic convergence: two estimates of the truncation error.

``top_harmonic_share``, a share of the contact force (below), is cheap and recorded per point; it
says where more harmonics are needed but not how wrong the response is (docs/theory.md).
``TruncationEstimator`` (the last section) estimates the error of the response itself.

The contact forces are the only source of higher harmonics.  Their content in the two highest
retained harmonics, relative to all their dynamic (k >= 1) content,

    e = sqrt(sum_{k = H-1, H} |F_k|^2) / sqrt(sum_{k = 1..H} |F_k|^2)   (every pair and component),

is what a truncation at H throws away the next part of: where it is small, the harmonics beyond H
carry less still (they decay at least as fast for the laws here: a kink in the force's slope
gives 1/k^2, a jump 1/k).  A linear (stuck) contact has e = 0.  Two top harmonics, because a
symmetric law (the Jenkins pair without a normal axis) has no even ones: one of the two is odd.
For H <= 2 the top would include the fundamental, and e = 1: not known to be converged (at H = 2
the second harmonic alone reads 6e-19 on the slipping SDOF oscillator, whose third is 0.14).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from ..contact.law import ContactResult
from ..continuation.arclength import (ContinuationError, ContinuationOptions, ContinuationPoint, ConvergenceError,
                                      NewtonOptions, continue_branch, solve_adaptive)
from ..harmonics import Harmonics
from ..hbm.problem import Problem, newton_system
from .peaks import Peak, locate_peaks, output_signal


def top_harmonic_share(contact: list[ContactResult], harmonics: Harmonics, *, top: int = 2) -> float:
    """e of the module docstring for the contact results of one point (0 without contact)."""
    if not contact or harmonics.H < 1:
        return 0.0
    F = np.concatenate([c.F.reshape(harmonics.num_hc, -1) for c in contact], axis=1)  # (num_hc, all comps)
    orders = harmonics.orders
    dyn = float(np.sum(F[orders >= 1] ** 2))
    if dyn <= 0.0:
        return 0.0
    if harmonics.H <= top:
        return 1.0  # the top harmonics would include the fundamental: not known to be converged
    hi = float(np.sum(F[orders > harmonics.H - top] ** 2))
    return float(np.sqrt(hi / dyn))


# ---- the truncation error of the response --------------------------------------------------------
#
# The converged point x at (H, N), padded with zeros for the harmonics H+1..H2, is a point of the
# same problem at (H2, N2) with a residual R2(x0): the contact forces' harmonics above H (which no
# retained equation balances) and, in the retained ones, the change of the AFT from N to N2 samples.
# The Newton homotopy R2(y) - (1 - theta) R2(x0) = 0, followed by arclength continuation from
# (x0, theta = 0) to theta = 1, ends on the solution at (H2, N2) that the point becomes when the
# missing harmonics are let in; what that changes in an output is the estimate of the error of (H, N).
# Where the point is near that solution the path is one Newton step long (its first step is the
# linearised correction).  Where the point is an artefact of the truncation (a loop that more
# harmonics remove), no solution at (H2, N2) continues it: the path turns back in theta, and the
# point is reported as not connected (its error is not known, and larger than the estimate could
# tell).  A superharmonic resonance shows: the harmonic k of the forces drives the dynamic
# stiffness of harmonic k near its zero, and the path's end is far.
#
# A peak's error is not the change at its frequency where the top is a fold (the beam's top at 3 N
# holds three solutions within 0.07 rad/s): ``TruncationEstimator.peak`` follows the (H2, N2)
# branch from the homotopy's end across a span of omega each side and locates its peak there
# (analysis.peaks).
#
# Measured (docs/benchmarks_truncation.md): within 0.65-1.14 of the true error of the located peaks
# of the SDOF Jenkins oscillator and of two masses at a 3:1 superharmonic resonance, H = 1 to 9
# (amplitude, and RMS at the peak's frequency), and 1.02 on the beam at 3 N at H = 21.  Below that
# the beam's impacts converge erratically in H (its peak moves by -5 %, -7 %, -4.5 %, ... from
# H = 5 to 15): its peaks at H = 5, 9 and 13 lie on loops that more harmonics remove, and the
# homotopy from each turns back (not connected).

def amplitude_and_rms(coeffs: np.ndarray, harmonics: Harmonics) -> tuple[float, float]:
    """(first-harmonic amplitude, RMS over a period) of one signal's coefficients (num_hc,)."""
    a1 = float(np.hypot(coeffs[harmonics.block_cos(1)], coeffs[harmonics.block_sin(1)]))
    rms = float(np.sqrt(coeffs[0] ** 2 + 0.5 * np.sum(coeffs[1:] ** 2)))
    return a1, rms


@dataclass(frozen=True)
class TruncationError:
    """The estimated error of one point at fixed omega, per output (in the order of ``outputs``):
    ``amplitude`` and ``rms``, the change of the first-harmonic amplitude and of the RMS over a
    period from the point to the (H2, N2) solution it continues to, m (signed: the better answer
    minus the point's; zero where not ``connected``).  ``connected``: the homotopy reached theta = 1;
    ``theta``: how far it got; ``folds``: how often it turned back in theta on the way (0 on every
    connected point of docs/benchmarks_truncation.md; 2 on the beam's H = 21 peak towards 2H = 42); ``x_to``: the (H2, N2) solution."""

    amplitude: np.ndarray
    rms: np.ndarray
    connected: bool
    theta: float
    folds: int
    harmonics_to: Harmonics
    x_to: np.ndarray | None = None


@dataclass(frozen=True)
class PeakError:
    """A located peak at H against the same peak at (H2, N2): ``peak``, the (H2, N2) branch's
    located peak within ``span`` of the H peak's omega (None where the homotopy did not connect or
    no peak lies in the span); ``at_omega``, the estimate at the H peak's frequency."""

    peak: Peak | None
    at_omega: TruncationError
    reason: str = ""


# the span of omega (a share of it) each side of a peak at H in which its peak at (3H, 2N) is sought:
# the beam's peak at H = 21 lies 0.066 rad/s (3.9e-5) from H = 41's; the SDOF oscillator's at H = 1
# 3e-4 rad/s (2.3e-4) from its reference (docs/benchmarks_truncation.md)
PEAK_SPAN = 2e-3


class _TurnedBack(Exception):
    pass


def estimate_harmonics(harmonics: Harmonics, *, factor: int = 3) -> Harmonics:
    """(H2, N2) of the estimate: H2 = factor H (a friction or impact force's harmonics up to 3H
    drive the response's; measured, the peak at 3H gives the peak's error within 0.65-1.14 on the
    SDOF Jenkins oscillator from H = 1 to 9) and N2 = 2N (the sampling error of the AFT: halving
    the spacing of the samples), at least 4 H2 + 4."""
    H2 = max(factor * harmonics.H, harmonics.H + 2)
    return Harmonics(H2, max(2 * harmonics.N, 4 * H2 + 4))


class TruncationEstimator:
    """The estimate of this section for the points of one problem solved at ``harmonics``:
    ``problem_at(h)`` builds the same problem at other harmonics (analysis.frf.create_problem of
    its model); ``window``: the sweep's (omega_start, omega_end) in rad/s (the (H2, N2) problem's
    scales); ``outputs``: name -> index or recovery row of the coordinates.
    ``max_folds``: the homotopy gives up (not connected) once it has turned back this often;
    ``max_points``: its budget of points."""

    def __init__(self, problem_at: Callable[[Harmonics], Problem], harmonics: Harmonics, outputs: dict, *,
                 window: tuple[float, float], factor: int = 3, max_folds: int = 4, max_points: int = 400,
                 newton: NewtonOptions = NewtonOptions()):
        self.h = harmonics
        self.h2 = estimate_harmonics(harmonics, factor=factor)
        self.problem: Problem = problem_at(self.h2)
        self.outputs = dict(outputs)
        self.scales = self.problem.scales(*window)
        self.lam_scale = abs(window[1] - window[0])
        self.q = self.problem.num_coefficients // self.h2.num_hc
        self.max_folds, self.max_points = max_folds, max_points
        self.newton = replace(newton, tol=max(newton.tol, self.problem.tol_floor))

    def pad(self, x: np.ndarray) -> np.ndarray:
        """x at H as coefficients at H2 (the harmonics above H zero)."""
        x2 = np.zeros(self.q * self.h2.num_hc)
        x2[: x.size] = x
        return x2

    def _changes(self, x0: np.ndarray, x1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        amp, rms = [], []
        for dof in self.outputs.values():
            a0, r0 = amplitude_and_rms(output_signal(x0, dof, self.h2), self.h2)
            a1, r1 = amplitude_and_rms(output_signal(x1, dof, self.h2), self.h2)
            amp.append(a1 - a0)
            rms.append(r1 - r0)
        return np.array(amp), np.array(rms)

    def __call__(self, x: np.ndarray, lam: float) -> TruncationError:
        """The estimate at the converged point (x, lam) of the model at H (see the section's comment)."""
        pb = self.problem
        adapt = pb.adaptation
        x0 = self.pad(x)
        if adapt is not None:
            adapt.restore(adapt.state_of(x0))
        start: dict[bytes, np.ndarray] = {}  # R2(x0) in the rows of each set of unknowns met

        def fun(y, theta):
            sel = pb.unknowns()
            key = b"" if sel is None else np.asarray(sel).tobytes()
            if key not in start:
                start[key] = pb.evaluate(x0, lam, jacobian=False).R
            ev = pb.evaluate(y, lam, jacobian=True)
            return ev.R - (1.0 - theta) * start[key], ev.J, start[key]

        thetas = [0.0]
        folds = [0]

        def watch(point: ContinuationPoint):
            if len(thetas) >= 2 and (point.lam - thetas[-1]) * (thetas[-1] - thetas[-2]) < 0:
                folds[0] += 1
                if folds[0] > self.max_folds:
                    raise _TurnedBack
            thetas.append(point.lam)

        sc = self.scales
        opts = ContinuationOptions(lam_bounds=(-0.5, 1.5), max_points=self.max_points, newton=self.newton,
                                   max_leaps=0)
        zero = np.zeros(len(self.outputs))
        try:
            points = continue_branch(fun, x0, 0.0, 1.0, x_scale=sc.x, lam_scale=1.0, r_scale=sc.r, options=opts,
                                     callback=watch, adapt=adapt)
        except (ContinuationError, ConvergenceError, _TurnedBack, np.linalg.LinAlgError):
            return TruncationError(zero, zero, False, float(max(thetas)), folds[0], self.h2)
        try:  # the last point has passed theta = 1: Newton there from it
            x1, _ = solve_adaptive(fun, points[-1].x, 1.0, adapt=adapt, x_scale=sc.x, r_scale=sc.r,
                                   options=self.newton)
        except ConvergenceError:
            return TruncationError(zero, zero, False, float(max(thetas)), folds[0], self.h2)
        amp, rms = self._changes(x0, x1)
        return TruncationError(amp, rms, True, 1.0, folds[0], self.h2, x1)

    def peak(self, x: np.ndarray, lam: float, name: str, *, span: float) -> PeakError:
        """The located peak of output ``name`` at (H2, N2) near the located peak (x, lam) at H: the
        homotopy at lam, then the (H2, N2) branch followed from its end to lam - span and to
        lam + span (rad/s), and its peak located there (analysis.peaks)."""
        at = self(x, lam)
        if not at.connected:
            return PeakError(None, at, f"the homotopy to H = {self.h2.H} reached theta = {at.theta:.3g} at most, turning "
                                       f"back {at.folds} times: the point at H = {self.h.H} continues to no solution there")
        pb = self.problem
        adapt = pb.adaptation
        sc = self.scales

        def record(y, w):
            return pb.record(y, w, pb.evaluate(y, w, jacobian=False))

        # (steps measured in the span, not the sweep's window: a few tens of points each side)
        opts = ContinuationOptions(lam_bounds=(lam - 3 * span, lam + 3 * span), max_rel_change=1.0, newton=self.newton,
                                   max_points=self.max_points)
        halves = []
        for end in (lam - span, lam + span):
            if adapt is not None:
                adapt.restore(adapt.state_of(at.x_to))
            try:
                halves.append(continue_branch(newton_system(pb), at.x_to, lam, end, x_scale=sc.x, lam_scale=span,
                                              r_scale=sc.r, options=opts, extra=record, adapt=adapt))
            except ContinuationError as exc:
                halves.append(exc.points)
        points = halves[0][::-1] + halves[1][1:]
        if len(points) < 3:
            return PeakError(None, at, f"the branch at H = {self.h2.H} could not be followed from the homotopy's end")
        X = np.array([p.x for p in points])
        omega = np.array([p.lam for p in points])
        found = locate_peaks(pb, X, omega, np.array([p.residual for p in points]), [p.extra for p in points],
                             {name: self.outputs[name]}, scales=sc, lam_scale=span, newton=self.newton)[name]
        if not found.located:
            return PeakError(None, at, f"no peak within {span:g} rad/s at H = {self.h2.H}: {found.reason}")
        return PeakError(found, at)
