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

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

import numpy as np
import scipy.sparse as sp

from ..contact.law import ContactResult
from ..continuation.arclength import bordered, linear_solve
from ..harmonics import Harmonics

if TYPE_CHECKING:
    from ..hbm.problem import Problem


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
# same problem at (H2, N2) with a residual: the contact forces' harmonics above H (which no retained
# equation balances) and, in the retained ones, the change of the AFT from N to N2 samples.  One
# Newton step of the (H2, N2) problem from there, x2 = x + dx, is the linearised answer of the
# larger truncation; what it changes in an output is the estimate of the error of (H, N).  The step
# may be bordered by the branch's direction (the corrector's hyperplane), so that near a fold, where
# the Jacobian at fixed omega is singular, it measures the distance between the two curves rather
# than a slide along them.  A superharmonic resonance shows: the harmonic k of the forces drives
# the dynamic stiffness of harmonic k near its zero, and dx is large there.  A second step says
# whether the first can be trusted as a linearisation (its contraction).
#
# Measured (docs/benchmarks_truncation.md): within 0.37-1.29 of the true error at the located peaks
# of the SDOF Jenkins oscillator and of two masses at a 3:1 superharmonic resonance, H = 1 to 9.
# It is a local estimate: it sees the error where the orbit at H is near the one at 3H.  On the
# beam at 3 N, whose impacts converge erratically in H (its peak moves by -5 %, -7 %, -4.5 %, ...
# from H = 5 to 15), the orbit at H = 5 lies on an artefact loop that more harmonics remove, and the
# step from it measures the distance to a nearby orbit at 3H that is not the answer.

def output_signal(x: np.ndarray, dof, harmonics: Harmonics) -> np.ndarray:
    """An output's harmonic coefficients (num_hc,) from coefficients x (index or recovery row)."""
    X = np.asarray(x).reshape(harmonics.num_hc, -1)
    return X @ dof if np.ndim(dof) else X[:, dof]


def amplitude_and_rms(coeffs: np.ndarray, harmonics: Harmonics) -> tuple[float, float]:
    """(first-harmonic amplitude, RMS over a period) of one signal's coefficients (num_hc,)."""
    a1 = float(np.hypot(coeffs[harmonics.block_cos(1)], coeffs[harmonics.block_sin(1)]))
    rms = float(np.sqrt(coeffs[0] ** 2 + 0.5 * np.sum(coeffs[1:] ** 2)))
    return a1, rms


@dataclass(frozen=True)
class TruncationError:
    """The estimated error of one point, per output (in the order of ``outputs``): ``amplitude`` and
    ``rms`` are the (H2, N2) correction's change of the first-harmonic amplitude and of the RMS over
    a period, m (signed: the better answer minus the point's).  ``contraction``: the size of the
    second Newton step over the first's (scaled norms); the estimate is the linearised answer only
    where this is small (``reliable``: below ``RELIABLE_CONTRACTION``).  ``harmonics_to``: (H2, N2)."""

    amplitude: np.ndarray
    rms: np.ndarray
    contraction: float
    harmonics_to: Harmonics

    @property
    def reliable(self) -> bool:
        return bool(self.contraction <= RELIABLE_CONTRACTION)


# Newton's second step at most this fraction of its first: the correction is then known to within
# about that fraction of itself (the steps of a contracting iteration shrink geometrically).  On the
# SDOF Jenkins oscillator and the two masses of tests/test_convergence.py the ratio is at most 0.2
# (measured) where the estimate is within 1.3x of the truth; where it passes 0.5 the step left the
# region in which one linearisation holds (the impacting beam, docs/theory.md).
RELIABLE_CONTRACTION = 0.5


def estimate_harmonics(harmonics: Harmonics, *, factor: int = 3) -> Harmonics:
    """(H2, N2) of the estimate: H2 = factor H (a friction or impact force's harmonics up to 3H
    drive the response's; measured on the SDOF Jenkins oscillator, the step to 3H gives the peak's
    error within 1.3x from H = 1 to 7) and N2 = 2N (the sampling error of the AFT: halving the
    spacing of the samples), at least 4 H2 + 4."""
    H2 = max(factor * harmonics.H, harmonics.H + 2)
    return Harmonics(H2, max(2 * harmonics.N, 4 * H2 + 4))


class TruncationEstimator:
    """The estimate of this section for the points of one problem: ``problem_at`` builds the same
    problem at other harmonics (analysis.frf.create_problem of the model); ``outputs``, name ->
    index or recovery row of the problem's coordinates; ``x_scale``, ``lam_scale``: the branch's
    scales (hbm.problem.Scales), in which the border is orthogonal and the steps are measured."""

    def __init__(self, problem_at: Callable[[Harmonics], "Problem"], harmonics: Harmonics, outputs: dict, *,
                 x_scale: np.ndarray, lam_scale: float, factor: int = 3):
        self.h = harmonics
        self.h2 = estimate_harmonics(harmonics, factor=factor)
        self.problem = problem_at(self.h2)
        self.outputs = dict(outputs)
        self.q = x_scale.size // harmonics.num_hc
        self.x_scale = np.tile(np.asarray(x_scale)[: self.q], self.h2.num_hc)
        self.lam_scale = float(lam_scale)

    def pad(self, x: np.ndarray) -> np.ndarray:
        """x at H as coefficients at H2 (the harmonics above H zero)."""
        x2 = np.zeros(self.q * self.h2.num_hc)
        x2[: x.size] = x
        return x2

    def _step(self, x2: np.ndarray, lam: float, border: np.ndarray | None, offset: float):
        """One Newton step of the (H2, N2) problem at (x2, lam): (dx, dlam, scaled norm of the step).
        With ``border`` (unit, scaled), the step keeps border . (dy, dlam) = -offset."""
        pb = self.problem
        adapt = pb.adaptation
        if adapt is not None:
            adapt.restore(adapt.state_of(x2))
        sel = pb.unknowns()
        sel = np.arange(x2.size) if sel is None else np.asarray(sel)
        ev = pb.evaluate(x2, lam, jacobian=True)
        xs = self.x_scale[sel]
        J = (ev.J @ sp.diags(xs)).tocsc() if sp.issparse(ev.J) else ev.J * xs
        if border is None:
            dy, dl = linear_solve(J, -ev.R), 0.0
        else:
            z = linear_solve(bordered(J, ev.dR_dlam * self.lam_scale, border[np.append(sel, -1)]),
                             np.append(-ev.R, -offset))
            dy, dl = z[:-1], z[-1]
        if not (np.all(np.isfinite(dy)) and np.isfinite(dl)):
            raise np.linalg.LinAlgError("the truncation estimate's Newton step is not finite (a singular Jacobian at H2)")
        dx = np.zeros(x2.size)
        dx[sel] = dy * xs
        return dx, dl * self.lam_scale, float(np.hypot(np.linalg.norm(dy), dl))

    def __call__(self, x: np.ndarray, lam: float, direction: tuple[np.ndarray, float] | None = None
                 ) -> TruncationError:
        """The estimate at the converged point (x, lam) of the problem at H: two Newton steps of the
        (H2, N2) problem from x padded, the second to measure how far the first can be trusted.
        ``direction``: the branch's direction there (dx, dlam), to border the steps (the
        corrector's hyperplane: near a fold the Jacobian at fixed lam is singular), or None for
        steps at fixed lam."""
        x0 = self.pad(x)
        border = None
        if direction is not None:
            t = np.append(self.pad(direction[0]) / self.x_scale, direction[1] / self.lam_scale)
            border = t / max(np.linalg.norm(t), 1e-300)
        dx1, dl1, n1 = self._step(x0, lam, border, 0.0)
        x1, lam1 = x0 + dx1, lam + dl1
        offset = 0.0 if border is None else float(border @ np.append(dx1 / self.x_scale, dl1 / self.lam_scale))
        try:
            dx2, dl2, n2 = self._step(x1, lam1, border, offset)
            contraction = n2 / n1 if n1 > 0 else 0.0
        except np.linalg.LinAlgError:
            dx2, dl2, contraction = np.zeros_like(dx1), 0.0, np.inf
        amp, rms = [], []
        for dof in self.outputs.values():
            a0, r0 = amplitude_and_rms(output_signal(x0, dof, self.h2), self.h2)
            a1, r1 = amplitude_and_rms(output_signal(x1, dof, self.h2), self.h2)
            amp.append(a1 - a0)
            rms.append(r1 - r0)
        return TruncationError(np.array(amp), np.array(rms), float(contraction), self.h2)
