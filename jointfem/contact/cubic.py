"""A cubic spring: the hardening element of the Duffing oscillator, as a contact law.

Per pair one component, the relative displacement ``g`` (m), and the force ``f = k3 g^3`` (N), with
``k3`` in N/m^3.  The force is a smooth function of the current gap (no memory, no kinks), so the
AFT is the DFT of ``f(g_t)`` and its Jacobian ``dF/dG = Gamma^-1 diag(3 k3 g_t^2) Gamma`` per pair is
exact.  Its linearisation at rest is no spring at all (``Kc = 0``, ``f0 = 0``): a stuck joint is the
structure without it.  Every sample is reported as STICK (the law neither slips nor opens), and the
energy per cycle is zero (the law is elastic).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..harmonics import Harmonics
from .law import STICK, ContactLaw, ContactResult, check_gaps, loop_energy


@dataclass(frozen=True)
class CubicSprings(ContactLaw):
    """``P`` cubic springs: ``k3`` (N/m^3, shape (P,))."""

    k3: np.ndarray

    name = "cubic_spring"

    def __post_init__(self):
        k3 = np.atleast_1d(np.asarray(self.k3, dtype=float))
        if not np.all(np.isfinite(k3)):
            raise ValueError(f"cubic springs need finite k3, got {k3}")
        object.__setattr__(self, "k3", k3)

    @property
    def num_pairs(self) -> int:
        return self.k3.shape[0]

    @property
    def num_comp(self) -> int:
        return 1

    @property
    def stiffness(self) -> np.ndarray:
        return np.zeros((self.num_pairs, 1))

    @property
    def preload(self) -> np.ndarray:
        return np.zeros((self.num_pairs, 1))

    def aft(self, G: np.ndarray, harmonics: Harmonics, *, jacobian: bool = True) -> ContactResult:
        G = check_gaps(self, G, harmonics)
        g_t = harmonics.to_time(G)  # (N, P, 1)
        g = g_t[:, :, 0]
        f_t = (self.k3[None, :] * g**3)[:, :, None]
        J = None
        if jacobian:
            kt = 3.0 * self.k3[None, :] * g**2  # (N, P)
            J = np.einsum("hi,ip,ij->phj", harmonics.gamma_inv, kt, harmonics.gamma)[:, :, None, :, None]
        state = np.full(g.shape, STICK, np.int8)
        return ContactResult(harmonics.from_time(f_t), J, f_t, g_t, state, np.zeros((self.num_pairs, 0)))

    def linear_breaks(self, g_t: np.ndarray, *, tol: float) -> np.ndarray:
        """Wherever the spring moves at all: its linearisation is no spring, so any k3 g^3 != 0
        breaks it (``tol`` is relative to a scale this law does not have)."""
        moves = np.abs(g_t[:, :, 0]).max(axis=0) > 0.0
        return (moves & (self.k3 != 0.0))[:, None]

    def busy(self, result: ContactResult) -> np.ndarray:
        return self.linear_breaks(result.g_t, tol=0.0)

    def summary(self, f_t: np.ndarray, g_t: np.ndarray) -> np.ndarray:
        """Energy per cycle (0 up to quadrature: the law is elastic), the amplitude of g about its
        mean, and the peak force."""
        g = g_t[:, :, 0]
        return np.column_stack([loop_energy(f_t, g_t), np.abs(g - g.mean(axis=0)).max(axis=0),
                                np.abs(f_t[:, :, 0]).max(axis=0)])

    def subset(self, index: np.ndarray) -> "CubicSprings":
        return CubicSprings(k3=self.k3[index])
