"""The physical model handed from the builders to the solvers: plain NumPy/SciPy data."""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp

from ..contact.jenkins import JenkinsPairs
from ..contact.law import ContactLaw


@dataclass(frozen=True)
class ContactGroup:
    """The pairs of one contact law and the gap operator that maps DOFs to their local gaps.

    pairs: P pairs of one law (jointfem.contact.law.ContactLaw: Jenkins, unilateral springs, ...).
    gap: sparse, shape (P*m, n): row p*m + a is component a of the relative displacement of
    pair p in its local frame (Jenkins: t1, [t2], [n]), m.
    names: a label per pair (for outputs and plots).
    coords: a reference position per pair, shape (P, 3), m (for plots).
    areas: the contact area each pair stands for, shape (P,), m^2 (continua; for the per-area
    quantities of the pictures and exports: pressure, energy per area).
    """

    pairs: ContactLaw
    gap: sp.csr_matrix
    names: tuple[str, ...] = ()
    coords: np.ndarray | None = None
    areas: np.ndarray | None = None
    load: sp.csr_matrix | None = None  # L: the force enters the residual as L^T (f - f0); None means L = G

    def __post_init__(self):
        P, m = self.pairs.num_pairs, self.pairs.num_comp
        if self.gap.shape[0] != P * m:
            raise ValueError(f"gap operator has {self.gap.shape[0]} rows, expected {P}*{m}")
        if self.load is not None and self.load.shape != self.gap.shape:
            raise ValueError(f"load operator has shape {self.load.shape}, expected {self.gap.shape}")

    @property
    def load_operator(self) -> sp.csr_matrix:
        return self.gap if self.load is None else self.load

    @property
    def stuck_stiffness(self) -> sp.csr_matrix:
        """L^T Kc G: the group's contribution to the linearised (all-stuck) stiffness, N/m."""
        kc = sp.diags(self.pairs.stiffness.ravel())
        return sp.csr_matrix(self.load_operator.T @ kc @ self.gap)

    @property
    def rest_stiffness(self) -> sp.csr_matrix:
        """L^T Kc G with the law's tangent at rest (ContactLaw.rest_stiffness), N/m."""
        kc = sp.diags(self.pairs.rest_stiffness.ravel())
        return sp.csr_matrix(self.load_operator.T @ kc @ self.gap)


@dataclass(frozen=True)
class Links:
    """Linear joint connections between substructures (e.g. the beam's rotational springs).

    gap: sparse (L, n) relative displacement of each link; stiffness: (L,) N/m or N m/rad.
    Their stiffness G^T diag(k) G is already part of Structure.K; they are listed so that
    reductions built from substructure matrices can take it out again.
    """

    gap: sp.csr_matrix
    stiffness: np.ndarray

    @property
    def matrix(self) -> sp.csr_matrix:
        return sp.csr_matrix(self.gap.T @ sp.diags(self.stiffness) @ self.gap)


def pair_names(groups) -> tuple[str, ...]:
    """A name per physical pair of the contact groups, in their order (``pair<i>`` where unnamed)."""
    return tuple(nm for g in groups for nm in (g.names or [f"pair{i}" for i in range(g.pairs.num_pairs)]))


def per_pair(groups, attr: str) -> np.ndarray | None:
    """A per-pair attribute ("coords", "areas") of the contact groups, concatenated; None unless every
    group has it."""
    parts = [getattr(g, attr) for g in groups]
    return np.concatenate(parts) if parts and all(x is not None for x in parts) else None


@dataclass(frozen=True)
class Structure:
    """M u'' + D u' + K u + sum_g G_g^T (f_g(G_g u) - f0_g) = Re[(fc - i fs) e^{i omega t}].

    K, M, D: sparse (n, n) in N/m, kg, N s/m.  The external force is
    fc cos(omega t) + fs sin(omega t), N.  The static preload f0 of every
    contact group is balanced by a static external load (bolt force), so only
    the change of the contact force drives the dynamics.
    """

    K: sp.csr_matrix
    M: sp.csr_matrix
    D: sp.csr_matrix
    fc: np.ndarray
    fs: np.ndarray
    contacts: tuple[ContactGroup, ...] = ()
    dof_names: tuple[str, ...] = ()
    outputs: dict = field(default_factory=dict)  # name -> dof index
    info: dict = field(default_factory=dict)
    substructure: np.ndarray | None = None  # (n,) substructure id per DOF, for the CMS reductions
    links: Links | None = None  # linear joint connections included in K
    f0: np.ndarray | None = None  # (n,) a static external force, N (the zeroth harmonic); None: none

    @property
    def f_static(self) -> np.ndarray:
        """The static external force, N (zeros if there is none)."""
        return np.zeros(self.num_dofs) if self.f0 is None else self.f0

    @property
    def num_dofs(self) -> int:
        return self.K.shape[0]

    @property
    def num_pairs(self) -> int:
        return sum(g.pairs.num_pairs for g in self.contacts)

    @property
    def pair_names(self) -> tuple[str, ...]:
        """A name per physical pair, in the order of the contact groups (``pair<i>`` where unnamed)."""
        return pair_names(self.contacts)

    @property
    def pair_coords(self) -> np.ndarray | None:
        """Reference position per pair (num_pairs, 3), m; None unless every group has them."""
        return per_pair(self.contacts, "coords")

    @property
    def pair_areas(self) -> np.ndarray | None:
        """Contact area per pair (num_pairs,), m^2; None unless every group has them."""
        return per_pair(self.contacts, "areas")

    @property
    def K_lin(self) -> sp.csr_matrix:
        """Linearised stiffness with every contact pair stuck (paper Eq. 7), N/m."""
        K = self.K.copy()
        for g in self.contacts:
            K = K + g.stuck_stiffness
        return K.tocsr()

    @property
    def K_rest(self) -> sp.csr_matrix:
        """The stiffness of small vibrations about rest: friction pairs stuck, open pairs and
        unilateral springs short of their gap open (ContactLaw.rest_stiffness), N/m.  It differs
        from K_lin only where a law linearises elsewhere than at rest (a unilateral spring with a
        gap, which the reductions take engaged)."""
        K = self.K.copy()
        for g in self.contacts:
            K = K + g.rest_stiffness
        return K.tocsr()

    def linear_response(self, omega: float | np.ndarray) -> np.ndarray:
        """Complex amplitude of the stuck linear system, u = Re[X e^{i omega t}], shape (..., n), m."""
        f = self.fc - 1j * self.fs
        Kl = self.K_lin.tocsc()
        out = []
        for w in np.atleast_1d(omega):
            Z = (Kl - w**2 * self.M + 1j * w * self.D).tocsc()
            out.append(sp.linalg.spsolve(Z, f))
        X = np.array(out)
        return X[0] if np.ndim(omega) == 0 else X


def with_event_aft(structure: Structure) -> Structure:
    """The same structure with every Jenkins group evaluated by the event-accurate AFT
    (jointfem.contact._events); other laws are unchanged."""
    groups = tuple(replace(g, pairs=replace(g.pairs, events=True)) if isinstance(g.pairs, JenkinsPairs) else g
                   for g in structure.contacts)
    return replace(structure, contacts=groups)
