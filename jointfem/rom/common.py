"""What every reduction shares: options, the reduced model, and dispatch by method name."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..linalg import eigen
from ..models.structure import ContactGroup, Structure

METHODS = ("full", "exact", "cb", "rubin", "macneal", "dcb", "jim", "tvd", "penalty")


class RomError(ValueError):
    """A reduction cannot be built for this model (names the method and the reason)."""


@dataclass(frozen=True)
class RomOptions:
    modes: int = 20  # vibration modes: global (penalty, tvd) or in total over the substructures (CMS)
    tvd: int = 0  # POD-compressed trial-vector derivatives (penalty, tvd)
    interface_modes: int | None = None  # JIM: characteristic interface modes (default: half the boundary DOFs)
    release_after: int = 2  # penalty: converged points a pair must stay stuck before it leaves the active set


@dataclass
class ReducedModel:
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

    @property
    def size(self) -> int:
        return self.structure.num_dofs

    def natural_frequencies(self, num: int) -> np.ndarray:
        """The lowest ``num`` stuck natural frequencies of the ROM, rad/s."""
        s = self.structure
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

    contacts = tuple(ContactGroup(g.pairs, sp.csr_matrix(g.gap @ T), names=g.names, coords=g.coords)
                     for g in structure.contacts)
    outputs = {name: T[dof].copy() for name, dof in structure.outputs.items()}
    M = pr(structure.M) if M_override is None else sp.csr_matrix(M_override)
    red = Structure(K=pr(structure.K), M=M, D=pr(structure.D), fc=T.T @ structure.fc, fs=T.T @ structure.fs,
                    contacts=contacts, dof_names=tuple(f"{method}.{i}" for i in range(T.shape[1])),
                    outputs=outputs, info={"kind": f"rom:{method}", "full_dofs": structure.num_dofs})
    return ReducedModel(method, red, T, structure.num_dofs, info=dict(info or {}))


@dataclass
class ExactModel:
    """Marker for ``--method exact``: the full model, solved by exact harmonic condensation."""

    full: Structure
    offline_s: float = 0.0
    info: dict = field(default_factory=dict)


def build_rom(structure: Structure, method: str, options: RomOptions = RomOptions()):
    """Build the ROM of ``method`` (one of METHODS but 'full').  Records the offline seconds."""
    from . import cms, penalty

    if method == "exact":  # not a reduction: the exact condensation on the gaps (jointfem.hbm.condensed)
        return ExactModel(structure)
    builders = {"cb": cms.craig_bampton, "rubin": cms.rubin, "macneal": cms.macneal, "dcb": cms.dual_craig_bampton,
                "jim": cms.joint_interface_modes, "tvd": cms.tvd_method, "penalty": penalty.PenaltyROM}
    if method not in builders:
        raise RomError(f"unknown reduction method {method!r}; choose one of {', '.join(METHODS[1:])}")
    if options.modes < 0 or options.tvd < 0:
        raise RomError(f"{method}: modes = {options.modes} and tvd = {options.tvd} must be >= 0")
    t0 = time.perf_counter()
    rom = builders[method](structure, options)
    rom.offline_s = time.perf_counter() - t0
    return rom
