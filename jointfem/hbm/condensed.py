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

Where D is diagonal in the modes (Rayleigh damping, or modal damping) and the model has at most
MODAL_MAX DOFs, the per-omega LUs are replaced by one dense eigendecomposition of the inverse
problem M v = mu K v (V^T K V = I, V^T M V = diag(mu), V^T D V = diag(d)), which diagonalises
every harmonic at once:

    V^T Z_k V = diag(z),  z = 1 - (k omega)^2 mu + i k omega (d - xi mu),
    R_k = B diag(1/z) B^T,  B = C V,   dR_k/domega = -B diag(z'/z^2) B^T,

the same receptance with every mode kept (no truncation: exact to round-off, tested against the
LU path), at two r x n x r products per harmonic instead of a sparse complex LU and r solves.
With Rayleigh damping the modes far above k omega are summed as a power series whose r x r terms
are formed once (``CondensedProblem._stiff``), so a new omega costs products over the low modes only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.linalg import LinearOperator

from ..harmonics import Harmonics
from ..linalg import BorderedFactor, Factorized, LinAlgError, all_modes_inverse, bordered_unavailable, eigen
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
    _full_last = None  # (key, _full_point's answer) of the last point asked

    def __init__(self, structure: Structure, harmonics: Harmonics, *, modal: "bool | None | ModalBasis" = None,
                 sparse: str | None = None):
        """``modal``: the modal path (None: where D is diagonal in the modes and n <= MODAL_MAX;
        True: required, an error where it cannot be taken; False: a sparse factorisation per
        harmonic and omega; a ModalBasis: that one, computed offline by ``modal_basis``).
        ``sparse``, where the modal path is not taken: "schur" (complex MUMPS, the receptance formed
        as a Schur complement, one analysis for the branch; an error where MUMPS cannot be called
        directly), "lu" (a sparse LU and r solves per harmonic and omega), None: "schur" where it
        can be taken."""
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
        self._CT_sparse = self.C.T.tocsr()
        self._F1 = structure.fc - 1j * structure.fs
        self._ops = None  # (omega, per-harmonic data)
        self._modal = self._modal_basis(modal)  # (mu, d, V, B, V^T F1, rayleigh) or None
        self._schur = None  # harmonic k -> BorderedFactor, on the Schur path
        if self._modal is None:
            if sparse not in (None, "schur", "lu"):
                raise ValueError(f"exact condensation: sparse = {sparse!r}, expected 'schur', 'lu' or None")
            reason = bordered_unavailable() if sparse != "lu" else "asked for"
            if reason is None:
                self._schur = {}
            elif sparse == "schur":
                raise LinAlgError(f"exact condensation (Schur path): {reason}")
        self._split = None  # the modal path's stiff modes summed as a series (_stiff)
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

    def branch_info(self) -> dict:
        """How the harmonics were condensed: "modal" (one eigendecomposition), "schur" (a MUMPS
        factorisation per harmonic and omega, one analysis) or "lu" (a sparse LU per harmonic and
        omega)."""
        return {"condensation": "modal" if self._modal is not None else "schur" if self._schur is not None else "lu"}

    # ---- per-omega operators ------------------------------------------------------------
    def _modal_basis(self, modal):
        """(mu, d, V, B = C V, V^T F1) of the modal path, or None where it is not taken (see
        ``modal`` of __init__)."""
        basis = modal if isinstance(modal, ModalBasis) else None
        if basis is None and modal is not False:
            basis = modal_basis(self.full, required=bool(modal))
        if basis is None:
            return None
        return (basis.mu, basis.d, basis.V, np.ascontiguousarray(self.C @ basis.V), basis.V.T @ self._F1,
                basis.rayleigh)

    def _harmonic(self, k: int, omega: float, xi: float | None = None, *, recovery: bool = False) -> "_Harmonic":
        """The operators of harmonic k at omega, with the EPMC's self-excitation -xi M u' in the
        damping where xi (1/s) is given: Z_k = K - (k omega)^2 M + i k omega (D - xi M), and dS/dxi
        (zero where xi is None).  ``recovery``: also T = Z^-1 C^T S, which maps the retained
        coordinates to every DOF."""
        if self._modal is not None:
            return self._harmonic_modal(k, omega, xi, recovery=recovery)
        if self._schur is not None and k > 0:  # the static harmonic, once: the LU path below
            return self._harmonic_schur(k, omega, xi, recovery=recovery)
        s = self.full
        kw = k * omega
        D = s.D - xi * s.M if xi else s.D  # xi None or 0: the structure's own damping
        Z = (s.K - kw**2 * s.M + 1j * kw * D) if k else s.K
        lu = Factorized(Z, what=f"exact condensation: dynamic stiffness of harmonic {k} at omega = {omega:.6g} rad/s"
                        + (f", xi = {xi:.6g} 1/s" if xi is not None else ""))
        CT = self.C.T.toarray()  # dense n x r right-hand sides: the LU path only
        rhs = CT if k != 1 else np.column_stack([CT, self._F1])
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

    @staticmethod
    def _coefficients(k: int, omega: float, xi: float | None) -> tuple:
        """(a, b, c) of Z_k = a K + b M + c D for k >= 1: K - (k omega)^2 M + i k omega (D - xi M)."""
        kw = k * omega
        return 1.0, -kw**2 - 1j * kw * (xi or 0.0), 1j * kw

    def _factor(self, k: int) -> BorderedFactor:
        """Harmonic k's factorisation on the Schur path (its analysis made at the first call)."""
        f = self._schur.get(k)
        if f is None:
            s = self.full
            f = self._schur[k] = BorderedFactor([s.K, s.M, s.D], self.C,
                                                what=f"exact condensation: dynamic stiffness of harmonic {k}")
        return f

    def _harmonic_schur(self, k: int, omega: float, xi: float | None, *, recovery: bool) -> "_Harmonic":
        """_harmonic on the Schur path, k >= 1: R_k = C Z_k^-1 C^T from MUMPS's Schur complement of
        [[Z_k, C^T], [C, 0]], and every product with X = Z_k^-1 C^T (dS/domega, dS/dxi, the
        recovery T) as an operator of two solves with the kept factors, never the n x r X itself:
        dS v = S C Z^-1 Z' Z^-1 C^T S v (Z complex symmetric).  The static harmonic, formed once per
        problem, takes the LU path: its pivot check refuses a body without supports (K singular),
        which MUMPS's null-pivot detection cannot tell from a body held by its contacts alone
        (tests/test_continuum.py, tests/test_preload.py)."""
        s, C, r = self.full, self.C, self.r
        f = self._factor(k)
        coef = self._coefficients(k, omega, xi)
        try:
            R = f.factor(coef)
        except LinAlgError as exc:
            raise LinAlgError(f"{exc}, at omega = {omega:.6g} rad/s" + (f", xi = {xi:.6g} 1/s" if xi else "")) from exc
        try:
            S = np.linalg.inv(R)
        except np.linalg.LinAlgError as exc:
            raise LinAlgError(f"exact condensation: the receptance of harmonic {k} on the contact gaps is singular "
                              f"(two gaps or outputs are linearly dependent)") from exc
        CT = self._CT_sparse

        def chain(*maps):  # x -> the maps' chain of solves with the factor at (k, omega, xi)
            def matvec(v):
                f.ensure(coef)
                return S @ f.solve_chain(CT @ (S @ np.ravel(v)), list(maps) + [lambda y: C @ y])
            return LinearOperator((r, r), matvec=matvec, dtype=complex)

        def recover(y):
            f.ensure(coef)
            return f.solve_chain(CT @ (S @ np.ravel(y)), [lambda x: x])

        T = LinearOperator((s.num_dofs, r), matvec=recover, dtype=complex) if recovery else None
        zero = np.zeros((r, r), dtype=complex)

        def dZ(x):  # Z' = -2 k^2 omega M + i k (D - xi M), applied without forming it
            Mx = s.M @ x
            return (-2.0 * k * k * omega - 1j * k * (xi or 0.0)) * Mx + 1j * k * (s.D @ x)

        dS = chain(dZ)
        dSxi = zero if xi is None else chain(lambda x: (-1j * k * omega) * (s.M @ x))
        if k == 1:  # ylin = C Z^-1 F1, dylin = -C Z^-1 Z' Z^-1 F1
            first = {}

            def keep(u):
                first["y"] = C @ u
                return dZ(u)

            both = f.solve_chain(self._F1, [keep, lambda x: np.concatenate([first["y"], -(C @ x)])])
            ylin, dylin = both[:r], both[r:]
        else:
            ylin = dylin = np.zeros(self.r, dtype=complex)
        return _Harmonic(S, dS, dSxi, ylin, dylin, T)

    def _harmonic_modal(self, k: int, omega: float, xi: float | None, *, recovery: bool) -> "_Harmonic":
        """_harmonic on the modal path (module docstring): the same operators from the diagonal
        V^T Z_k V = diag(z); with Rayleigh damping, the stiff modes' share summed as a series
        (``_stiff``)."""
        mu, d, V, B, f1, rayleigh = self._modal
        kw = k * omega

        def receptance(w, Bw=B):  # Bw diag(w) Bw^T, Bw real: one or two real products
            if np.iscomplexobj(w):
                return (Bw * w.real) @ Bw.T + 1j * ((Bw * w.imag) @ Bw.T)
            return (Bw * w) @ Bw.T

        if k == 0:
            w = np.ones_like(mu)  # V^T K V = I
            R = receptance(w)
        else:
            stiff = self._stiff(k, omega, xi or 0.0) if rayleigh is not None else None
            # without recovery the stiff modes enter through the series alone: w, q and qxi are formed
            # over the low modes only (the same numbers, elementwise; a stiff mode's z is not 0)
            part = stiff[0] if stiff is not None and not recovery else None
            mu_k, d_k = (mu, d) if part is None else (mu[part], d[part])
            dx = d_k - xi * mu_k if xi else d_k
            z = 1.0 - kw**2 * mu_k + 1j * kw * dx
            if np.any(z == 0):
                raise LinAlgError(f"exact condensation: dynamic stiffness of harmonic {k} at omega = {omega:.6g} "
                                  "rad/s is singular (an undamped resonance)")
            w = 1.0 / z
            q = (-2.0 * k * k * omega * mu_k + 1j * k * dx) * w * w  # z'/z^2: X^T Z' X = B diag(q) B^T
            qxi = (-1j * kw) * mu_k * w * w
            if stiff is None:
                R = receptance(w)
            else:
                low, Bl, c, cw, cxi, P, g = stiff
                wl, ql, qxl = (w, q, qxi) if part is not None else (w[low], q[low], qxi[low])
                R = receptance(wl, Bl) + _series(c, P)
        try:
            S = np.linalg.inv(R)
        except np.linalg.LinAlgError as exc:
            raise LinAlgError(f"exact condensation: the receptance of harmonic {k} on the contact gaps is singular "
                              f"(two gaps or outputs are linearly dependent)") from exc
        T = V @ (w[:, None] * (B.T @ S)) if recovery else None
        zero = np.zeros_like(S)
        if k == 0:
            return _Harmonic(S, zero, zero, np.zeros(self.r), np.zeros(self.r), T)
        if stiff is None:
            dS = S @ receptance(q) @ S
            dSxi = zero if xi is None else S @ receptance(qxi) @ S
            ylin, dylin = (B @ (w * f1), -(B @ (q * f1))) if k == 1 else (None, None)
        else:  # receptance(q) = -dR/domega, receptance(qxi) = -dR/dxi
            dS = S @ (receptance(ql, Bl) - _series(cw, P)) @ S
            dSxi = zero if xi is None else S @ (receptance(qxl, Bl) - _series(cxi, P)) @ S
            if k == 1:
                fl = f1[low]
                ylin, dylin = Bl @ (wl * fl) + c @ g, -(Bl @ (ql * fl)) + cw @ g
        if k != 1:
            ylin = dylin = np.zeros(self.r, dtype=complex)
        return _Harmonic(S, dS, dSxi, ylin, dylin, T)

    def _stiff(self, k: int, omega: float, xi: float):
        """The modal path's split at harmonic k (Rayleigh damping D = alpha M + beta K): with
        a = 1 + i k omega beta and s = (k omega)^2 - i k omega (alpha - xi), every mode's
        z = a - mu s, so a mode with |mu s / a| <= SPLIT_RHO has

            1/z = (1/a) sum_p (mu s / a)^p,  p = 0 .. SPLIT_ORDER  (remainder below 2e-16 of it),

        and the stiff modes' share of R_k is sum_p c_p P_p with P_p = B_s diag((mu_s/cut)^p) B_s^T,
        c_p = (s cut / a)^p / a: r x r matrices formed once, so a new omega costs products over the
        low modes only.  Returns (low mask, B_low, c, dc/domega, dc/dxi, P, g), forming the split again
        (cut = SPLIT_RHO / (2 |s/a|) at the highest harmonic) when this harmonic's |s/a| exceeds
        what the current one covers; None where no mode is stiff enough to gain from it."""
        mu, f1, B = self._modal[0], self._modal[4], self._modal[3]
        alpha, beta = self._modal[5]
        kw = k * omega
        a, sf = 1.0 + 1j * kw * beta, kw**2 - 1j * kw * (alpha - xi)
        ratio = abs(sf / a)
        if self._split is None or self._split[0] * ratio > SPLIT_RHO:
            H = max(self.harmonics.H, k)
            aH, sH = 1.0 + 1j * H * omega * beta, (H * omega) ** 2 - 1j * H * omega * (alpha - xi)
            cut = SPLIT_RHO / (2.0 * max(abs(sH / aH), ratio))
            low = mu > cut
            if low.sum() > 0.8 * mu.size:  # the series would save little: every mode summed
                self._split = (cut, None, None, None, None)
            else:
                Bs, ms = B[:, ~low], mu[~low] / cut
                P = np.empty((SPLIT_ORDER + 1, self.r, self.r))
                g = np.empty((SPLIT_ORDER + 1, self.r), dtype=complex)
                for p in range(SPLIT_ORDER + 1):
                    wp = ms**p
                    P[p] = (Bs * wp) @ Bs.T
                    g[p] = Bs @ (wp * f1[~low])
                self._split = (cut, P, g, low, np.ascontiguousarray(B[:, low]))
        cut, P, g, low, Bl = self._split
        if P is None:
            return None
        pp = np.arange(SPLIT_ORDER + 1)
        c = (sf * cut / a) ** pp / a
        dsf, da = 2.0 * k * k * omega - 1j * k * (alpha - xi), 1j * k * beta
        return low, Bl, c, c * (pp * dsf / sf - (pp + 1) * da / a), c * pp * (1j * kw) / sf, P, g

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
            if jacobian:  # (on the Schur path each product with dS costs two solves)
                dE = op.dS @ (Yk - ylin) - op.S @ dylin
                dR[c], dR[s_] = dE.real, -dE.imag
                dE = op.dSxi @ Yk
                dRxi[c], dRxi[s_] = dE.real, -dE.imag
                # the real form of S on (c - i s), [[Sr, Si], [-Si, Sr]], written block by block
                rc, rs = slice(c * r, (c + 1) * r), slice(s_ * r, (s_ + 1) * r)
                J[rc, rc], J[rc, rs], J[rs, rc], J[rs, rs] = op.S.real, op.S.imag, -op.S.imag, op.S.real
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
        out = [np.real(data[0].T @ Y[0])]
        for k in range(1, h.H + 1):
            out.append(data[k].T @ (Y[h.block_cos(k)] - 1j * Y[h.block_sin(k)]))
        return out

    stability_not_by_default = ("the exact condensation's stability is the full model's Hill problem at every "
                                "point, far larger than the condensed one (--stability on computes it)")

    def hill_matrices(self, x, lam, evaluation):
        """Hill's problem of the full model at the full field of the point (full_coefficients): the
        condensed dynamic stiffness S_k(omega) is not polynomial in the exponent, the full model's
        is, and both have the same periodic solution (analysis.stability)."""
        fp, x_full, ev = self._full_point(x, lam)
        return ev.J, *fp.hill_operators(lam), fp.num_dynamic()

    def floquet_correction(self, x, lam, evaluation):
        """The full model's, at the full field of the point (as hill_matrices)."""
        fp, x_full, ev = self._full_point(x, lam)
        return fp.floquet_correction(x_full, lam, ev)

    def _full_point(self, x, lam):
        """(the full model's problem, the point's full field, its evaluation there with the Jacobian),
        kept for the last point: hill_matrices and floquet_correction both ask for it."""
        if self._full_problem is None:
            self._full_problem = ForcedProblem(self.full, self.harmonics)
        key = (float(lam), x.tobytes())
        if self._full_last is None or self._full_last[0] != key:
            fp = self._full_problem
            x_full = self.full_coefficients(x, lam)
            self._full_last = (key, (fp, x_full, fp.evaluate(x_full, lam, jacobian=True)))
        return self._full_last[1]

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
        if self._modal is not None:  # u_k = V diag(1/z) V^T rhs
            mu, d, V = self._modal[:3]
            out[0] = V @ (V.T @ -load[0])
            for k in range(1, h.H + 1):
                c, s_ = h.block_cos(k), h.block_sin(k)
                rhs = -(load[c] - 1j * load[s_]) + (self._F1 if k == 1 else 0.0)
                z = 1.0 - (k * omega) ** 2 * mu + 1j * k * omega * d
                u = V @ ((V.T @ rhs.real + 1j * (V.T @ rhs.imag)) / z)
                out[c], out[s_] = u.real, -u.imag
            return out.ravel()
        out[0] = Factorized(s.K, what="exact condensation: the static harmonic's recovery").solve(-load[0])
        if self._schur is not None:  # u_k = Z_k^-1 rhs with the factors the evaluation above made
            for k in range(1, h.H + 1):
                rhs = -(load[h.block_cos(k)] - 1j * load[h.block_sin(k)]) + (self._F1 if k == 1 else 0.0)
                f = self._factor(k)
                f.ensure(self._coefficients(k, omega, None))
                u = f.solve_chain(np.asarray(rhs, dtype=complex), [lambda x: x])
                out[h.block_cos(k)], out[h.block_sin(k)] = u.real, -u.imag
            return out.ravel()
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


# the modal path (module docstring) up to this many DOFs: its eigendecomposition holds three dense
# n x n arrays (3.5 GB at 12000) and takes minutes there, once
MODAL_MAX = 13000
# the modal path's stiff modes (_stiff): |mu s / a| <= SPLIT_RHO, the series to SPLIT_ORDER
# (SPLIT_RHO^(SPLIT_ORDER + 1) / (1 - SPLIT_RHO) = 2.4e-16 of the stiff share left out)
SPLIT_RHO = 0.25
SPLIT_ORDER = 26


def _series(c: np.ndarray, P: np.ndarray) -> np.ndarray:
    """sum_p c_p P_p, c complex, P real (p, r, r)."""
    # (np.tensordot's own product, without its per-call overhead: this runs per harmonic and evaluation)
    flat = P.reshape(P.shape[0], -1)
    return (np.dot(c.real[None, :], flat) + 1j * np.dot(c.imag[None, :], flat)).reshape(P.shape[1:])

_LAST_BASIS: list = []  # [(K, M, D), ModalBasis] of the last structure whose basis was computed


@dataclass(frozen=True)
class ModalBasis:
    """Every mode of the inverse problem M v = mu K v: V^T K V = I, V^T M V = diag(mu), and the
    damping V^T D V = diag(d)."""

    mu: np.ndarray
    d: np.ndarray
    V: np.ndarray
    rayleigh: tuple[float, float] | None = None  # (alpha, beta) where D = alpha M + beta K: d = alpha mu + beta


def modal_basis(structure: Structure, *, required: bool = False) -> ModalBasis | None:
    """The modal path's basis of ``structure`` (module docstring), or None where it is not taken:
    more than MODAL_MAX DOFs, K not positive definite, or D not diagonal in the modes.
    ``required``: raise LinAlgError instead of None, saying why."""
    n = structure.num_dofs
    key = (structure.K, structure.M, structure.D)
    if _LAST_BASIS and all(a is b for a, b in zip(_LAST_BASIS[0], key)):
        return _LAST_BASIS[1]  # the same matrices as the last call: minutes saved at 12000 DOFs
    if n > MODAL_MAX:
        if required:
            raise LinAlgError(f"exact condensation (modal path): {n} DOFs, more than {MODAL_MAX}")
        return None
    try:
        mu, V = all_modes_inverse(structure.K, structure.M, what="exact condensation (modal path)")
    except LinAlgError:
        if required:
            raise
        return None
    d, rayleigh = _diagonal_damping(structure, V, mu)
    if d is None:
        if required:
            raise LinAlgError("exact condensation (modal path): the damping matrix is not diagonal in the modes "
                              "(neither Rayleigh nor modal damping)")
        return None
    _LAST_BASIS[:] = [key, ModalBasis(mu, d, V, rayleigh)]  # holds the matrices too, so that `is` cannot be fooled
    return _LAST_BASIS[1]


def _diagonal_damping(s: Structure, V: np.ndarray, mu: np.ndarray) -> tuple[np.ndarray | None, tuple | None]:
    """d with V^T D V = diag(d) (V^T K V = I, V^T M V = diag(mu)), or None where D is not
    diagonal in the modes; and (alpha, beta) where D is Rayleigh damping (else None).  Rayleigh damping D = alpha M + beta K (d = alpha mu + beta) is
    recognised from two random probes; other damping up to 4000 DOFs (modal damping) by
    forming diag(V^T D V) and checking D V c = K V (d c) on a random c."""
    n = s.num_dofs
    rng = np.random.default_rng(0)
    x = rng.standard_normal((n, 2))
    Dx = np.asarray(s.D @ x).ravel()
    A = np.column_stack([np.asarray(s.M @ x).ravel(), np.asarray(s.K @ x).ravel()])
    norms = np.maximum(np.linalg.norm(A, axis=0), 1e-300)  # K x is about 1e12 times M x: scale the columns
    ab = np.linalg.lstsq(A / norms, Dx, rcond=None)[0] / norms
    if np.linalg.norm(A @ ab - Dx) <= 1e-12 * np.linalg.norm(Dx):
        return ab[0] * mu + ab[1], (float(ab[0]), float(ab[1]))
    if n > 4000:
        return None, None
    d = np.einsum("ij,ij->j", V, np.asarray(s.D @ V))
    c = rng.standard_normal(n)
    lhs = s.D @ (V @ c)
    rhs = s.K @ (V @ (d * c))
    return (d if np.linalg.norm(lhs - rhs) <= 1e-9 * max(np.linalg.norm(lhs), 1e-300) else None), None
