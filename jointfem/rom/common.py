"""What every reduction shares: options, errors, the reduced models and their checks.

As in pyMOR, a reductor (a function of jointfem.rom.reductors.REDUCTORS) takes the full model and
returns a reduced model; the reduced model knows how to ``reconstruct`` the physical DOFs and
offers its HBM problem (``create_problem``) to the analyses.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .. import defaults
from ..harmonics import Harmonics
from ..hbm.condensed import CondensedProblem, ModalBasis, modal_basis
from ..hbm.forced import ForcedProblem
from ..hbm.problem import Problem
from ..linalg import bordered_unavailable, eigen, finite_frequencies
from ..models.structure import ContactGroup, Structure


class RomError(ValueError):
    """A reduction cannot be built for this model (names the method and the reason)."""


class BasisError(RomError):
    """A reduction basis failed its postcondition (rank, M-orthonormality)."""


@dataclass(frozen=True)
class RomOptions:
    modes: int = defaults.ROM_MODES  # vibration modes: global (penalty, tvd) or in total over the substructures (CMS)
    tvd: int = defaults.ROM_TVD  # POD-compressed trial-vector derivatives (penalty, tvd)
    # which TVDs: "eigen", exact eigenvector derivatives with respect to each contact stiffness;
    # "eq12", the paper's static modal derivatives (Eq. 12; tvd method only: docs/theory.md)
    tvd_kind: str = "eigen"
    interface_modes: int | None = None  # cc: characteristic constraint modes (default: half the boundary DOFs)
    release_after: int = 2  # penalty: converged points a pair must stay stuck before it leaves the active set
    # penalty on a continuum scene: "replicated" (every rank holds K, M and the basis) or "distributed"
    # (jointfem.fem.distributed: they stay in row blocks on the ranks; issue 17)
    offline: str = "replicated"


def check_modes(Phi: np.ndarray, M, what: str, *, rtol: float = 1e-6) -> None:
    """Postcondition of an eigensolve: Phi^T M Phi = I to ``rtol`` (mass-normalised modes)."""
    G = Phi.T @ (M @ Phi)
    err = float(np.abs(G - np.eye(G.shape[0])).max()) if G.size else 0.0
    if not err <= rtol:
        raise BasisError(f"{what} are not M-orthonormal: max |Phi^T M Phi - I| = {err:.3e} > {rtol:.0e}")


DEPENDENT_PIVOT = 1e3 * np.finfo(float).eps  # check_basis: a column's independent mass share below it


def check_basis(T: np.ndarray, Mr: np.ndarray, what: str) -> None:
    """Postcondition of a Ritz basis T (n, q) with reduced mass Mr = T^T M T: finite, and of full
    rank in the mass inner product (Mr positive definite: no two vectors move the same mass)."""
    if not np.all(np.isfinite(T)):
        raise BasisError(f"{what}: the basis holds a non-finite value")
    G = 0.5 * (Mr + Mr.T)
    try:
        L = sla.cholesky(G, lower=True)
        # a pivot over its column's own mass is the squared sine of the angle between that column
        # and the span of the ones before it: at round-off, the column is dependent whether or not
        # round-off left the pivot positive (it did for a repeated mode on an AMD EPYC's OpenBLAS)
        if G.size and not np.min(np.diag(L) ** 2 / np.diag(G)) > DEPENDENT_PIVOT:
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:
        w = np.linalg.eigvalsh(G)
        raise BasisError(f"{what}: the basis is rank deficient in the mass inner product (T^T M T has eigenvalue "
                         f"{w[0]:.3e} against {w[-1]:.3e}: dependent vectors)") from None


class Reduction(ABC):
    """What a reductor returns: a model the analyses solve through ``create_problem``, with the
    offline time and information of the reduction."""

    method: str
    offline_s: float
    info: dict

    @abstractmethod
    def create_problem(self, harmonics: Harmonics) -> Problem:
        """The HBM problem of this model (jointfem.hbm.problem protocol)."""

    @property
    @abstractmethod
    def basis(self) -> np.ndarray | None:
        """The Ritz basis T (n, q) with u = T z, or None where the unknowns are not Ritz
        coordinates (the exact condensation keeps only gaps and outputs)."""

    def reconstruct(self, Z: np.ndarray) -> np.ndarray:
        """Physical DOFs of reduced coordinates Z (..., q): Z T^T, shape (..., n)."""
        if self.basis is None:
            raise RomError(f"{self.method}: the unknowns are gaps and outputs, not Ritz coordinates: "
                           f"the physical DOFs cannot be reconstructed")
        return np.asarray(Z) @ self.basis.T


@dataclass
class ReducedModel(Reduction):
    """A Ritz reduction u = T z of a Structure (the penalty ROM adds its own internal variables).

    structure: the reduced model itself (a Structure in the coordinates z), which the HBM
    layer solves exactly like a physical one.  T: (n, q) basis, for recovery.
    """

    method: str
    structure: Structure
    T: np.ndarray
    full_size: int
    offline_s: float = 0.0
    info: dict = field(default_factory=dict)
    # a saddle-point model (the dual Craig-Bampton's multipliers and gaps): K_lin indefinite, M
    # singular, so its frequencies are the finite eigenvalues of the general pencil
    indefinite: bool = False

    @property
    def basis(self) -> np.ndarray:
        return self.T

    @property
    def size(self) -> int:
        return self.structure.num_dofs

    def create_problem(self, harmonics: Harmonics) -> Problem:
        return ForcedProblem(self.structure, harmonics, self.T, no_stability=(
            f"{self.method} is a saddle point (indefinite K, singular M) whose spurious modes of negative w^2 "
            f"are unstable Floquet exponents of no physical meaning" if self.indefinite else None))

    def natural_frequencies(self, num: int) -> np.ndarray:
        """The lowest ``num`` stuck natural frequencies of the ROM, rad/s."""
        s = self.structure
        if self.indefinite:
            # (as many as it has: with m modes and J multipliers, the DCB can have fewer than m + J)
            w, negative = finite_frequencies(s.K_lin, s.M, num, what=f"{self.method} ROM", at_most=True)
            # w^2 < 0: the spurious modes of an indefinite reduction (Rixen 2004), and how far out they lie
            self.info["spurious_modes"] = int(negative.size)
            self.info["spurious_lowest_rad_s"] = float(np.sqrt(-negative[-1])) if negative.size else None
            return w
        # MacNeal's reduced mass has the rank of its modes: no more finite frequencies than that
        rank = np.linalg.matrix_rank(s.M.toarray())
        w2, _ = eigen(s.K_lin, s.M, min(num, rank), what=f"{self.method} ROM")
        return np.sqrt(np.clip(w2, 0.0, None))


def project(structure: Structure, T: np.ndarray, method: str, *, M_override: np.ndarray | None = None,
            info: dict | None = None) -> ReducedModel:
    """Galerkin projection of a Structure on the basis T (n, q); contact gaps become G T."""
    T = np.asarray(T, dtype=float)

    def pr(A):
        return sp.csr_matrix(T.T @ (A @ T))

    Mr = pr(structure.M)
    check_basis(T, Mr.toarray(), f"{method} basis")

    contacts = tuple(ContactGroup(g.pairs, sp.csr_matrix(g.gap @ T), names=g.names, coords=g.coords,
                                  areas=g.areas)
                     for g in structure.contacts)
    outputs = {name: T[dof].copy() for name, dof in structure.outputs.items()}
    M = Mr if M_override is None else sp.csr_matrix(M_override)
    red = Structure(K=pr(structure.K), M=M, D=pr(structure.D), fc=T.T @ structure.fc, fs=T.T @ structure.fs,
                    contacts=contacts, dof_names=tuple(f"{method}.{i}" for i in range(T.shape[1])),
                    outputs=outputs, info={"kind": f"rom:{method}", "full_dofs": structure.num_dofs},
                    f0=None if structure.f0 is None else T.T @ structure.f0)
    return ReducedModel(method, red, T, structure.num_dofs, info=dict(info or {}))


@dataclass
class ExactModel(Reduction):
    """``--method exact``: the full model, solved by exact harmonic condensation on the contact
    gaps and outputs (jointfem.hbm.condensed): not a truncation, the full model's solution."""

    full: Structure
    offline_s: float = 0.0
    info: dict = field(default_factory=dict)
    method = "exact"
    # the modal path's eigendecomposition (hbm.condensed.modal_basis), computed once here, offline,
    # and shared by every problem created: None computes it where it can be taken, False (or None
    # where it cannot) keeps a sparse factorisation per harmonic and omega
    modal: "ModalBasis | bool | None" = field(default=None, repr=False)
    # that sparse path (CondensedProblem's ``sparse``): "schur", "lu", or None ("schur" where MUMPS
    # can be called directly)
    sparse: str | None = field(default=None, repr=False)

    def __post_init__(self):
        if self.modal is None:
            self.modal = modal_basis(self.full) or False
        if self.modal is not False:
            path = "modal"
        elif self.sparse is None:
            path = "schur" if bordered_unavailable() is None else "lu"
        else:
            path = self.sparse
        self.info.setdefault("condensation", path)

    @property
    def basis(self) -> None:
        return None

    @property
    def size(self) -> int:
        """Retained coordinates: every gap component and every output."""
        return sum(g.gap.shape[0] for g in self.full.contacts) + len(self.full.outputs)

    def create_problem(self, harmonics: Harmonics) -> Problem:
        return CondensedProblem(self.full, harmonics, modal=self.modal, sparse=self.sparse)
