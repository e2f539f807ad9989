"""Node-to-node Jenkins contact (paper Eq. 3-6) and its AFT with the exact Jacobian.

One kernel serves every form: ``num_tangential`` is 1 or 2 (a 1D slider, or a 2D
slider with a circular friction limit and radial return), and ``has_normal``
says whether the normal gap is a variable (normal load ``N = N0 + kn*g_n``,
separation when ``N <= 0``) or not (constant normal load ``N0``).

Per pair the local relative displacement is ``g = [g_t1, (g_t2), (g_n)]``, in m,
``m = num_tangential + has_normal`` components, in the pair's own local frame
(the frame lives in the model's gap operator).  The total contact force is
``f = [f_t1, (f_t2), (N)]`` in N, compressive normal force positive.  The slider
position ``w`` (shape ``(P, num_tangential)``) carries the memory.

Discrete law at each time sample (return mapping)::

    N = N0 + kn g_n                       (N0 if no normal DOF)
    N <= 0:        f = 0, w = g_t          (separated)
    first contact: w_prev = g_t at the zero crossing of N between the samples (re-engages unloaded)
    t = kt (g_t - w_prev)                  (trial force)
    |t| <= mu N:   f_t = t, w = w_prev      (stick)
    otherwise:     f_t = mu N t/|t|, w = g_t - f_t/kt   (slip, radial return)

The force coefficients are the DFT of these samples, except that the normal force of a sample
next to a separated one is crossing-corrected (see _kernels._phi and docs/theory.md).

With ``events=True`` (scene key ``[solver] aft = "events"``, one tangential direction) the law is
integrated in continuous time instead: switches located between samples and the forces integrated
over the pieces between them (compute_aft_events, _events.py).

The march is sequential in time and vectorised over pairs.  The periodic steady
state is marched from w = 0: plain periods, then Newton on the fixed point
``w_start = P(w_start; g)`` of the period map.  A pair that never slips keeps
``w = 0`` (the unloaded spring position), so a fully stuck joint is exactly the
linear spring ``f - f0 = Kc g``; a pair that slips only in its transient and then
sticks for good (shakedown) keeps the slider where its transient left it.

The Jacobian of the force coefficients with respect to the gap coefficients is
exact: the tangent is propagated through the march, including the dependence
of every stick phase on the slider state at the last stick onset, and through
the periodicity of the steady state (implicit function theorem on the fixed
point), so ``d F / d G = J_G + J_w (I - T)^-1 S``; for a shakedown, through the
transient periods instead.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..harmonics import Harmonics
from ._events import MAX_EVENTS, event_kernel, event_tables
from ._floquet import floquet_kernel
from ._kernels import aft_kernel, product_table
from .law import (SEPARATED, SLIP, STATE_NAMES, STICK, ContactError, ContactLaw, ContactResult,  # noqa: F401
                  check_gaps, loop_energy)


@dataclass(frozen=True)
class JenkinsPairs(ContactLaw):
    """A homogeneous group of ``P`` Jenkins pairs (arrays of shape (P,), SI units)."""

    kt: np.ndarray  # tangential stiffness, N/m
    kn: np.ndarray  # normal stiffness, N/m (ignored when has_normal is False)
    mu: np.ndarray  # friction coefficient, -
    N0: np.ndarray  # normal preload, N (compressive positive); N0 = -kn g0 < 0: open by an initial gap g0 (m)
    num_tangential: int = 1
    has_normal: bool = False
    events: bool = False  # event-accurate AFT (_events.py) instead of the sampled law; one tangential direction

    name = "jenkins"

    def __post_init__(self):
        for name in ("kt", "kn", "mu", "N0"):
            object.__setattr__(self, name, np.atleast_1d(np.asarray(getattr(self, name), dtype=float)))
        P = self.kt.shape[0]
        for name in ("kn", "mu", "N0"):
            a = getattr(self, name)
            if a.shape == (1,) and P != 1:
                object.__setattr__(self, name, np.full(P, a[0]))
            elif a.shape != (P,):
                raise ValueError(f"JenkinsPairs.{name} has shape {a.shape}, expected ({P},)")
        if self.num_tangential not in (1, 2):
            raise ValueError(f"num_tangential must be 1 or 2, got {self.num_tangential!r}")
        if np.any(self.N0 < 0) and not self.has_normal:
            raise ValueError("JenkinsPairs: a negative N0 (an initial gap) needs a normal DOF (has_normal)")
        if self.events and self.num_tangential != 1:
            raise ValueError("the event-accurate AFT (aft = \"events\") has one tangential direction; "
                             f"these pairs have {self.num_tangential}")

    @property
    def num_pairs(self) -> int:
        return self.kt.shape[0]

    @property
    def num_comp(self) -> int:
        """Components per pair, m = num_tangential + has_normal."""
        return self.num_tangential + int(self.has_normal)

    @property
    def dissipative(self) -> np.ndarray:
        """The tangential components of pairs with friction (mu > 0)."""
        d = np.zeros((self.num_pairs, self.num_comp), bool)
        d[:, :self.num_tangential] = (self.mu > 0)[:, None]
        return d

    @property
    def open(self) -> np.ndarray:
        """Pairs open at rest: N0 < 0, an initial gap g0 = -N0 / kn that the motion must close."""
        return self.N0 < 0

    @property
    def initial_gap(self) -> np.ndarray:
        """g0 per pair, m: -N0 / kn for an open pair, 0 for a closed one."""
        return np.where(self.open, -self.N0 / np.where(self.kn > 0, self.kn, 1.0), 0.0)

    def law_spring(self) -> tuple[np.ndarray, np.ndarray]:
        """(Kc, f0), each (P, m): the law's own stuck spring f = f0 + Kc g, kt (and kn) and N0 as
        given, an open pair's negative N0 too (what the event kernel integrates the departure from)."""
        k = np.repeat(self.kt[:, None], self.num_comp, axis=1)
        f0 = np.zeros((self.num_pairs, self.num_comp))
        if self.has_normal:
            k[:, -1], f0[:, -1] = self.kn, self.N0
        return k, f0

    @property
    def preload(self) -> np.ndarray:
        """Static force f0 of shape (P, m): the force at rest, zero tangential force and N0 normal
        force (zero for an open pair, which carries nothing until it closes)."""
        return np.maximum(self.law_spring()[1], 0.0)

    @property
    def stiffness(self) -> np.ndarray:
        """Stuck stiffness per component, shape (P, m): kt (and kn); zero for an open pair (the
        linearisation at rest, where it carries no force)."""
        k = self.law_spring()[0]
        k[self.open] = 0.0
        return k

    def aft(self, G: np.ndarray, harmonics: Harmonics, *, jacobian: bool = True) -> ContactResult:
        return compute_aft(self, G, harmonics, jacobian=jacobian)

    def floquet_jacobian(self, result: ContactResult, harmonics: Harmonics, s: complex,
                         omega: float, *, derivative: bool = False):
        """The sampled law's contact Jacobian for a perturbation e^{s t} V, the slider's memory
        weighted by e^{-s tau} (_floquet.py), and with ``derivative`` its derivative in s too;
        None for the event-accurate law (not written)."""
        if self.events:
            return None
        N, P, m = result.g_t.shape
        nh = harmonics.num_hc
        moved = np.any(result.state_t != STICK, axis=0)
        J = np.zeros((P, nh, m, nh * m), dtype=complex)
        dJ = np.zeros_like(J)
        dt = 2.0 * np.pi / (abs(omega) * N)
        floquet_kernel(np.ascontiguousarray(result.g_t), self.kt, self.kn, self.mu, self.N0, self.num_tangential,
                       self.has_normal, harmonics.gamma, _complex_analysis(harmonics),
                       np.ascontiguousarray(result.w_start), moved, np.exp(-complex(s) * dt), dt, J, dJ)
        J = J.reshape(P, nh, m, nh, m)
        return (J, dJ.reshape(P, nh, m, nh, m)) if derivative else J

    def closed_at_rest(self) -> "JenkinsPairs":
        """Open pairs (N0 < 0) closed at rest with no preload: their stuck springs kt, kn."""
        return self if not self.open.any() else JenkinsPairs(
            kt=self.kt, kn=self.kn, mu=self.mu, N0=np.maximum(self.N0, 0.0), num_tangential=self.num_tangential,
            has_normal=self.has_normal, events=self.events)

    def subset(self, index: np.ndarray) -> "JenkinsPairs":
        return JenkinsPairs(kt=self.kt[index], kn=self.kn[index], mu=self.mu[index], N0=self.N0[index],
                            num_tangential=self.num_tangential, has_normal=self.has_normal, events=self.events)

    def linear_breaks(self, g_t: np.ndarray, *, tol: float) -> np.ndarray:
        """Components whose force, were they stuck at the unloaded position (the linear spring),
        would break the law at some sample: |t| > mu N (the tangential components) or N < 0 (a
        separation flags the whole pair)."""
        P, m, nt = self.num_pairs, self.num_comp, self.num_tangential
        N = self.N0[None, :] + (self.kn[None, :] * g_t[:, :, -1] if self.has_normal else 0.0)
        # an open pair is never its linear spring (it has none: the penalty ROM keeps it active)
        sep = (N < -tol * np.maximum(self.N0, 1e-300)).any(axis=0) | self.open
        t = self.kt[None, :] * np.linalg.norm(g_t[:, :, :nt], axis=2)
        slip = (t > self.mu * np.maximum(N, 0.0) + tol * np.maximum(self.mu * self.N0, 1e-300)).any(axis=0)
        out = np.zeros((P, m), bool)
        out[slip | sep, :nt] = True
        if self.has_normal:
            out[sep, :] = True
        return out

    def busy(self, result: ContactResult) -> np.ndarray:
        """A pair that slips or separates at some sample keeps its tangential components; one that
        separates keeps its normal component too."""
        nt = self.num_tangential
        slip = np.any(result.state_t == SLIP, axis=0)
        sep = np.any(result.state_t == SEPARATED, axis=0) | self.open
        out = np.zeros((self.num_pairs, self.num_comp), bool)
        out[slip | sep, :nt] = True
        if self.has_normal:
            out[sep, nt:] = True
        return out

    def summary(self, f_t: np.ndarray, g_t: np.ndarray) -> np.ndarray:
        """Per-pair quantities of one steady period, shape (P, 3):

        0. dissipated energy per cycle, J: the work of the friction force on the slider,
           sum_i f_(i+1) . (w_(i+1) - w_i) with the slider position w = g - f / kt, exact for the
           sampled law and >= 0 by its radial return (the trapezoid rule over the loop of g, used
           before, mixed in the spring's elastic energy at O(step^2): -1.5e-11 J on a stuck pair);
           exactly 0 for a pair stuck all period;
        1. amplitude of the tangential relative displacement, m: max over the period of
           |g_t - mean g_t| (the slip plus the elastic stretch of the pair's spring);
        2. peak normal force over the period, N (N0 when the normal is not a variable).
        """
        nt = self.num_tangential
        g = g_t[:, :, :nt]
        f = f_t[:, :, :nt]
        w = g - f / self.kt[None, :, None]
        dw = np.roll(w, -1, axis=0) - w
        # between two samples strictly inside the friction cone the slider does not move (the
        # kernel copies w): w recovered from g and f differs there by round-off only, which showed
        # as +-1e-23 J on stuck pairs
        lim = self.mu[None, :] * (f_t[:, :, nt] if self.has_normal else self.N0[None, :])
        inside = np.linalg.norm(f, axis=2) < lim * (1.0 - 1e-9)
        dw[inside & np.roll(inside, -1, axis=0)] = 0.0
        energy = np.einsum("ipa,ipa->p", np.roll(f, -1, axis=0), dw)
        amp = np.linalg.norm(g - g.mean(axis=0), axis=2).max(axis=0)
        normal = f_t[:, :, nt].max(axis=0) if self.has_normal else self.N0.copy()
        return np.column_stack([energy, amp, normal])


@lru_cache(maxsize=16)
def _complex_analysis(harmonics: Harmonics) -> np.ndarray:
    """gamma_inv as complex (what the Floquet kernel's BLAS product takes)."""
    return np.ascontiguousarray(harmonics.gamma_inv, dtype=complex)


@lru_cache(maxsize=16)
def _operators(harmonics: Harmonics):
    """Running sums and product table that the compiled kernel needs, per Harmonics."""
    N, H = harmonics.N, harmonics.H
    cum_gamma_inv = np.zeros((N + 1, harmonics.num_hc))
    cum_gamma_inv[1:] = np.cumsum(harmonics.gamma_inv.T, axis=0)
    kt = np.outer(harmonics.tau, np.arange(2 * H + 1))
    trig = np.ascontiguousarray(np.stack([np.cos(kt), np.sin(kt)], axis=1))  # (N, 2, 2H+1)
    cum_trig = np.zeros((N + 1, 2, 2 * H + 1))
    cum_trig[1:] = np.cumsum(trig, axis=0)
    return cum_gamma_inv, trig, cum_trig, product_table(H, N)


def compute_aft(pairs: JenkinsPairs, G: np.ndarray, harmonics: Harmonics, *, jacobian: bool = True,
                rtol: float = 1e-10, max_iter: int = 50) -> ContactResult:
    """Alternating frequency-time evaluation of a group of Jenkins pairs.

    G: gap coefficients, shape (num_hc, P, m), m.  Returns a ContactResult whose J is
    dF/dG of shape (P, num_hc, m, num_hc, m) when ``jacobian``.
    Raises ContactError if a slider's periodic steady state is not found.
    """
    G = check_gaps(pairs, G, harmonics)
    if pairs.events:
        return compute_aft_events(pairs, G, harmonics, jacobian=jacobian, rtol=rtol, max_iter=max_iter)
    num_hc, P, m = G.shape
    g_t = np.ascontiguousarray(harmonics.to_time(G))
    N = harmonics.N
    nt = pairs.num_tangential
    f_t = np.zeros((N, P, m))
    state_t = np.empty((N, P), dtype=np.int8)
    w_start = np.zeros((P, nt))
    status = np.zeros(P, dtype=np.int8)
    errs = np.zeros(P)
    J = np.zeros((P, num_hc, m, num_hc * m) if jacobian else (1, 1, 1, 1))
    ops = _operators(harmonics)
    aft_kernel(g_t, pairs.kt, pairs.kn, pairs.mu, pairs.N0, nt, pairs.has_normal, harmonics.gamma, *ops,
               jacobian, rtol, max_iter, f_t, state_t, w_start, J, status, errs)
    if status.any():
        bad = int(np.argmax(errs))
        raise ContactError(f"slider steady state not reached for {int(status.sum())} pair(s) after {max_iter} "
                           f"periods; worst: pair {bad}, relative change {errs[bad]:.3e} > {rtol:.1e}")
    J = J.reshape(P, num_hc, m, num_hc, m) if jacobian else None
    return ContactResult(harmonics.from_time(f_t), J, f_t, g_t, state_t, w_start)


@lru_cache(maxsize=16)
def _event_operators(harmonics: Harmonics):
    """Synthesis of tau-rates at the samples (gammad), the running integrals Tcum
    (_events.event_tables), and 4-point Gauss-Legendre on [0, 1] (xq, wq)."""
    gammad = np.ascontiguousarray(harmonics.gamma @ harmonics.derivative_matrix())
    x, w = np.polynomial.legendre.leggauss(4)
    xq, wq = 0.5 * (x + 1.0), 0.5 * w
    return gammad, event_tables(harmonics.N, harmonics.num_hc), xq, wq


def compute_aft_events(pairs: JenkinsPairs, G: np.ndarray, harmonics: Harmonics, *, jacobian: bool = True,
                       rtol: float = 1e-10, max_iter: int = 50) -> ContactResult:
    """The event-accurate AFT (_events.py): switches located between samples on the cubic Hermite
    interpolant of the gaps, force coefficients integrated over the pieces between them.

    Same arguments and result as compute_aft; f_t and state_t are the force and state at the samples.
    """
    num_hc, P, m = G.shape
    g_t = np.ascontiguousarray(harmonics.to_time(G))
    gammad, Tcum, xq, wq = _event_operators(harmonics)
    gd_t = np.ascontiguousarray(harmonics.to_time(np.einsum("jk,kpa->jpa", harmonics.derivative_matrix(), G)))
    N = harmonics.N
    F = np.zeros((P, num_hc, m))
    J = np.zeros((P, num_hc, m, num_hc * m) if jacobian else (P, 1, 1, 1))
    f_t = np.zeros((N, P, m))
    state_t = np.zeros((N, P), dtype=np.int8)
    res = np.zeros((P, 4))
    event_kernel(g_t, gd_t, np.ascontiguousarray(G), np.ascontiguousarray(harmonics.gamma), gammad, Tcum, xq, wq,
                 pairs.kt, pairs.kn, pairs.mu,
                 pairs.N0, pairs.has_normal, jacobian, max_iter, rtol, F, J, f_t, state_t, res)
    status = res[:, 1]
    if (status == 2).any():
        bad = int(np.argmax(status == 2))
        raise ContactError(f"event-accurate AFT: more than {MAX_EVENTS} switches of pair {bad} between samples "
                           f"{int(res[bad, 3])} and {int(res[bad, 3]) + 1} of {N}; use more samples")
    if status.any():
        bad = int(np.argmax(res[:, 2] * (status == 1)))
        raise ContactError(f"slider steady state not reached for {int((status == 1).sum())} pair(s) after "
                           f"{max_iter} periods (event-accurate AFT); worst: pair {bad}, relative change "
                           f"{res[bad, 2]:.3e} > {rtol:.1e}")
    # the stuck spring f0 + Kc g exactly (the kernel integrated the departure from it), so that a
    # pair stuck all period is exactly linear, as with the sampled law.  The kernel's spring is the
    # law's own (kt, kn and N0 as given, an open pair's negative N0 too), not the linearisation's
    # (pairs.stiffness and pairs.preload are zero for a pair open at rest)
    Kc, f0 = pairs.law_spring()
    F = F.transpose(1, 0, 2) + Kc[None] * G
    F[0] += f0
    Jr = None
    if jacobian:
        Jr = J.reshape(P, num_hc, m, num_hc, m)
        for a in range(m):
            Jr[:, np.arange(num_hc), a, np.arange(num_hc), a] += Kc[:, a, None]
    return ContactResult(np.ascontiguousarray(F), Jr, f_t, g_t, state_t, res[:, :1].copy())


def compute_dissipation(f_t: np.ndarray, g_t: np.ndarray) -> np.ndarray:
    """Energy dissipated per cycle per pair, J: the closed loop integral of f . dg (trapezoid).

    f_t, g_t of shape (N, P, m).  Positive for a dissipating element.
    """
    return loop_energy(f_t, g_t)
