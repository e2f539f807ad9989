"""The harmonic-balance residual of a Structure, with its exact Jacobian.

R(U, omega) = A(omega) U + sum_g L_g^T (F_g(B_g U) - f0_g) - F_ext = 0,

A(omega) = I (x) K + omega (nabla (x) D) + omega^2 (nabla^2 (x) M), where nabla is the
d/dtau matrix of the harmonic layout, B_g = I (x) G_g the gap operator of a
contact group and L_g = I (x) L_g its load operator (L = G for a physical model; the
penalty ROM applies the force to its internal variables instead).  U has the harmonic-major layout of ``Harmonics`` (m), R is in N.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..contact.law import ContactResult
from ..harmonics import Harmonics
from ..models.structure import Structure
from .problem import Evaluation, KeepsLastEvaluation


def contact_pattern(pairs, nh: int, stride: int, offset: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where a contact group's AFT Jacobian blocks [p, h, a, h', b] land in a harmonic-major system
    whose harmonic blocks are ``stride`` long and whose group starts at ``offset`` in each block,
    and the group's static force f0 in the coefficient layout: (rows, cols, f0 of shape (nh, P, m))."""
    P, m = pairs.num_pairs, pairs.num_comp
    p, h, a, h2, b = np.indices((P, nh, m, nh, m)).reshape(5, -1)
    f0 = np.zeros((nh, P, m))
    f0[0] = pairs.preload
    return h * stride + offset + p * m + a, h2 * stride + offset + p * m + b, f0


def _selection(L: np.ndarray):
    """(rows, columns) if the dense L (P*m, n) only selects: every nonzero entry 1, at most one per
    row and per column; else None."""
    r, c = np.nonzero(L)
    if np.all(L[r, c] == 1.0) and np.unique(r).size == r.size and np.unique(c).size == c.size:
        return r, c
    return None


def _pairs_of(pairs, res: ContactResult, B: np.ndarray, BT, keep: np.ndarray):
    """A dense group's AFT result, gap operator G (P*m, n) and load operator L (dense, or a
    selection (rows, columns): _selection) on the pairs ``keep`` only (the result alone where G is
    None)."""
    m = pairs.num_comp
    rows = (keep[:, None] * m + np.arange(m)).ravel()
    sub = ContactResult(res.F[:, keep], res.J[keep], res.f_t[:, keep], res.g_t[:, keep], res.state_t[:, keep],
                        res.w_start[keep])
    if B is None:
        return sub, None, None
    if isinstance(BT, tuple):
        where = np.full(pairs.num_pairs * m, -1)
        where[rows] = np.arange(rows.size)
        r, c = BT
        inside = where[r] >= 0
        BT = (where[r[inside]], c[inside])
    else:
        BT = BT[rows]
    return sub, B[rows], BT


class HBMResidual(KeepsLastEvaluation):
    """Precomputed harmonic operators for one Structure and one Harmonics."""

    # unknowns; a ROM's matrices are dense, and sparse bookkeeping would dominate: at 4200 unknowns
    # of a full matrix SuperLU takes 5.6 s and LAPACK 0.65 s (here, 2 cores).  Craig-Bampton on the
    # 221-pair lap joint (1336 per harmonic, 9352 unknowns at H = 3) had not swept 15 rad/s in
    # 22 min in SuperLU under the former limit of 6000; LAPACK factors it in 5.6 s.  A dense J of 12000 is
    # 1.15 GB, and the continuation holds about five (bordered copy, factors, scaled copy): 6 GB
    DENSE_MAX = 12000
    _hill = None  # (I (x) D, nabla (x) M, I (x) M) for hill_operators

    def __init__(self, structure: Structure, harmonics: Harmonics, *, dense: bool | None = None):
        self.structure = structure
        self.harmonics = harmonics
        n, nh = structure.num_dofs, harmonics.num_hc
        self.num_unknowns = n * nh
        if dense is None:
            density = structure.K.nnz / max(n * n, 1)
            dense = self.num_unknowns <= self.DENSE_MAX and density > 0.2
        self.dense = dense
        nab = sp.csr_matrix(harmonics.derivative_matrix())
        eye = sp.identity(nh, format="csr")
        self._A0 = sp.kron(eye, structure.K, format="csr")
        self._A1 = sp.kron(nab, structure.D, format="csr")
        self._A2 = sp.kron(nab @ nab, structure.M, format="csr")
        if dense:
            self._A0, self._A1, self._A2 = (a.toarray() for a in (self._A0, self._A1, self._A2))
        F = np.zeros(self.num_unknowns)
        F[harmonics.cos(0, n)] = structure.f_static
        F[harmonics.cos(1, n)] = structure.fc
        F[harmonics.sin(1, n)] = structure.fs
        self.F_ext = F
        self._groups = []
        for g in structure.contacts:
            # sparsity pattern of the per-pair Jacobian blocks, in the group's own gap coefficients
            rows, cols, f0 = contact_pattern(g.pairs, nh, g.gap.shape[0])
            if dense:
                # a dense model keeps G and L (P*m, n) themselves: the harmonic blocks are applied by
                # reshaping (B = I (x) G), and the contact Jacobian L^T Jc G by contracting its
                # per-pair blocks, instead of products with the Kronecker matrices (on the 3D lap
                # joint's penalty ROM those took 17 ms of an 18 ms evaluation).  An L that only
                # selects (the penalty ROM's: each component's force on its own internal variable)
                # is kept as (rows, columns) and applied by indexing.
                B, BT = g.gap.toarray(), g.load_operator.toarray()
                BT = _selection(BT) or BT
            else:
                B = sp.kron(eye, g.gap, format="csr")
                BT = sp.kron(eye, g.load_operator, format="csr").T.tocsr()
            self._groups.append((g, B, BT, f0, rows, cols))

    def hill_operators(self, omega: float):
        """(Delta1, Delta2) of Hill's method: a perturbation e^{s t} v(omega t) of a periodic solution
        satisfies (J + s Delta1 + s^2 Delta2) v = 0, with Delta1 = I (x) D + 2 omega (nabla (x) M)
        and Delta2 = I (x) M (J: the HBM Jacobian at the solution; the contact Jacobian is frozen)."""
        if self._hill is None:  # the omega-free parts, built once
            eye = sp.identity(self.harmonics.num_hc, format="csr")
            nab = sp.csr_matrix(self.harmonics.derivative_matrix())
            self._hill = (sp.kron(eye, self.structure.D, format="csr"), sp.kron(nab, self.structure.M, format="csr"),
                          sp.kron(eye, self.structure.M, format="csr"))
        D, nabM, M = self._hill
        return (D + (2.0 * omega) * nabM).tocsr(), M

    def linear_operator(self, omega: float):
        A = self._A0 + omega * self._A1 + omega**2 * self._A2
        return A if self.dense else A.tocsr()

    def gaps(self, U: np.ndarray) -> list[np.ndarray]:
        """Gap coefficients per contact group, shape (num_hc, P, m)."""
        nh = self.harmonics.num_hc
        if self.dense:
            Z = U.reshape(nh, -1)
            return [(Z @ B.T).reshape(nh, g.pairs.num_pairs, g.pairs.num_comp) for g, B, *_ in self._groups]
        return [(B @ U).reshape(nh, g.pairs.num_pairs, g.pairs.num_comp) for g, B, *_ in self._groups]

    def _contact_jacobian_dense(self, Jp: np.ndarray, G: np.ndarray, L) -> np.ndarray:
        """L^T Jc G in the harmonic-major layout, from the per-pair blocks Jp (P, nh, m, nh, m) of
        dF/dg and the group's G, L (P*m, n): sum over p, a, b of L[pa, i] Jp[p, h, a, k, b] G[pb, j].
        L may be a selection (rows, columns) (_selection)."""
        P, nh, m = Jp.shape[0], Jp.shape[1], Jp.shape[2]
        n = G.shape[1]
        X = np.einsum("phakb,pbj->pahkj", Jp, G.reshape(P, m, n), optimize=True)  # (P, m, nh, nh, n)
        X = X.reshape(P * m, nh, nh, n)
        if isinstance(L, tuple):
            rows, cols = L
            out = np.zeros((nh, n, nh, n), dtype=X.dtype)
            out[:, cols] = X[rows].transpose(1, 0, 2, 3)
            return out.reshape(nh * n, nh * n)
        J4 = L.T @ X.reshape(P * m, nh * nh * n)  # (n, nh * nh * n): [i, h, k, j]
        return J4.reshape(n, nh, nh, n).transpose(1, 0, 2, 3).reshape(nh * n, nh * n)

    def floquet_correction(self, omega: float, contact: list):
        """``s -> (dJ(s), dJ'(s))``, dJ(s) = L^T (Jc(s) - Jc) G summed over the contact groups (dense,
        complex) and its derivative in s: what turns the point's Jacobian into Hill's matrix of a
        perturbation e^{s t} v where a law remembers its past (ContactLaw.floquet_jacobian;
        analysis.stability), sparse where the model is; the function answers None where a group's is
        not known (the event-accurate law).
        ``contact``: the point's AFT results, with their Jacobians."""
        if any(res.J is None for res in contact):
            return None
        # only pairs that leave stick somewhere in the period can remember anything, and those whose
        # slider a transient moved (a shakedown: w_start != 0; the AFT's tangent says how the
        # transient placed it, a perturbed orbit leaves it frozen); a pair stuck at its unloaded
        # position (or open) all period is its spring whatever s, and costs nothing here
        parts = []
        for (g, B, BT, f0, rows, cols), res in zip(self._groups, contact):
            keep = np.flatnonzero(np.any(res.state_t != 0, axis=0)
                                  | np.any(res.w_start.reshape(res.w_start.shape[0], -1) != 0, axis=1))
            if not keep.size:
                continue
            pairs = g.pairs.subset(keep)
            if self.dense:
                sub, Bs, BTs = _pairs_of(g.pairs, res, B, BT, keep)
                parts.append((pairs, sub, Bs, BTs, self._contact_jacobian_dense(sub.J, Bs, BTs)))
            else:  # the kept pairs' blocks of the group's sparse pattern (pair-major: contact_pattern)
                sub = _pairs_of(g.pairs, res, None, None, keep)[0]
                block = rows.size // g.pairs.num_pairs
                at = (keep[:, None] * block + np.arange(block)).ravel()
                parts.append((pairs, sub, B, BT, (rows[at], cols[at], B.shape[0])))

        if not parts:
            return None  # no pair remembers anything: Hill's matrix is exact

        def correction(s: complex):
            # base: dense, the periodic contact Jacobian to subtract; sparse, where the blocks go
            out, slope = 0.0, 0.0
            for pairs, res, B, BT, base in parts:
                both = pairs.floquet_jacobian(res, self.harmonics, s, omega, derivative=True)
                if both is None:
                    return None  # a law whose memory is not written (the first call says so)
                Js, dJs = both
                if self.dense:
                    out = out + (self._contact_jacobian_dense(Js, B, BT) - base)
                    slope = slope + self._contact_jacobian_dense(dJs, B, BT)
                else:
                    r, c, size = base
                    out = out + BT @ sp.csr_matrix(((Js - res.J).ravel(), (r, c)), shape=(size, size)) @ B
                    slope = slope + BT @ sp.csr_matrix((dJs.ravel(), (r, c)), shape=(size, size)) @ B
            return out, slope
        return correction

    def _load(self, BT, F: np.ndarray) -> np.ndarray:
        """L^T applied to force coefficients F (nh, P*m) of one group, as the residual's (nh * n,)."""
        if isinstance(BT, tuple):
            rows, cols = BT
            out = np.zeros((F.shape[0], self.structure.num_dofs))
            out[:, cols] = F[:, rows]
            return out.ravel()
        return (F @ BT).ravel()

    def _evaluate(self, U: np.ndarray, omega: float, jacobian: bool) -> Evaluation:
        A = self.linear_operator(omega)
        R = A @ U - self.F_ext
        J = A if jacobian else None
        contact = []
        nh = self.harmonics.num_hc
        for (g, B, BT, f0, rows, cols), G in zip(self._groups, self.gaps(U)):
            res = g.pairs.aft(G, self.harmonics, jacobian=jacobian)
            contact.append(res)
            if self.dense:
                R = R + self._load(BT, (res.F - f0).reshape(nh, -1))
            else:
                R = R + BT @ (res.F - f0).ravel()
            if jacobian:
                if self.dense:
                    J = J + self._contact_jacobian_dense(res.J, B, BT)
                    continue
                size = B.shape[0]
                Jc = sp.csr_matrix((res.J.ravel(), (rows, cols)), shape=(size, size))
                J = J + BT @ Jc @ B
        dR = (self._A1 + 2.0 * omega * self._A2) @ U if jacobian else None
        if jacobian and not self.dense:
            J = J.tocsr()
        return Evaluation(R, J if jacobian else None, dR, contact)

    def linear_solution(self, omega: float) -> np.ndarray:
        """Coefficients of the stuck linear response at omega (the continuation's start), m."""
        X = self.structure.linear_response(omega)
        n = self.structure.num_dofs
        U = np.zeros(self.num_unknowns)
        U[self.harmonics.cos(1, n)] = X.real
        U[self.harmonics.sin(1, n)] = -X.imag
        if self.structure.f0 is not None:  # the stuck static deflection
            U[self.harmonics.cos(0, n)] = sp.linalg.spsolve(self.structure.K_lin.tocsc(), self.structure.f0)
        return U
