"""The problem protocol: what every solved problem offers the analyses, defined once.

A problem is a residual ``R(x, lam) = 0`` in harmonic coefficients ``x`` and one parameter
``lam`` (omega in rad/s for a forced response), with everything an analysis needs around it:

* ``num_coefficients``: the length of ``x`` (``layout.num_coords`` per harmonic block), the same
  at every point of a branch, so that branches, peaks and resumed runs store one array;
* ``unknowns()``: which coefficients are solved now (an index array; None: all of them).  The
  others are zero, held there by the problem's equations (the penalty ROM's inactive internal
  variables), and take no part in Newton;
* ``num_unknowns``: how many are solved now: the size of the system Newton solves;
* ``evaluate(x, lam, *, jacobian)`` -> :class:`Evaluation` (R, dR/dx, dR/dlam, contact results),
  x being every coefficient and R, the Jacobian and dR/dlam being those of the unknowns;
* ``initial_guess(lam)``: where the continuation starts (refined by Newton);
* ``scales(lam_start, lam_end)`` -> :class:`Scales` (per unknown, and the residual's);
* ``record(x, lam, evaluation)`` -> :class:`PointRecord`: the named data kept per point;
* ``layout``: what the coordinates are (:class:`Layout`: names, outputs, pairs), for the results;
* ``adaptation``: None, or the hooks of a problem whose equations and unknowns change along the
  branch (:class:`jointfem.continuation.arclength.Adaptive`; the penalty ROM's active set);
* ``tol_floor``: a Newton tolerance below which this problem's round-off makes no progress;
* ``branch_info()``: data of the whole branch (e.g. the active-set events);
* ``hill_operators(lam)`` and ``num_dynamic()``: what Hill's method needs for the stability of a
  point (analysis.stability), None where it does not apply; ``hill_matrices(x, lam, evaluation)``
  puts them together with the Jacobian (by default the point's own), and ``hill_size`` is the size of
  that Jacobian, which the automatic stability limit compares (the exact condensation, whose dynamic
  stiffness is not polynomial in the exponent, answers with the full model's, at its point);
* ``floquet_correction(x, lam, evaluation)``: what Hill's matrix lacks where a contact law remembers
  its past (None where not known);
* ``no_stability``: None, or why no stability is computed for this problem's points.

Implementations: :class:`jointfem.hbm.forced.ForcedProblem` (a Structure, physical or a Galerkin
projection), :class:`jointfem.hbm.condensed.CondensedProblem` (exact condensation on the gaps)
and :class:`jointfem.rom.penalty.PenaltyProblem`.  The analyses (jointfem.analysis) drive any of
them and never ask an object what it has.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..contact.law import ContactResult
from ..continuation.arclength import Adaptive
from ..harmonics import Harmonics


@dataclass
class Evaluation:
    """One evaluation of a problem at (x, lam)."""

    R: np.ndarray  # residual, N (the problem's own units)
    J: sp.csr_matrix | np.ndarray | None  # dR/dx (dense for a small dense model); None if not asked
    dR_dlam: np.ndarray | None  # dR/dlam (N s/rad for lam = omega); None if not asked
    contact: list[ContactResult]  # one AFT result per contact group


@dataclass
class PointRecord:
    """What is kept of one converged point, by name.

    states: (N, num_pairs) int8, the contact state per time sample and physical pair.
    size: the model's size at the point (for the penalty ROM: modes + TVDs + active components).
    unknowns: the number of unknowns Newton solved at the point (size x (2H + 1) for an HBM of a
    model; set by the analysis that solved it).
    pair_summary: (num_pairs, 3): dissipated energy per cycle (J), tangential amplitude (m), peak
    normal force (N), per physical pair (ContactLaw.summary).
    active: the penalty ROM's active components (num_components,) bool, else None.
    stability, harmonic_error: room for the leading Floquet exponent (the largest real part; complex,
    1/s) and for the harmonic truncation error estimate (None until an analysis computes them);
    stability_method: how the exponent was made (analysis.stability.HILL or HILL_MEMORY).
    harmonics: the H the point was solved at (set by the analysis; a branch whose H changes along it,
    analysis.adaptive); harmonics_enough: the smallest H the point's forces predict would do
    (analysis.adaptive.enough_harmonics).
    """

    states: np.ndarray
    size: int
    pair_summary: np.ndarray
    active: np.ndarray | None = None
    unknowns: int = 0
    stability: complex | None = None
    harmonic_error: float | None = None
    harmonics: int = 0
    harmonics_enough: int | None = None
    stability_method: str | None = None


@dataclass(frozen=True)
class Scales:
    """x: scale per unknown (num_unknowns,); r: residual scale (N).  The continuation works on
    x / x and R / r, so that one step length means the same on every unknown."""

    x: np.ndarray
    r: float

    @classmethod
    def from_coordinates(cls, per_coordinate: np.ndarray, harmonics: Harmonics, r: float) -> "Scales":
        """The same scale for every harmonic of a coordinate, times sqrt(q): a response of the size
        of the largest linear one has a scaled norm of about 1."""
        q = per_coordinate.size
        return cls(np.tile(per_coordinate, harmonics.num_hc) * np.sqrt(q), r)


def force_scale(structure) -> float:
    """Residual scale of a forced Structure: its largest external force component, N."""
    return float(max(np.abs(np.concatenate([structure.fc, structure.fs, structure.f_static])).max(), 1e-300))


@dataclass(frozen=True)
class Layout:
    """What the solved coordinates are (per harmonic block), for results and pictures.

    num_coords: coordinates per harmonic block.  outputs: name -> coordinate index, or a recovery
    row (num_coords,) from the coordinates.  pair_names, pair_coords, pair_areas: the physical pairs
    (positions (P, 3) in m, contact areas (P,) in m^2, None where unknown).
    """

    num_coords: int
    dof_names: tuple = ()
    outputs: dict = field(default_factory=dict)
    pair_names: tuple = ()
    pair_coords: np.ndarray | None = None
    pair_areas: np.ndarray | None = None


class Problem(ABC):
    """The protocol (see the module docstring).  Subclasses set ``harmonics`` and ``layout``."""

    harmonics: Harmonics
    layout: Layout
    adaptation: Adaptive | None = None
    tol_floor: float = 0.0
    no_stability: str | None = None  # why the points' Floquet exponents are not computed (None: they are)
    # None, or why a sweep's default ("auto") leaves the stability out although it can compute it
    # (--stability on computes it): where Hill's problem is far larger than the one Newton solves
    stability_not_by_default: str | None = None

    @property
    def num_coefficients(self) -> int:
        """The length of x: every coefficient of the layout, solved or not."""
        return self.layout.num_coords * self.harmonics.num_hc

    def unknowns(self) -> np.ndarray | None:
        """The coefficients solved now (None: every one; an adaptive problem's change)."""
        return None

    @property
    def num_unknowns(self) -> int:
        """The size of the system Newton solves now."""
        sel = self.unknowns()
        return self.num_coefficients if sel is None else int(sel.size)

    @abstractmethod
    def evaluate(self, x: np.ndarray, lam: float, *, jacobian: bool = True) -> Evaluation:
        ...

    @abstractmethod
    def initial_guess(self, lam: float) -> np.ndarray:
        ...

    @abstractmethod
    def scales(self, lam_start: float, lam_end: float) -> Scales:
        ...

    @abstractmethod
    def record(self, x: np.ndarray, lam: float, evaluation: Evaluation) -> PointRecord:
        ...

    def branch_info(self) -> dict:
        """Data of the whole branch, for the results' info (none by default)."""
        return {}

    def hill_operators(self, lam: float):
        """(Delta1, Delta2) with which J + s Delta1 + s^2 Delta2 is the Hill matrix of a Floquet
        exponent s (analysis.stability), or None where the residual is not polynomial in the time
        derivative (the exact condensation's dynamic stiffness): then no stability is computed."""
        return None

    def num_dynamic(self) -> int | None:
        """The number of Floquet exponents of a point: 2 per coordinate with mass, 1 per massless
        coordinate with damping (None where hill_operators is None)."""
        return None

    def hill_matrices(self, x: np.ndarray, lam: float, evaluation: Evaluation):
        """(J, Delta1, Delta2, num) of Hill's problem (J + s Delta1 + s^2 Delta2) v = 0 at the point x
        (``evaluation``: this problem's at x, with its Jacobian), or None where there is none.  By
        default the point's own Jacobian with ``hill_operators`` and ``num_dynamic``."""
        ops = self.hill_operators(lam)
        if ops is None or evaluation.J is None:
            return None
        return evaluation.J, ops[0], ops[1], self.num_dynamic()

    def floquet_correction(self, x: np.ndarray, lam: float, evaluation: Evaluation):
        """None, or ``s -> (dJ(s), dJ'(s))`` (complex, dense or sparse as the Jacobian of
        ``hill_matrices``): what Hill's matrix J + s Delta1 + s^2 Delta2 lacks for a perturbation
        e^{s t} v where a contact law remembers its past (a stuck slider: its force depends on the gap
        at its stick onset, e^{-s tau} earlier; contact.law.ContactLaw.floquet_jacobian), and its
        derivative in s.  None, or a function answering None, where it is not known: Hill's matrix is
        then taken as it is."""
        return None

    @property
    def hill_size(self) -> int:
        """The number of rows of the Jacobian of ``hill_matrices`` (what Hill's method costs)."""
        return self.num_coefficients


def newton_system(problem: Problem):
    """``(x, lam) -> (R, dR/dx, dR/dlam)`` of a problem: what ``solve_newton`` and the
    continuation take."""
    def fun(x, lam):
        ev = problem.evaluate(x, lam, jacobian=True)
        return ev.R, ev.J, ev.dR_dlam
    return fun


class KeepsLastEvaluation:
    """``evaluate`` returns the last evaluation again for the same (x, lam): the continuation
    evaluates an accepted point again for its tangent, its record and the penalty ROM's active
    set, and the AFT need not run twice.  Subclasses implement ``_evaluate``."""

    _last = None  # (key, Evaluation)

    def evaluate(self, x: np.ndarray, lam: float, *, jacobian: bool = True) -> Evaluation:
        key = (float(lam), x.tobytes())
        last = self._last
        if last is not None and last[0] == key and (last[1].J is not None or not jacobian):
            return last[1]
        ev = self._evaluate(x, lam, jacobian)
        self._last = (key, ev)
        return ev


COUNT_DENSE = 500  # up to this many coordinates the rank of M is taken from a dense SVD


def count_exponents(M, D) -> int:
    """Floquet exponents of M u'' + D u' + ...: two per coordinate with mass (rank M), one per
    massless direction with damping (rank of D on the null space of M).  A sparse M (semi-definite,
    as a model's is) above COUNT_DENSE coordinates without a zero on its diagonal is first tested
    for a null space by the inertia of a sparse LDL^T of M - 1e-12 |M| I (linalg.eigenvalues_below,
    the dense SVD's threshold): a continuum's consistent mass has none, and a dense SVD of its 10k
    DOFs takes minutes, during which no signal is handled."""
    n = M.shape[0]
    if sp.issparse(M) and n > COUNT_DENSE and np.all(M.diagonal() > 0):
        from ..linalg import eigenvalues_below

        gershgorin = float(abs(M).sum(axis=1).max())  # >= its largest eigenvalue
        if eigenvalues_below(M, 1e-12 * gershgorin) == 0:
            return 2 * n
    Md = np.asarray(M.toarray() if sp.issparse(M) else M, dtype=float)
    Dd = np.asarray(D.toarray() if sp.issparse(D) else D, dtype=float)
    if not Md.size:
        return 0
    U, sv, _ = np.linalg.svd(Md)
    r = int(np.count_nonzero(sv > 1e-12 * sv.max())) if sv.max() > 0 else 0
    N = U[:, r:]
    rd = 0
    if N.shape[1]:
        Dn = N.T @ Dd @ N
        sd = np.linalg.svd(Dn, compute_uv=False)
        rd = int(np.count_nonzero(sd > 1e-12 * max(np.abs(Dd).max(), 1e-300)))
    return 2 * r + rd


def contact_records(harmonics: Harmonics, laws, contact: list[ContactResult]) -> tuple[np.ndarray, np.ndarray]:
    """States (N, P) and pair summaries (P, 3) of the contact results of groups with ``laws``."""
    if not contact:
        return np.zeros((harmonics.N, 0), dtype=np.int8), np.zeros((0, 3))
    return (np.concatenate([c.state_t for c in contact], axis=1),
            np.concatenate([law.summary(c.f_t, c.g_t) for c, law in zip(contact, laws)]))
