"""The paper's penalty ROM (Sec. 3, Eq. 7-14) with an adaptive active set (Sec. 4).

Formulation (docs/theory.md, "Penalty ROM").  With the gaps g = G u of all contact
components and their stiffnesses Kc, write the contact force as f(g) = f0 + Kc (g - p).
The internal variable p is then 0 for a component that sticks the whole period from the
unloaded position, the slider position for a slipping tangential component, and what
makes the force vanish for a separated one.  The full model
    M u'' + D u' + K u + G^T (f(G u) - f0) = F
is exactly the augmented system (paper Eq. 9)
    M u'' + D u' + K_lin u - G^T Kc p          = F          (u rows)
    -Kc G u + Kc p + (f(G u) - f0)             = 0          (p rows: consistency)
with K_lin = K + G^T Kc G.  Its Galerkin projection on
    u = Phi eta + V xi + Psi p,   Psi = K_lin^-1 G^T Kc   (static modes, Eq. 11),
with Phi the stuck vibration modes, V POD-compressed trial-vector derivatives (Eq. 12)
and p itself as the last coordinates (T = [[Phi, V, Psi], [0, 0, I]], Eq. 13-14), keeps
only the components of the active set A: the others are 0 and their rows are dropped
(the index matrix B).  With every mode kept, T is square and invertible, so the ROM is
the full model (tests/test_rom.py checks separated solutions to 1e-8).

Because Psi is K_lin-orthogonal to the modes, the reduced stiffness is block diagonal:
diag(Phi^T K_lin Phi, Kc - Kc G Psi) in (eta, p).

Adaptive size: the active set is taken at each predictor from the last converged point
(components that slipped or separated there, or whose stuck state the linear spring could not
hold, or that did within the last ``release_after`` points: hysteresis); after each corrector every inactive component is
checked against the friction law with its linear force; any violation enlarges the set and
the step is redone (continuation's ``adapt`` hook).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp

from ..continuation.arclength import Adaptive
from ..harmonics import Harmonics
from ..hbm.forced import compute_rom_scales
from ..hbm.problem import Evaluation, Layout, PointRecord, Problem, Scales, count_exponents, force_scale
from ..hbm.residual import HBMResidual
from ..linalg import (Factorized, LinAlgError, RowBlocks, allreduce, direct_factor, eigen, eigen_rows, gram,
                      solve_rows)
from ..models.structure import ContactGroup, Structure, pair_names, per_pair
from .cms import trial_vector_derivatives
from .common import ReducedModel, RomError, RomOptions, check_modes


def _keep_recent(cache: dict, key, value, kept: int):
    """Store ``value`` under ``key`` as the most recent entry of ``cache`` (dicts keep insertion
    order; a hit is popped by the caller first), drop the oldest beyond ``kept``, return ``value``."""
    cache[key] = value
    while len(cache) > kept:
        cache.pop(next(iter(cache)))
    return value


@dataclass
class _Group:
    """Bookkeeping of one physical contact group inside the ROM."""

    group: ContactGroup
    first: int  # index of its first component among all J components
    Gr: np.ndarray  # (P*m, q): gaps from the ROM coordinates


@dataclass
class PenaltyData:
    """What the offline stage hands the penalty ROM: reduced matrices and single rows only, and the
    basis T = [Phi, V, Psi] (n, q) for recovery, replicated or in row blocks (distributed)."""

    K_lin: np.ndarray  # T^T K_lin T (q, q)
    M: np.ndarray  # T^T M T
    D: np.ndarray  # T^T D T
    GT: np.ndarray  # (J, q): the gaps of every basis vector
    kc: np.ndarray  # (J,): the stuck stiffness of every contact component
    fc: np.ndarray  # (q,): T^T fc
    fs: np.ndarray
    f0: np.ndarray | None
    outputs: dict  # name -> (q,): the output's row of T
    basis: RowBlocks
    num_modes: int
    num_tvd: int
    tvd_singular_values: np.ndarray
    timings: dict = field(default_factory=dict)  # s per offline stage (the distributed one records them)


def _stuck_springs(kc: np.ndarray, what: str) -> None:
    if np.any(kc <= 0):
        raise RomError(f"{what}: {int(np.sum(kc <= 0))} contact components have no stuck stiffness (a cubic "
                       "spring): the penalty ROM's internal variables need a stuck spring; use tvd, cb, exact or "
                       "full order")


def _offline_replicated(structure: Structure, options: RomOptions) -> PenaltyData:
    """Modes, TVDs and static modes of a Structure held whole on this rank (closed at rest)."""
    Kl = structure.K_lin
    w2, Phi = eigen(Kl, structure.M, options.modes, what="penalty: stuck structure")
    check_modes(Phi, structure.M, "penalty: the stuck vibration modes")
    if options.tvd and options.tvd_kind == "eq12":
        raise RomError("penalty: the paper's TVDs (tvd_kind = 'eq12', Eq. 12) are combinations of the static "
                       "modes, K_lin^-1 dK_lin/dq_j b_i = sum_c (g_c b_i)(g_c b_j) psi_c / l, because each contact "
                       "spring's stiffness change has rank one; this ROM already holds the static mode of every "
                       "active component, so they add nothing, and make it singular once every component is "
                       "active (docs/theory.md, TVDs); use tvd_kind = 'eigen' here, or the tvd method")
    V, sv = trial_vector_derivatives(structure, Phi, w2, options.tvd, kind=options.tvd_kind)
    G = sp.vstack([g.gap for g in structure.contacts]).tocsr()
    kc = np.concatenate([g.pairs.stiffness.ravel() for g in structure.contacts])
    _stuck_springs(kc, "penalty")
    try:
        Psi = Factorized(Kl, what="penalty: K_lin").solve(G.T.toarray() * kc)  # (n, J)
    except LinAlgError as exc:
        raise RomError(str(exc)) from exc
    Tu = np.hstack([Phi, V, Psi])
    return PenaltyData(Tu.T @ (Kl @ Tu), Tu.T @ (structure.M @ Tu), Tu.T @ (structure.D @ Tu), G @ Tu, kc,
                       Tu.T @ structure.fc, Tu.T @ structure.fs, None if structure.f0 is None else Tu.T @ structure.f0,
                       {nm: Tu[dof].copy() for nm, dof in structure.outputs.items()},
                       RowBlocks(Tu, Tu.shape[0]), Phi.shape[1], V.shape[1], sv)


def _offline_distributed(model, options: RomOptions) -> PenaltyData:
    """The same from a jointed continuum kept distributed (jointfem.fem.distributed.DistributedModel):
    the modes and static modes stay in the rows each rank owns, and only the reduced matrices, the
    gap rows (J, q) and the force and output rows cross the ranks (linalg.gram, allreduce)."""
    if options.tvd:
        raise RomError("penalty: the distributed offline stage has no trial-vector derivatives yet (tvd = 0)")
    comm = model.comm
    kc = model.pairs.stiffness.ravel()
    _stuck_springs(kc, "penalty")
    t0 = time.perf_counter()
    factor = None
    try:
        # K_lin factorised once, by MUMPS called directly where it can be, for both the shift-invert
        # of the modes and the static modes (None: each makes its own through PETSc)
        factor = direct_factor(model.K_lin, what="penalty: K_lin")
        w2, Phi = eigen_rows(model.K_lin, model.M, options.modes, what="penalty: stuck structure", comm=comm,
                             factor=factor)
        m = Phi.num_cols
        check_modes(np.eye(m), gram(model.M, Phi), "penalty: the stuck vibration modes")
        # Fortran order: each block of static modes is written, and later read, as contiguous columns
        T = RowBlocks(np.empty((Phi.local.shape[0], m + kc.size), order="F"), model.n, Phi.offset, comm)
        T.local[:, :m] = Phi.local
        del Phi
        t1 = time.perf_counter()
        solve_rows(model.K_lin, sp.csr_matrix(model.gap_local.T) @ sp.diags(kc), what="penalty: K_lin", comm=comm,
                   out=T.local[:, m:], factor=factor, direct=factor is not None)  # no second attempt
    except LinAlgError as exc:
        raise RomError(str(exc)) from exc
    finally:
        if factor is not None:
            factor.destroy()
    t2 = time.perf_counter()
    # T^T K_lin T without a product over the n rows but the modes': K_lin Psi = G^T Kc, so the
    # blocks that hold Psi are gap rows, Phi^T G^T Kc and Psi^T G^T Kc = (G Psi)^T Kc
    # G T from the rows G reads (the interface's): a sparse product with the whole Fortran-order
    # T.local would copy it to row-major first (scipy ravels its dense operand)
    G = sp.csr_matrix(model.gap_local)
    used = np.unique(G.indices)
    GT = allreduce(comm, G[:, used] @ T.local[used])
    Kl = np.zeros((T.num_cols, T.num_cols))
    Kl[:m, :m] = gram(model.K_lin, T, cols=m)
    Kl[:, m:] = GT.T * kc
    Kl[m:, :m] = Kl[:m, m:].T
    Kl = 0.5 * (Kl + Kl.T)
    Mr = gram(model.M, T)
    alpha, beta = model.rayleigh
    Dr = alpha * Mr + beta * (Kl - GT.T @ (kc[:, None] * GT))  # T^T K T: K_lin without the stuck springs
    row, amplitude = model.force
    names = list(model.outputs)
    rows = T.rows(np.array([row] + [model.outputs[nm] for nm in names], dtype=np.int64))
    # eigen_s includes the factorisation of K_lin, which the static modes reuse
    timings = {"eigen_s": t1 - t0, "static_s": t2 - t1, "projection_s": time.perf_counter() - t2}
    return PenaltyData(Kl, Mr, Dr, GT, kc, amplitude * rows[0], np.zeros(T.num_cols), None,
                       dict(zip(names, rows[1:])), T, m, 0, np.zeros(0), timings)


class PenaltyROM(ReducedModel):
    """The offline part: modes, TVDs, static modes and the augmented reduced matrices.

    ``structure``: the full model, replicated; or None with ``distributed``, a jointed continuum
    kept distributed (jointfem.fem.distributed), whose n-sized data never leave their ranks."""

    STRUCTURES_KEPT = 16  # reduced Structures kept for the most recent active sets

    def __init__(self, structure: Structure | None, options: RomOptions, *, distributed=None):
        self.options = options
        if distributed is not None:
            data = _offline_distributed(distributed, options)
            n = distributed.num_dofs
            physical = (ContactGroup(distributed.pairs, sp.csr_matrix(data.GT), names=distributed.names,
                                     coords=distributed.coords, areas=distributed.areas),)
        else:
            if not structure.contacts:
                raise RomError("penalty: the model has no contact pairs")
            n = structure.num_dofs
            physical = structure.contacts
            # a pair open at rest (an initial gap, N0 < 0) has no stuck stiffness, but the augmented
            # system is exact for any Kc > 0: its basis and Kc take the pair as if closed at rest, and
            # the pair stays active (JenkinsPairs.linear_breaks), so its p carries its real force
            data = _offline_replicated(replace(structure, contacts=tuple(
                replace(g, pairs=g.pairs.closed_at_rest()) for g in structure.contacts)), options)
        self.num_modes, self.num_tvd, kc, GT = data.num_modes, data.num_tvd, data.kc, data.GT
        self.num_comp = kc.size
        q = data.K_lin.shape[0]
        self.p_slots = np.arange(q - kc.size, q)
        S = np.zeros((kc.size, q))
        S[:, self.p_slots] = np.eye(kc.size)
        KcGT = kc[:, None] * GT
        self.K = data.K_lin - GT.T @ (kc[:, None] * S) - S.T @ KcGT + S.T @ (kc[:, None] * S)
        self.K = 0.5 * (self.K + self.K.T)
        self.M, self.D, self.kc = data.M, data.D, kc
        self.forces = (data.fc, data.fs, data.f0)
        self.output_rows = data.outputs
        self.rows = data.basis  # the basis T (n, q), replicated or in row blocks
        self.groups, first = [], 0
        for g in physical:  # the laws as they are (open pairs open)
            m_rows = g.pairs.num_pairs * g.pairs.num_comp
            self.groups.append(_Group(g, first, GT[first:first + m_rows]))
            first += m_rows
        self.pair_names = pair_names(physical)
        self.pair_coords, self.pair_areas = per_pair(physical, "coords"), per_pair(physical, "areas")
        self._cache: dict[bytes, Structure] = {}
        stuck = self.structure_for(np.zeros(kc.size, bool))
        T = data.basis.local if data.basis.comm is None else None
        super().__init__("penalty", stuck, T, n, info={"modes": self.num_modes, "tvd": self.num_tvd,
                                                        "static_modes_available": int(kc.size),
                                                        "offline": "replicated" if T is not None else "distributed",
                                                        "offline_timings": data.timings,
                                                        "tvd_singular_values": data.tvd_singular_values[:10].tolist()})

    def reconstruct(self, Z: np.ndarray) -> np.ndarray:
        if self.T is None:
            raise RomError("penalty: the basis stays in row blocks on the ranks (the distributed offline stage): "
                           "the physical DOFs are not gathered; the outputs and the contact gaps are")
        return super().reconstruct(Z)

    # --- the ROM for one active set -------------------------------------------------------
    @property
    def size(self) -> int:
        """Size with no active internal variable (all stuck): modes + TVDs."""
        return self.num_modes + self.num_tvd

    def size_of(self, mask: np.ndarray) -> int:
        return self.num_modes + self.num_tvd + int(np.count_nonzero(mask))

    def coordinates(self, mask: np.ndarray) -> np.ndarray:
        """The ROM coordinates kept with active components ``mask`` (J,): the modes, the TVDs and
        the internal variables of the active components (the others are zero, and not unknowns)."""
        return np.concatenate([np.arange(self.num_modes + self.num_tvd), self.p_slots[np.asarray(mask, bool)]])

    def structure_for(self, mask: np.ndarray) -> Structure:
        """The reduced Structure of active components ``mask`` (J,): its coordinates are
        ``coordinates(mask)``, modes + TVDs + active components (paper Eq. 14, with the index
        matrix B keeping the active rows of p)."""
        key = np.asarray(mask, bool).tobytes()
        if key in self._cache:
            return _keep_recent(self._cache, key, self._cache.pop(key), self.STRUCTURES_KEPT)
        mask = np.asarray(mask, bool)
        keep = self.coordinates(mask)
        q = keep.size
        K, M, D = (A[np.ix_(keep, keep)] for A in (self.K, self.M, self.D))
        where = np.full(self.K.shape[0], -1)
        where[keep] = np.arange(q)  # position of a kept ROM coordinate in the reduced Structure
        contacts = []
        for gr in self.groups:
            g = gr.group
            P, m = g.pairs.num_pairs, g.pairs.num_comp
            act = np.asarray(mask[gr.first:gr.first + P * m], bool).reshape(P, m)
            sel = np.flatnonzero(act.any(axis=1))
            if sel.size == 0:
                continue
            rows = (sel[:, None] * m + np.arange(m)).ravel()
            load = np.zeros((rows.size, q))
            comp = gr.first + rows
            on = act[sel].ravel()
            load[np.flatnonzero(on), where[self.p_slots[comp[on]]]] = 1.0
            contacts.append(ContactGroup(g.pairs.subset(sel), sp.csr_matrix(gr.Gr[np.ix_(rows, keep)]),
                                         names=tuple(np.array(g.names)[sel]) if g.names else (),
                                         load=sp.csr_matrix(load)))
        fc, fs, f0 = self.forces
        s = Structure(K=sp.csr_matrix(K), M=sp.csr_matrix(M), D=sp.csr_matrix(D), fc=fc[keep], fs=fs[keep],
                      contacts=tuple(contacts), f0=None if f0 is None else f0[keep],
                      dof_names=tuple(f"penalty.{i}" for i in keep),
                      outputs={nm: row[keep] for nm, row in self.output_rows.items()},
                      info={"kind": "rom:penalty", "active": int(np.count_nonzero(mask))})
        return _keep_recent(self._cache, key, s, self.STRUCTURES_KEPT)

    def create_problem(self, harmonics: Harmonics) -> "PenaltyProblem":
        return PenaltyProblem(self, harmonics)

    def natural_frequencies(self, num: int) -> np.ndarray:
        """Stuck natural frequencies (no active component: modes and TVDs only), rad/s."""
        r = self.num_modes + self.num_tvd
        w2, _ = eigen(self.K[:r, :r], self.M[:r, :r], min(num, r), what="penalty ROM")
        return np.sqrt(np.clip(w2, 0.0, None))


@dataclass
class _Pair:
    """Where one physical pair's components live: group index, pair index, component range."""

    group: int
    pair: int
    comps: np.ndarray


class PenaltyProblem(Problem, Adaptive):
    """The online part: HBM of the penalty ROM whose active set follows the branch (it is its own
    ``adaptation``: the continuation's before_step/after_converge hooks)."""

    # residuals kept for the most recent active sets (a step refused, a peak search going back):
    # each holds its dense harmonic operators, 240 MB at 455 coordinates and H = 3 (the 221-pair
    # joint), and the active set changes at nearly every point there
    HBM_KEPT = 4

    def __init__(self, rom: PenaltyROM, harmonics: Harmonics, *, friction_tol: float = 1e-9):
        self.rom, self.harmonics = rom, harmonics
        self.adaptation = self
        self.q = rom.K.shape[0]
        self.layout = Layout(self.q, tuple(f"penalty.{i}" for i in range(self.q)),
                             {nm: row.copy() for nm, row in rom.output_rows.items()},
                             rom.pair_names, rom.pair_coords, rom.pair_areas)
        self.mask = np.zeros(rom.num_comp, bool)
        self.history: list[np.ndarray] = []  # per accepted point: components that slipped/separated/p != 0
        self.friction_tol = friction_tol
        self._hbm: dict[bytes, HBMResidual] = {}
        self._unknowns: dict[bytes, np.ndarray] = {}
        self._num_dynamic: dict[bytes, int] = {}
        self.pairs = []
        for gi, gr in enumerate(rom.groups):
            P, m = gr.group.pairs.num_pairs, gr.group.pairs.num_comp
            for p in range(P):
                self.pairs.append(_Pair(gi, p, gr.first + p * m + np.arange(m)))
        self.num_pairs = len(self.pairs)
        self.events = {"activated": 0, "released": 0, "redone_steps": 0}
        # a pair open at rest is never its stuck spring: active from the start, so that the linear
        # model (the first point, the nonlinear modes' linear mode) is the real one, not one in
        # which the open pairs are closed
        self.mask = self._linear_breaks(np.zeros(harmonics.num_hc * self.q))

    # --- evaluation ------------------------------------------------------------------------
    @property
    def structure(self) -> Structure:
        return self.rom.structure_for(self.mask)

    @property
    def size(self) -> int:
        return self.rom.size_of(self.mask)

    def hbm(self) -> HBMResidual:
        key = self.mask.tobytes()
        hbm = self._hbm.pop(key, None) or HBMResidual(self.structure, self.harmonics)
        return _keep_recent(self._hbm, key, hbm, self.HBM_KEPT)

    def unknowns(self) -> np.ndarray:
        """The coefficients solved: every harmonic of the modes, the TVDs and the active
        components' internal variables ((size) x (2H + 1) of them)."""
        key = self.mask.tobytes()
        if key not in self._unknowns:
            keep = self.rom.coordinates(self.mask)
            self._unknowns[key] = (np.arange(self.harmonics.num_hc)[:, None] * self.q + keep[None, :]).ravel()
        return self._unknowns[key]

    def evaluate(self, U, omega, *, jacobian=True) -> Evaluation:
        return self.hbm().evaluate(U[self.unknowns()], omega, jacobian=jacobian)

    def initial_guess(self, omega):
        U = np.zeros(self.num_coefficients)
        U[self.unknowns()] = self.hbm().linear_solution(omega)
        return U

    def record(self, U, omega, evaluation) -> PointRecord:
        return PointRecord(self.states(U, omega, evaluation.contact), self.size,
                           self.pair_summary(U, omega, evaluation.contact), active=self.mask.copy())

    def branch_info(self) -> dict:
        return {"active_set_events": dict(self.events)}

    def hill_operators(self, omega):
        return self.hbm().hill_operators(omega)

    def floquet_correction(self, U, omega, evaluation):
        return self.hbm().floquet_correction(omega, evaluation.contact)

    def num_dynamic(self) -> int:
        key = self.mask.tobytes()
        if key not in self._num_dynamic:
            s = self.structure  # the ROM of the current active set: its p have no mass
            self._num_dynamic[key] = count_exponents(s.M, s.D)
        return self._num_dynamic[key]

    def restore(self, state) -> None:
        """Adaptive hook: the active set recorded at a point (its PointRecord.active)."""
        self.mask = np.asarray(state, bool).copy()

    def state_of(self, U) -> np.ndarray:
        """Adaptive hook: the components whose internal variable is not zero in U (active)."""
        return np.any(U.reshape(self.harmonics.num_hc, self.q)[:, self.rom.p_slots] != 0.0, axis=0)

    def _gap_time(self, U):
        """Gap samples of every group from the ROM coordinates: list of (N, P, m)."""
        h = self.harmonics
        Z = U.reshape(h.num_hc, self.q)
        out = []
        for gr in self.rom.groups:
            P, m = gr.group.pairs.num_pairs, gr.group.pairs.num_comp
            out.append(h.to_time((Z @ gr.Gr.T).reshape(h.num_hc, P, m)))
        return out

    def states(self, U, omega, contact=None) -> np.ndarray:
        """Contact state per sample and physical pair (N, num_pairs): inactive pairs stick."""
        h = self.harmonics
        st = np.zeros((h.N, self.num_pairs), np.int8)
        if contact is None:
            contact = self.evaluate(U, omega, jacobian=False).contact
        for res, idx in zip(contact, self._active_pair_index()):
            st[:, idx] = res.state_t
        return st

    def pair_summary(self, U, omega, contact) -> np.ndarray:
        """ContactLaw.summary per physical pair (P, 3): the AFT of the active pairs, the stuck
        linear springs of the others (which dissipate nothing)."""
        out = [gr.group.pairs.linear_summary(g_t) for gr, g_t in zip(self.rom.groups, self._gap_time(U))]
        out = np.concatenate(out) if out else np.zeros((0, 3))
        for res, idx, gr in zip(contact, self._active_pair_index(), self.structure.contacts):
            out[idx] = gr.pairs.summary(res.f_t, res.g_t)
        return out

    def _active_pair_index(self):
        """Global pair indices of the pairs in each contact group of the current ROM structure."""
        out, base = [], 0
        for gr in self.rom.groups:
            P, m = gr.group.pairs.num_pairs, gr.group.pairs.num_comp
            act = self.mask[gr.first:gr.first + P * m].reshape(P, m).any(axis=1)
            if act.any():
                out.append(base + np.flatnonzero(act))
            base += P
        return out

    # --- the active set ---------------------------------------------------------------------
    def _linear_breaks(self, U) -> np.ndarray:
        """Components whose stuck linear force (p = 0) would break their law at some sample
        (ContactLaw.linear_breaks)."""
        bad = np.zeros(self.rom.num_comp, bool)
        for gr, g_t in zip(self.rom.groups, self._gap_time(U)):
            pr = gr.group.pairs
            bad[gr.first:gr.first + pr.num_pairs * pr.num_comp] = pr.linear_breaks(g_t, tol=self.friction_tol).ravel()
        return bad

    def _busy(self, U, omega, breaks: np.ndarray) -> np.ndarray:
        """Components that must stay active at a converged point: away from the linear law in the
        AFT of the active pairs (ContactLaw.busy: Jenkins slip or separation), or a stuck state the
        linear spring could not hold (a shakedown offset).  ``breaks``: _linear_breaks(U)."""
        busy = np.zeros(self.rom.num_comp, bool)
        contact = self.evaluate(U, omega, jacobian=False).contact
        for res, idx, g in zip(contact, self._active_pair_index(), self.structure.contacts):
            comps = np.concatenate([self.pairs[k].comps for k in idx])
            busy[comps] = g.pairs.busy(res).ravel()
        # releasing a component pins p = 0: only where the linear spring holds the law
        return busy | (breaks & self.mask)

    def violations(self, U) -> np.ndarray:
        """Inactive components whose linear force breaks the law at some sample: |t| > mu N or N < 0."""
        return self._linear_breaks(U) & ~self.mask

    def after_converge(self, U, omega) -> bool:
        """Continuation hook: enlarge the set if an inactive component breaks the law (redo the step)."""
        breaks = self._linear_breaks(U)
        need = breaks & ~self.mask
        if need.any():
            self.mask = self.mask | need
            self.events["activated"] += int(need.sum())
            self.events["redone_steps"] += 1
            return True
        self.history.append(self._busy(U, omega, breaks))
        return False

    def before_step(self, U, omega) -> bool:
        """Continuation hook: the active set for the next step.  True if it changed: a released
        component's internal variable leaves the unknowns (it is zero from now on)."""
        if not self.history:
            return False
        recent = np.logical_or.reduce(self.history[-self.rom.options.release_after:])
        new = self.mask & recent | self.history[-1]
        if np.array_equal(new, self.mask):
            return False
        released = self.mask & ~new
        self.events["released"] += int(released.sum())
        self.mask = new
        return True

    def scales(self, omega_start, omega_end) -> Scales:
        """x scale per ROM coordinate, active or not (hbm.forced.compute_rom_scales on the stuck
        ROM, the internal variables being displacements): the same for a coordinate whatever the
        active set, so that the arclength metric does not change when the unknowns do; the
        residual's, the largest force on the stuck ROM's coordinates."""
        stuck = self.rom.structure_for(np.zeros(self.rom.num_comp, bool))
        per = compute_rom_scales(stuck, self.rom.rows, omega_start, omega_end, displacements=self.rom.num_comp)
        return Scales.from_coordinates(per, self.harmonics, force_scale(stuck))
