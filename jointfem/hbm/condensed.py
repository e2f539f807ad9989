"""Exact harmonic condensation of the linear structure onto the contact gaps (``--method exact``).

The linear part of the full HBM equations decouples harmonic by harmonic.  For harmonic k,
in complex form with X = U_c - i U_s,

    Z_k X_k + G^T F_k = F_ext,k,      Z_k(omega) = K - (k omega)^2 M + i k omega D.

Retain the coordinates y = C u, C = [G; Q]: the gaps of every contact component and the
output DOFs (unit rows Q).  Eliminating everything else is exact:

    y_k = C Z_k^-1 F_ext,k - R_k E^T F_k,   R_k = C Z_k^-1 C^T,   G = E C,

so, with the dynamic stiffness S_k = R_k^-1 (N/m) on the retained coordinates,

    S_k (y_k - y_lin,k) + E^T (F_k - f0 delta_k0) = 0.

This residual (N) is solved by the same Newton/arclength continuation as the full model,
with the exact Jacobian: dS/domega = -S (dR/domega) S, dR/domega = -X^T Z' X with
X = Z^-1 C^T (Z is complex symmetric), Z' = -2 k^2 omega M + i k D.  Every new omega costs
one sparse complex LU per harmonic (k = 0 once) and size(C) solves each; a new U at the
same omega costs only the AFT.  It equals the full-order HBM to round-off (tested), with
(2H+1) * (P m + outputs) unknowns instead of (2H+1) n: the reference for large 3D models.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..harmonics import Harmonics
from ..linalg import Factorized, LinAlgError, eigen
from ..models.structure import Structure
from .forced import ForcedProblem
from .problem import (Evaluation, KeepsLastEvaluation, Layout, PointRecord, Problem, Scales, contact_records,
                      force_scale)
from .residual import contact_pattern


@dataclass(frozen=True)
class _Harmonic:
    """The operators of one harmonic at one (omega, xi), complex on (c - i s)."""

    S: np.ndarray  # dynamic stiffness on the retained coordinates, N/m
    dS: np.ndarray  # dS/domega
    dSxi: np.ndarray  # dS/dxi (zero where xi takes no part)
    ylin: np.ndarray  # the linear response to the scene's harmonic force (harmonic 1)
    dylin: np.ndarray
    T: np.ndarray | None  # Z^-1 C^T S: every DOF from the retained coordinates (None unless asked)


class CondensedProblem(KeepsLastEvaluation, Problem):
    """The HBM problem of a Structure condensed exactly on its contact gaps and outputs."""

    # S = R^-1 of a receptance whose condition number reaches 1e8 (neighbouring gaps move almost
    # alike) carries a relative round-off of about 1e-9: a Newton tolerance below this floor only
    # adds iterations (10 per point instead of 2 on the 3D lap joint), so compute_frf raises it.
    tol_floor = 1e-8
    _full_problem = None  # the full model's HBM problem, for Hill's method at this problem's points

    def __init__(self, structure: Structure, harmonics: Harmonics):
        if not structure.contacts:
            raise LinAlgError("exact condensation: the model has no contact pairs")
        for g in structure.contacts:
            if g.load is not None:
                raise LinAlgError("exact condensation needs L = G (a physical model, not a ROM)")
        if structure.f0 is not None:
            raise LinAlgError("exact condensation: a static force is not supported yet (use full order or a ROM)")
        self.full = structure
        self.harmonics = harmonics
        G = sp.vstack([g.gap for g in structure.contacts]).tocsr()
        self.num_gaps = G.shape[0]
        # an output that is a combination of gaps (a DOF with a pair to ground) is recovered from
        # them; retained too, it would make the receptance singular
        recovered = {}
        for k, d in structure.outputs.items():
            e = np.zeros(structure.num_dofs)
            e[d] = 1.0
            c = spla.lsqr(G.T, e, atol=1e-14, btol=1e-14, iter_lim=10 * self.num_gaps)[0]
            if np.linalg.norm(G.T @ c - e) < 1e-10:
                recovered[k] = c
        out_names = [k for k in structure.outputs if k not in recovered]
        rows = [structure.outputs[k] for k in out_names]
        Q = sp.csr_matrix((np.ones(len(rows)), (np.arange(len(rows)), rows)), shape=(len(rows), structure.num_dofs))
        self.C = sp.vstack([G, Q]).tocsr()
        self.r = self.C.shape[0]
        nh = harmonics.num_hc
        self._num_unknowns = nh * self.r
        self._CT = self.C.T.toarray()
        self._F1 = structure.fc - 1j * structure.fs
        self._ops = None  # (omega, per-harmonic data)
        self._H0 = self._harmonic(0, 0.0)
        # the retained coordinates: every gap component, then the outputs
        names = [f"gap.{i}" for i in range(self.num_gaps)] + out_names
        outputs = {k: self.num_gaps + out_names.index(k) if k in out_names
                   else np.concatenate([recovered[k], np.zeros(len(out_names))]) for k in structure.outputs}
        self.layout = Layout(self.r, tuple(names), outputs, structure.pair_names, structure.pair_coords,
                             structure.pair_areas)
        # contact Jacobian pattern per group (as in HBMResidual), in the retained coordinates
        self._groups = []
        offset = 0
        self._Kc = np.zeros((self.r, self.r))  # the stuck contact springs on the retained coordinates
        for g in structure.contacts:
            Pm = g.gap.shape[0]
            rows_, cols_, f0 = contact_pattern(g.pairs, nh, self.r, offset)
            idx = (np.arange(nh)[:, None] * self.r + offset + np.arange(Pm)[None, :]).ravel()
            self._groups.append((g, idx, rows_, cols_, f0))
            self._Kc[offset:offset + Pm, offset:offset + Pm] = np.diag(g.pairs.stiffness.ravel())
            offset += Pm

    @property
    def num_unknowns(self) -> int:
        return self._num_unknowns

    # ---- per-omega operators ------------------------------------------------------------
    def _harmonic(self, k: int, omega: float, xi: float | None = None, *, recovery: bool = False) -> "_Harmonic":
        """The operators of harmonic k at omega, with the EPMC's self-excitation -xi M u' in the
        damping where xi (1/s) is given: Z_k = K - (k omega)^2 M + i k omega (D - xi M), and dS/dxi
        (zero where xi is None).  ``recovery``: also T = Z^-1 C^T S, which maps the retained
        coordinates to every DOF."""
        s = self.full
        kw = k * omega
        D = s.D - xi * s.M if xi else s.D  # xi None or 0: the structure's own damping
        Z = (s.K - kw**2 * s.M + 1j * kw * D) if k else s.K
        lu = Factorized(Z, what=f"exact condensation: dynamic stiffness of harmonic {k} at omega = {omega:.6g} rad/s"
                        + (f", xi = {xi:.6g} 1/s" if xi is not None else ""))
        rhs = self._CT if k != 1 else np.column_stack([self._CT, self._F1])
        sol = lu.solve(rhs.astype(complex) if k else rhs)
        X = sol[:, :self.r]
        R = self.C @ X
        try:
            S = np.linalg.inv(R)
        except np.linalg.LinAlgError as exc:
            raise LinAlgError(f"exact condensation: the receptance of harmonic {k} on the contact gaps is singular "
                              f"(two gaps or outputs are linearly dependent)") from exc
        zero = np.zeros_like(S)
        T = X @ S if recovery else None
        if k == 0:
            return _Harmonic(S, zero, zero, np.zeros(self.r), np.zeros(self.r), T)
        dZ = -2.0 * k * k * omega * s.M + 1j * k * D
        dS = S @ (X.T @ (dZ @ X)) @ S  # -S (dR/domega) S, dR/domega = -X^T Z' X (Z complex symmetric)
        dSxi = zero if xi is None else S @ (X.T @ ((-1j * kw) * (s.M @ X))) @ S  # dZ/dxi = -i k omega M
        if k == 1:
            u = sol[:, self.r]
            ylin = self.C @ u
            dylin = -X.T @ (dZ @ u)
        else:
            ylin = dylin = np.zeros(self.r, dtype=complex)
        return _Harmonic(S, dS, dSxi, ylin, dylin, T)

    def _operators(self, omega: float, xi: float = 0.0, orders: tuple = ()) -> list[_Harmonic]:
        """Every harmonic's operators at omega, with xi on the harmonics ``orders`` (cached for the
        last (omega, xi, orders): a new U at the same point costs only the AFT)."""
        key = (omega, xi, tuple(orders))
        if self._ops is None or self._ops[0] != key:
            H = self.harmonics.H
            modal = bool(orders)
            if modal and self._H0.T is None:  # the static harmonic with its recovery, once
                self._H0 = self._harmonic(0, 0.0, recovery=True)
            data = [self._H0]
            data += [self._harmonic(k, omega, xi if k in orders else None, recovery=modal) for k in range(1, H + 1)]
            self._ops = (key, data)
        return self._ops[1]

    @staticmethod
    def _real_block(S):
        """Real form of a complex operator on (c - i s): [[Sr, Si], [-Si, Sr]]."""
        return np.block([[S.real, S.imag], [-S.imag, S.real]])

    # ---- the problem protocol (jointfem.hbm.problem) -------------------------------------
    def _evaluate(self, U, omega, jacobian):
        R, J, dR, _, contact = self._assemble(U, self._operators(float(omega)), jacobian, forced=True)
        return Evaluation(R, J, dR, contact)

    def evaluate_self_excited(self, U, omega: float, xi: float, orders: tuple, *, jacobian: bool = True):
        """The EPMC's residual of the free structure (no harmonic force; the preload stays): the
        linear part with -xi M u' on the harmonics ``orders``, plus the contact forces.  Returns
        (Evaluation with dR/domega, dR/dxi)."""
        R, J, dR, dRxi, contact = self._assemble(U, self._operators(float(omega), float(xi), tuple(orders)),
                                                 jacobian, forced=False)
        return Evaluation(R, J, dR, contact), dRxi

    def _assemble(self, U, data, jacobian, *, forced: bool):
        h, r = self.harmonics, self.r
        nh = h.num_hc
        Y = U.reshape(nh, r)
        R = np.zeros((nh, r))
        dR = np.zeros((nh, r))
        dRxi = np.zeros((nh, r))
        J = np.zeros((nh * r, nh * r)) if jacobian else None
        S0 = data[0].S.real
        R[0] = S0 @ Y[0]
        if jacobian:
            J[:r, :r] = S0
        for k in range(1, h.H + 1):
            op = data[k]
            c, s_ = h.block_cos(k), h.block_sin(k)
            Yk = Y[c] - 1j * Y[s_]
            ylin, dylin = (op.ylin, op.dylin) if forced else (0.0 * op.ylin, 0.0 * op.dylin)
            E = op.S @ (Yk - ylin)
            R[c], R[s_] = E.real, -E.imag
            dE = op.dS @ (Yk - ylin) - op.S @ dylin
            dR[c], dR[s_] = dE.real, -dE.imag
            dE = op.dSxi @ Yk
            dRxi[c], dRxi[s_] = dE.real, -dE.imag
            if jacobian:
                blk = self._real_block(op.S)
                J[np.ix_(np.r_[c * r:(c + 1) * r, s_ * r:(s_ + 1) * r],
                         np.r_[c * r:(c + 1) * r, s_ * r:(s_ + 1) * r])] = blk
        R = R.ravel()
        contact = []
        for g, idx, rows_, cols_, f0 in self._groups:
            G = U[idx].reshape(nh, g.pairs.num_pairs, g.pairs.num_comp)
            res = g.pairs.aft(G, h, jacobian=jacobian)
            contact.append(res)
            R[idx] += (res.F - f0).ravel()
            if jacobian:
                J[rows_, cols_] += res.J.ravel()  # the pattern's (row, col) pairs are distinct
        return R, J, dR.ravel() if jacobian else None, dRxi.ravel(), contact

    def harmonic_fields(self, U, omega: float, xi: float, orders: tuple) -> list[np.ndarray]:
        """The complex amplitude u_k = c_k - i s_k of every DOF for k = 0..H (u_0 real) of the
        retained coordinates U solved by ``evaluate_self_excited``: u_k = Z_k^-1 C^T S_k y_k
        (exact: the contact forces act on the gaps alone)."""
        h, r = self.harmonics, self.r
        data = self._operators(float(omega), float(xi), tuple(orders))
        Y = U.reshape(h.num_hc, r)
        out = [data[0].T.real @ Y[0]]
        for k in range(1, h.H + 1):
            out.append(data[k].T @ (Y[h.block_cos(k)] - 1j * Y[h.block_sin(k)]))
        return out

    def hill_matrices(self, x, lam, evaluation):
        """Hill's problem of the full model at the full field of the point (full_coefficients): the
        condensed dynamic stiffness S_k(omega) is not polynomial in the exponent, the full model's
        is, and both have the same periodic solution (analysis.stability)."""
        if self._full_problem is None:
            self._full_problem = ForcedProblem(self.full, self.harmonics)
        fp = self._full_problem
        ev = fp.evaluate(self.full_coefficients(x, lam), lam, jacobian=True)
        return ev.J, *fp.hill_operators(lam), fp.num_dynamic()

    @property
    def hill_size(self) -> int:
        return self.full.num_dofs * self.harmonics.num_hc

    def full_coefficients(self, U, omega: float) -> np.ndarray:
        """The full model's HBM coefficients (every DOF, in the full-order problem's layout: harmonic
        blocks of num_dofs) of the forced solution U at omega.  With the contact forces F_k of U's
        gaps, u_k = Z_k^-1 (F_ext,k - G^T (F_k - f0 delta_k0)): exact, since the contact forces act on
        the gaps alone, so the result solves the full-order residual to the condensation's round-off.
        What the full-order problem needs at a point of this one: Hill's stability, a time
        integration from the orbit's state, pictures of the whole field."""
        h, s = self.harmonics, self.full
        ev = self.evaluate(np.asarray(U, float), float(omega), jacobian=False)
        load = np.zeros((h.num_hc, s.num_dofs))
        for (g, _, _, _, f0), res in zip(self._groups, ev.contact):
            load += (res.F - f0.reshape(res.F.shape)).reshape(h.num_hc, -1) @ g.gap
        out = np.zeros((h.num_hc, s.num_dofs))
        out[0] = Factorized(s.K, what="exact condensation: the static harmonic's recovery").solve(-load[0])
        for k in range(1, h.H + 1):
            c, s_ = h.block_cos(k), h.block_sin(k)
            rhs = -(load[c] - 1j * load[s_]) + (self._F1 if k == 1 else 0.0)
            Z = s.K - (k * omega) ** 2 * s.M + 1j * k * omega * s.D
            u = Factorized(Z, what=f"exact condensation: recovery of harmonic {k} at omega = {omega:.6g} rad/s").solve(
                rhs.astype(complex))
            out[c], out[s_] = u.real, -u.imag
        return out.ravel()

    def linear_mode(self, mode: int):
        """The stuck linear mode ``mode`` of the full structure: (omega rad/s, phi mass-normalised
        over every DOF, phi^T D phi)."""
        s = self.full
        w2, Phi = eigen(s.K_lin, s.M, mode, what="exact condensation: the stuck linear structure")
        phi = Phi[:, mode - 1]
        return float(np.sqrt(max(w2[mode - 1], 0.0))), phi, float(phi @ (s.D @ phi))

    def _stuck(self, omega):
        """Stuck linear response on the retained coordinates at harmonic 1 (complex)."""
        op = self._harmonic(1, omega)
        return np.linalg.solve(op.S + self._Kc, op.S @ op.ylin)

    def initial_guess(self, omega):
        """The stuck linear response on the retained coordinates."""
        y = self._stuck(omega)
        U = np.zeros(self.num_unknowns)
        U[self.harmonics.cos(1, self.r)] = y.real
        U[self.harmonics.sin(1, self.r)] = -y.imag
        return U

    def scales(self, omega_start, omega_end, num: int = 21) -> Scales:
        """Outputs: their largest stuck amplitude over the range.  Gaps: the largest retained
        amplitude, as the penalty ROM scales its internal variables: a gap that barely moves while
        stuck opens or slips by the size of the response, and scaled by its stuck amplitude it
        would dominate the arclength and shrink every step."""
        w = np.linspace(min(omega_start, omega_end), max(omega_start, omega_end), num)
        X = np.abs(np.array([self._stuck(x) for x in w])).max(axis=0)
        top = X.max()
        if not np.isfinite(top) or top <= 0:
            top = 1.0
        X = np.maximum(X, 1e-6 * top)
        X[:self.num_gaps] = top
        return Scales.from_coordinates(X, self.harmonics, force_scale(self.full))

    def record(self, x, omega, evaluation) -> PointRecord:
        states, summary = contact_records(self.harmonics, [g.pairs for g in self.full.contacts], evaluation.contact)
        return PointRecord(states, self.r, summary)
