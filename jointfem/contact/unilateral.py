"""A unilateral spring with a gap: the second contact law, and the proof that a law is one file.

Per pair one component, the relative displacement ``g`` (m).  The spring engages once ``g``
passes the ``gap`` (m, >= 0) and pushes back with ``k (g - gap)`` (N); open, it carries nothing:

    f(g) = k (g - gap)  if g > gap,   0 otherwise.

The force is a function of the current gap (no memory), so the AFT is the DFT of ``f(g_t)`` and
its Jacobian is ``dF/dG = Gamma^-1 diag(k [g_t > gap]) Gamma`` per pair, exact between the samples'
switches.  Its static force is the force at rest, ``f0 = f(0) = 0``, and its linearisation the
spring ``f = k g`` (``Kc = k``): that holds at a sample where ``gap = 0`` and the spring is engaged,
or where ``g = 0``, and the penalty ROM's internal variable ``p = g - f/k`` is zero exactly there.
A sample where the spring is open is SEPARATED, an engaged one STICK.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..harmonics import Harmonics
from .law import SEPARATED, STICK, ContactLaw, ContactResult, check_gaps, loop_energy


@dataclass(frozen=True)
class UnilateralSprings(ContactLaw):
    """``P`` unilateral springs (arrays of shape (P,)): stiffness ``k`` (N/m) and ``gap`` (m, >= 0)."""

    k: np.ndarray
    gap: np.ndarray

    name = "unilateral_spring"

    def __post_init__(self):
        k = np.atleast_1d(np.asarray(self.k, dtype=float))
        gap = np.broadcast_to(np.asarray(self.gap, dtype=float), k.shape).copy()
        if np.any(k < 0) or np.any(gap < 0):
            raise ValueError(f"unilateral springs need k >= 0 and gap >= 0, got k = {k}, gap = {gap}")
        object.__setattr__(self, "k", k)
        object.__setattr__(self, "gap", gap)

    @property
    def num_pairs(self) -> int:
        return self.k.shape[0]

    @property
    def num_comp(self) -> int:
        return 1

    @property
    def stiffness(self) -> np.ndarray:
        return self.k[:, None].copy()

    @property
    def rest_stiffness(self) -> np.ndarray:
        """k where the gap is zero (touching at rest), 0 where it is open: at rest (g = 0) a spring
        with gap > 0 carries nothing and small vibrations do not reach it."""
        return np.where(self.gap > 0, 0.0, self.k)[:, None]

    @property
    def preload(self) -> np.ndarray:
        return np.zeros((self.num_pairs, 1))

    def _force(self, g: np.ndarray) -> np.ndarray:
        """f(g) of samples g (N, P)."""
        return np.where(g > self.gap[None, :], self.k[None, :] * (g - self.gap[None, :]), 0.0)

    def aft(self, G: np.ndarray, harmonics: Harmonics, *, jacobian: bool = True) -> ContactResult:
        G = check_gaps(self, G, harmonics)
        g_t = harmonics.to_time(G)  # (N, P, 1)
        engaged = g_t[:, :, 0] > self.gap[None, :]
        f_t = self._force(g_t[:, :, 0])[:, :, None]
        J = None
        if jacobian:
            # dF_h/dG_h' = sum_i Gamma^-1[h, i] k [g_i > gap] Gamma[i, h'], per pair
            kt = engaged * self.k[None, :]  # (N, P)
            J = np.einsum("hi,ip,ij->phj", harmonics.gamma_inv, kt, harmonics.gamma)[:, :, None, :, None]
        state = np.where(engaged, STICK, SEPARATED).astype(np.int8)
        return ContactResult(harmonics.from_time(f_t), J, f_t, g_t, state, np.zeros((self.num_pairs, 0)))

    def linear_breaks(self, g_t: np.ndarray, *, tol: float) -> np.ndarray:
        """Where the linear spring k g and the law differ at some sample, by more than ``tol``
        times the pair's force scale k max(|g|, gap)."""
        g = g_t[:, :, 0]
        scale = np.maximum(self.k * np.maximum(np.abs(g).max(axis=0), self.gap), 1e-300)
        return (np.abs(self.k[None, :] * g - self._force(g)).max(axis=0) > tol * scale)[:, None]

    def busy(self, result: ContactResult) -> np.ndarray:
        """Away from the linear spring at some sample (to round-off)."""
        return self.linear_breaks(result.g_t, tol=1e-12)

    def summary(self, f_t: np.ndarray, g_t: np.ndarray) -> np.ndarray:
        """Energy per cycle (0 up to the trapezoid's error: the law is elastic), the amplitude of g
        about its mean, and the peak force (reported as the "normal" force)."""
        g = g_t[:, :, 0]
        return np.column_stack([loop_energy(f_t, g_t), np.abs(g - g.mean(axis=0)).max(axis=0), f_t[:, :, 0].max(axis=0)])

    def subset(self, index: np.ndarray) -> "UnilateralSprings":
        return UnilateralSprings(k=self.k[index], gap=self.gap[index])
