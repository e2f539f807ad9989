"""The forced response of a Structure: a physical model, or the Galerkin projection of one (CMS,
tvd), as a :class:`~jointfem.hbm.problem.Problem` with lam = omega (rad/s)."""
from __future__ import annotations

import numpy as np

from ..harmonics import Harmonics
from ..linalg import RowBlocks
from ..models.structure import Structure
from .problem import Evaluation, Layout, PointRecord, Problem, Scales, contact_records, count_exponents, force_scale
from .residual import HBMResidual


def compute_scales(structure: Structure, omega_start: float, omega_end: float, *, num: int = 201) -> np.ndarray:
    """Per-DOF displacement scale: the largest stuck linear amplitude over the range, m.

    DOFs that barely move linearly (rotations, constrained directions) get a floor of
    1e-6 of the largest, so that every unknown is O(1) in the continuation.
    """
    w = np.linspace(min(omega_start, omega_end), max(omega_start, omega_end), num)
    X = np.abs(structure.linear_response(w)).max(axis=0)
    top = X.max()
    if not np.isfinite(top) or top <= 0:
        top = 1.0
    return np.maximum(X, 1e-6 * top)


def compute_rom_scales(structure: Structure, T: "np.ndarray | RowBlocks", omega_start: float, omega_end: float, *,
                       num: int = 101, displacements: int = 0) -> np.ndarray:
    """Scale per ROM coordinate: its stuck linear amplitude, but at least the amplitude at which
    its basis vector alone reaches the largest linear displacement of the structure.

    A mode far from the range barely moves linearly, yet a joint that slips or opens excites it
    to displacements of the size of the response: scaled by its linear amplitude alone, it
    would dominate the arclength and shrink every step.
    The last ``displacements`` columns of T are coordinates that are displacements themselves and
    not coordinates of ``structure`` (the penalty ROM's internal variables p, inactive in its stuck
    structure): their scale is the largest displacement.
    """
    T = T if isinstance(T, RowBlocks) else RowBlocks(np.asarray(T), np.shape(T)[0])
    w = np.linspace(min(omega_start, omega_end), max(omega_start, omega_end), num)
    q = T.num_cols - displacements
    X = np.abs(structure.linear_response(w))  # (num, q)
    top = T.max_abs_product(X, q)
    if not np.isfinite(top) or top <= 0:
        top = 1.0
    col = T.col_max(q)
    zs = np.maximum(X.max(axis=0), top / np.where(col > 0, col, 1.0))
    return np.concatenate([zs, np.full(displacements, top)])


class ForcedProblem(Problem):
    """HBM of a Structure under its harmonic force.  ``basis``: the Ritz basis T (n, q) of a
    Galerkin projection (scales per ROM coordinate), None for a physical model.  ``no_stability``:
    why the model's Floquet exponents are not the physical ones (the dual Craig-Bampton's saddle
    point, whose spurious modes of negative w^2 are unstable exponents), None where they are."""

    def __init__(self, structure: Structure, harmonics: Harmonics, basis: np.ndarray | None = None, *,
                 no_stability: str | None = None):
        self.structure, self.harmonics, self.basis = structure, harmonics, basis
        self.no_stability = no_stability
        self.hbm = HBMResidual(structure, harmonics)
        self._num_dynamic = None
        self.layout = Layout(structure.num_dofs, structure.dof_names, dict(structure.outputs),
                             structure.pair_names, structure.pair_coords, structure.pair_areas)

    @property
    def num_unknowns(self) -> int:
        return self.hbm.num_unknowns

    def evaluate(self, x, lam, *, jacobian=True) -> Evaluation:
        return self.hbm.evaluate(x, lam, jacobian=jacobian)

    def initial_guess(self, lam):
        return self.hbm.linear_solution(lam)

    def scales(self, lam_start, lam_end) -> Scales:
        if self.basis is not None:
            per = compute_rom_scales(self.structure, self.basis, lam_start, lam_end)
        else:
            per = compute_scales(self.structure, lam_start, lam_end)
        return Scales.from_coordinates(per, self.harmonics, force_scale(self.structure))

    def hill_operators(self, lam):
        return self.hbm.hill_operators(lam)

    def floquet_correction(self, x, lam, evaluation):
        return self.hbm.floquet_correction(lam, evaluation.contact)

    def num_dynamic(self) -> int:
        if self._num_dynamic is None:
            self._num_dynamic = count_exponents(self.structure.M, self.structure.D)
        return self._num_dynamic

    def record(self, x, lam, evaluation) -> PointRecord:
        states, summary = contact_records(self.harmonics, [g.pairs for g in self.structure.contacts],
                                          evaluation.contact)
        return PointRecord(states, self.structure.num_dofs, summary)
