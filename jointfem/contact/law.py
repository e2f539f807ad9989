"""What every contact law offers the layers above it: the one seam between a force law and
the harmonic balance, the reduced models and the outputs.

A contact group holds ``P`` pairs of ``m`` components each.  Its local relative displacements
(gaps) ``g``, shape ``(P, m)`` in m, come from the model's gap operator; its total force ``f``
of the same shape, in N, enters the residual as ``G^T (f - f0)``.  A law says:

* its sizes (``num_pairs``, ``num_comp``);
* its linearisation, ``stiffness`` ``Kc`` and ``preload`` ``f0`` (both ``(P, m)``): the law holds
  linearly where ``f = f0 + Kc g``.  This is the "stuck" joint of the penalty ROM (paper Eq. 7);
* ``aft(G, harmonics, jacobian=...)``: the force coefficients of gap coefficients, and their
  exact Jacobian, by alternating frequency-time;
* ``linear_breaks(g_t)``: which components the linearised law would break at some sample (the
  check that adds a component to the penalty ROM's active set), and ``busy(result)``: which must
  stay active at a converged point;
* ``summary(f_t, g_t)``: per pair, the dissipated energy per cycle, the tangential amplitude and
  the peak normal force (the columns of branch.npz's ``pair_*`` arrays);
* ``subset(index)``: the same law on some of its pairs (the penalty ROM's active pairs).

The state of a sample is STICK (the linear law holds), SLIP or SEPARATED (no force).

A new law is one file with one class derived from :class:`ContactLaw`, and one entry in
``jointfem.contact.LAWS``.  Nothing above this layer knows which law a group uses.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..harmonics import Harmonics

STICK, SLIP, SEPARATED = 0, 1, 2
STATE_NAMES = ("stick", "slip", "separated")


class ContactError(RuntimeError):
    """A contact law could not be evaluated (e.g. a slider's periodic steady state was not found)."""


@dataclass
class ContactResult:
    """AFT output for one group.

    F: force coefficients, shape (num_hc, P, m), N (total force, preload included).
    J: dF/dG, shape (P, num_hc, m, num_hc, m) ([p, h, a, h', b]), N/m; None if not asked.
    f_t, g_t: force and gap samples over the steady period, shape (N, P, m).
    state_t: STICK/SLIP/SEPARATED per sample and pair, shape (N, P), int8.
    w_start: the law's internal state at tau = 0 (Jenkins: the slider positions, (P, num_tangential));
    shape (P, 0) for a law without memory.
    """

    F: np.ndarray
    J: np.ndarray | None
    f_t: np.ndarray
    g_t: np.ndarray
    state_t: np.ndarray
    w_start: np.ndarray


class ContactLaw(ABC):
    """A homogeneous group of ``num_pairs`` pairs of one contact law (see the module docstring)."""

    name: ClassVar[str]  # the key of jointfem.contact.LAWS

    @property
    @abstractmethod
    def num_pairs(self) -> int:
        ...

    @property
    @abstractmethod
    def num_comp(self) -> int:
        """Components per pair, m."""

    @property
    @abstractmethod
    def stiffness(self) -> np.ndarray:
        """Linearised stiffness Kc per component, shape (P, m), N/m."""

    @property
    def rest_stiffness(self) -> np.ndarray:
        """The tangent stiffness of the law at rest (g = 0), shape (P, m), N/m: what the structure's
        small vibrations about rest see (``jointfem modes``).  By default ``stiffness``; a law whose
        linearisation ``stiffness`` is taken elsewhere than at rest says so here."""
        return self.stiffness

    @property
    @abstractmethod
    def preload(self) -> np.ndarray:
        """Static force f0 per component, shape (P, m), N."""

    @abstractmethod
    def aft(self, G: np.ndarray, harmonics: Harmonics, *, jacobian: bool = True) -> ContactResult:
        """Force coefficients (and dF/dG) of gap coefficients G of shape (num_hc, P, m)."""

    @abstractmethod
    def linear_breaks(self, g_t: np.ndarray, *, tol: float) -> np.ndarray:
        """Components (P, m) whose linearised force f0 + Kc g breaks the law at some sample of
        g_t (N, P, m); ``tol`` is relative to the law's own force scale."""

    @abstractmethod
    def busy(self, result: ContactResult) -> np.ndarray:
        """Components (P, m) that an AFT result shows away from the linear law (must stay active)."""

    @abstractmethod
    def summary(self, f_t: np.ndarray, g_t: np.ndarray) -> np.ndarray:
        """Per pair (P, 3): dissipated energy per cycle (J), tangential amplitude (m), peak normal
        force (N), from force and gap samples (N, P, m) of one period."""

    @abstractmethod
    def subset(self, index: np.ndarray) -> "ContactLaw":
        """The same law on the pairs ``index`` only."""

    def floquet_jacobian(self, result: ContactResult, harmonics: Harmonics, s: complex,
                         omega: float, *, derivative: bool = False):
        """d F / d V (P, num_hc, m, num_hc, m), complex, of a perturbation e^{s t} V of the gaps
        about the steady period of ``result`` (at omega): Hill's contact Jacobian where the law
        remembers its past (analysis.stability), or None where it is not known; with
        ``derivative``, (it, its derivative in s).  A law without memory has the periodic one,
        ``result.J``, whatever s."""
        if result.J is None:
            return None
        J = result.J.astype(complex)
        return (J, np.zeros_like(J)) if derivative else J

    @property
    def dissipative(self) -> np.ndarray:
        """(num_pairs, num_comp) bool: the components along which the law can dissipate energy
        (friction), so that it can bound an undamped resonance.  None by default."""
        return np.zeros((self.num_pairs, self.num_comp), bool)

    def closed_at_rest(self) -> "ContactLaw":
        """The same law with every pair closed at rest: what a reduction's basis may take for a pair
        that the motion has yet to close (JenkinsPairs: N0 >= 0).  The law itself by default."""
        return self

    def linear_summary(self, g_t: np.ndarray) -> np.ndarray:
        """``summary`` of pairs held by the linearised law f = f0 + Kc g."""
        return self.summary(self.preload[None] + self.stiffness[None] * g_t, g_t)


def check_gaps(law: ContactLaw, G: np.ndarray, harmonics: Harmonics) -> np.ndarray:
    """G as a float array, after checking that it fits the law and the harmonics."""
    G = np.asarray(G, dtype=float)
    if G.shape != (harmonics.num_hc, law.num_pairs, law.num_comp):
        raise ValueError(f"gap coefficients of shape {G.shape} do not fit {harmonics} and "
                         f"{law.num_pairs} pairs x {law.num_comp}")
    return G


def loop_energy(f_t: np.ndarray, g_t: np.ndarray) -> np.ndarray:
    """Work of f over the closed loop of g per pair, J: sum over samples of (f_i + f_i+1)/2 .
    (g_i+1 - g_i) (trapezoid, periodic); f_t, g_t of shape (N, P, k).  Positive when dissipated."""
    dg = np.roll(g_t, -1, axis=0) - g_t
    fm = 0.5 * (f_t + np.roll(f_t, -1, axis=0))
    return np.einsum("ipa,ipa->p", fm, dg)
