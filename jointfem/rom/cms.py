"""The reference reductions of the paper's Fig. 5 and 6, built from substructure matrices.

Every basis T keeps the physical contact DOFs recoverable (g = G T z), so the same AFT
runs on every ROM.  The substructures are coupled through the joint: the contact pairs
(nonlinear) and the Structure's linear ``links`` (the beam's rotational springs).  The
substructure matrices are K_s, M_s of the assembled K - links, M restricted to one
substructure; the boundary DOFs of a substructure are those the joint touches.

* cb: fixed-interface modes + constraint modes (boundary DOFs kept).
* rubin: free-interface modes + residual-flexibility attachment modes of unit boundary forces
  (residual mass kept), each column of unit mass norm (the span of Rubin's boundary-DOF form).
* macneal: the Rubin basis without the residual inertia (mass of the kept modes only).
* dcb: Rixen's dual Craig-Bampton: free-interface modes + the residual flexibility's response to
  the interface forces, which are unknowns (Lagrange multipliers) beside the joint's gaps; the
  joint is dual-assembled, each connection with its own law (dual_craig_bampton).
* cc: CB whose boundary DOFs are replaced by the lowest characteristic interface modes of
  the CB-reduced boundary matrices, joint stuck: the characteristic constraint modes of
  Castanier, Tan and Pierre (AIAA J. 39, 2001).  It stands where the paper's Fig. 5 has a
  "joint interface method" with half as many static modes as nonlinear DOFs; it was called
  "jim" here before, a name it did not earn (issue 13).
* tvd: global vibration modes of the stuck structure + POD-compressed trial-vector
  derivatives (derivatives of the modes with respect to each contact stiffness).

Modes: ``RomOptions.modes`` is the total number of substructure modes for the CMS methods,
split evenly, and the number of global modes for tvd.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..linalg import Factorized, LinAlgError, eigen, pod
from ..models.structure import ContactGroup, Structure
from .common import ReducedModel, RomError, RomOptions, check_basis, project


def joint_operator(structure: Structure) -> tuple[sp.csr_matrix, np.ndarray]:
    """All joint connections as rows: contact components first, then links.  Returns (C, k)."""
    rows = [g.gap for g in structure.contacts]
    ks = [g.pairs.stiffness.ravel() for g in structure.contacts]
    if structure.links is not None:
        rows.append(structure.links.gap)
        ks.append(np.asarray(structure.links.stiffness, float))
    if not rows:
        raise RomError("the model has no joint: nothing to reduce around")
    return sp.vstack(rows).tocsr(), np.concatenate(ks)


class _Sub:
    """One substructure: its DOFs, boundary/interior split and matrices."""

    def __init__(self, sid, dofs, boundary_mask, K, M):
        self.id, self.dofs = sid, dofs
        self.b = np.flatnonzero(boundary_mask)
        self.i = np.flatnonzero(~boundary_mask)
        self.K, self.M = K, M


def substructures(structure: Structure, method: str) -> list[_Sub]:
    if structure.substructure is None:
        raise RomError(f"{method}: the model ({structure.info.get('kind', '?')}) defines no substructures; "
                       f"use --method penalty or tvd, which need none")
    sid = np.asarray(structure.substructure)
    K = structure.K - (structure.links.matrix if structure.links is not None else 0)
    K = sp.csr_matrix(K)
    C, _ = joint_operator(structure)
    touched = np.zeros(structure.num_dofs, bool)
    touched[np.unique(C.indices)] = True
    subs = []
    for s in np.unique(sid):
        dofs = np.flatnonzero(sid == s)
        other = np.flatnonzero(sid != s)
        cross = K[dofs][:, other]
        if cross.nnz and np.abs(cross.data).max() > 1e-12 * np.abs(K.data).max():
            raise RomError(f"{method}: K couples substructure {s} to another outside the joint links; "
                           f"the model's substructure labels are inconsistent")
        subs.append(_Sub(int(s), dofs, touched[dofs], K[dofs][:, dofs].tocsr(), structure.M[dofs][:, dofs].tocsr()))
    if len(subs) < 2:
        raise RomError(f"{method}: needs at least two substructures, the model has {len(subs)}")
    return subs


def _split(total: int, parts: int) -> list[int]:
    return [total // parts + (1 if i < total % parts else 0) for i in range(parts)]


def _free_modes(sub: _Sub, num: int, method: str):
    try:
        w2, Phi = eigen(sub.K, sub.M, num, what=f"{method}: substructure {sub.id}")
        lu = Factorized(sub.K, what=f"{method}: stiffness of substructure {sub.id}")
    except LinAlgError as exc:
        raise RomError(str(exc)) from exc
    if w2.size and w2[0] <= 1e-8 * max(w2[-1], 1e-300):
        raise RomError(f"{method}: substructure {sub.id} has rigid-body modes (free-free): residual flexibility "
                       f"needs supports; use cb, cc, tvd or penalty")
    return w2, Phi, lu


def _residual_flexibility(lu, Phi, w2, X):
    """(K^-1 - Phi diag(1/w2) Phi^T) X: the static response the kept free modes miss.  (Next to
    Phi, its span is that of [Phi, K^-1 X] whatever the accuracy of the modes; the filtered form
    K^-1 (X - M Phi Phi^T X) is not, and put the Rubin ROM's first frequency 1.6e-5 below the
    full model's, which no Galerkin projection can.)"""
    return lu.solve(X) - Phi @ ((Phi.T @ X) / w2[:, None])


def craig_bampton_basis(structure: Structure, options: RomOptions, method: str = "cb"):
    subs = substructures(structure, method)
    n = structure.num_dofs
    modes, statics = [], []
    for sub, num in zip(subs, _split(options.modes, len(subs))):
        Kii, Mii = sub.K[sub.i][:, sub.i], sub.M[sub.i][:, sub.i]
        try:
            _, Phi = eigen(Kii, Mii, num, what=f"{method}: fixed-interface substructure {sub.id}")
            Psi = -Factorized(Kii, what=f"{method}: interior stiffness of substructure {sub.id}").solve(
                sub.K[sub.i][:, sub.b])
        except LinAlgError as exc:
            raise RomError(str(exc)) from exc
        Tm = np.zeros((n, num))
        Tm[sub.dofs[sub.i]] = Phi
        Ts = np.zeros((n, sub.b.size))
        Ts[sub.dofs[sub.i]] = Psi
        Ts[sub.dofs[sub.b], np.arange(sub.b.size)] = 1.0
        modes.append(Tm)
        statics.append(Ts)
    return np.hstack(modes), np.hstack(statics)


def craig_bampton(structure: Structure, options: RomOptions) -> ReducedModel:
    Tm, Ts = craig_bampton_basis(structure, options)
    return project(structure, np.hstack([Tm, Ts]), "cb", info={"modes": Tm.shape[1], "statics": Ts.shape[1]})


def _rubin_basis(structure: Structure, options: RomOptions, method: str):
    """Per substructure: its lowest free modes Phi and the residual-flexibility attachment modes A of
    unit forces at its boundary DOFs, each column scaled to unit mass norm.  (The same span as
    Rubin's form in the boundary DOFs, [Phi - A Abb^-1 Phi_b, A Abb^-1], in which the inverse of
    the boundary flexibility Abb, whose axial and bending entries differ by orders of magnitude on
    the beam, gave the reduced mass a condition of 6e15 (6-element beam, 7 modes per substructure)
    and the first frequency 2.2e-4 below the full model's.  The attachment modes are then made
    M-orthonormal to the kept modes and to each other, which leaves the span as it is and the
    reduced mass the identity to round-off.)"""
    subs = substructures(structure, method)
    n = structure.num_dofs
    Tm, Ts = [], []
    for sub, num in zip(subs, _split(options.modes, len(subs))):
        nb = sub.b.size
        if num == sub.dofs.size:
            # every free mode: the residual flexibility is zero and no attachment mode is left (the
            # complete basis; short of it, at most n - nb free modes leave room for the attachments)
            nb = 0
        elif num + nb > sub.dofs.size:
            raise RomError(f"{method}: substructure {sub.id} has {sub.dofs.size} DOFs, {nb} of them on its boundary: "
                           f"at most {sub.dofs.size - nb} free modes (asked for {num})")
        w2, Phi, lu = _free_modes(sub, num, method)
        E = np.zeros((sub.dofs.size, nb))
        E[sub.b[:nb], np.arange(nb)] = 1.0
        A = _residual_flexibility(lu, Phi, w2, E)  # attachment modes of unit boundary forces
        A = A / np.sqrt(np.einsum("ij,ij->j", A, sub.M @ A))
        # M-orthogonal to the kept modes (zero in exact arithmetic; the span of [Phi, A] is the same)
        A = A - Phi @ (Phi.T @ (sub.M @ A))
        gram, V = np.linalg.eigh(A.T @ (sub.M @ A)) if nb else (np.ones(1), None)
        if gram[0] <= 1e-10 * gram[-1]:
            # e.g. the straight beam: its axial and bending DOFs are decoupled, and the residual
            # flexibility at the 6 bending boundary DOFs has the rank of the bending modes left
            raise RomError(f"{method}: with {num} free modes, the residual flexibility at the {nb} boundary DOFs of "
                           f"substructure {sub.id} is rank deficient (Gram eigenvalue {gram[0]:.1e} of {gram[-1]:.1e}): "
                           f"fewer modes are left than boundary DOFs in some decoupled part of it; keep fewer modes")
        if nb:
            # M-orthonormal within their span: the reduced mass is then the identity to round-off,
            # not of condition 9e9 (6-element beam, 7 modes per substructure), whose eigenproblem
            # put frequencies up to 2.2e-5 below the full model's on an AMD EPYC's OpenBLAS
            A = A @ (V / np.sqrt(gram))
        blk_s = np.zeros((n, nb))
        blk_s[sub.dofs] = A
        blk_phi = np.zeros((n, num))
        blk_phi[sub.dofs] = Phi
        Tm.append(blk_phi)
        Ts.append(blk_s)
    return np.hstack(Tm), np.hstack(Ts)


def rubin(structure: Structure, options: RomOptions) -> ReducedModel:
    Tm, Ts = _rubin_basis(structure, options, "rubin")
    return project(structure, np.hstack([Tm, Ts]), "rubin", info={"modes": Tm.shape[1], "statics": Ts.shape[1]})


def macneal(structure: Structure, options: RomOptions) -> ReducedModel:
    """Rubin's basis; the reduced mass keeps only the inertia of the kept free modes."""
    Tm, Ts = _rubin_basis(structure, options, "macneal")
    T = np.hstack([Tm, Ts])
    MPhi_T = T.T @ (structure.M @ Tm)  # (q, modes); Phi^T M (residual flexibility) = 0
    return project(structure, T, "macneal", M_override=MPhi_T @ MPhi_T.T,
                   info={"modes": Tm.shape[1], "statics": Ts.shape[1]})


def dual_craig_bampton(structure: Structure, options: RomOptions) -> ReducedModel:
    """Rixen's dual Craig-Bampton (Int. J. Numer. Meth. Eng. 2004, "A dual Craig-Bampton method
    for dynamic substructuring"), with the joint's interface forces as unknowns.

    The joint is dual-assembled: every joint connection j (a contact component or a link) has a
    gap g_j, a Lagrange multiplier lambda_j (the interface force it puts on the substructures) and
    its law, so the full model is, exactly,

        M u'' + D u' + K_s u + C^T lambda = f     (K_s: the substructures, links taken out)
        C u - g = 0                                (compatibility of the gaps)
        -lambda + f_joint(g) = 0                   (the joint: contact law - f0, or k_link g)

    and each substructure's displacement is reduced to its lowest free modes plus the static
    response its residual flexibility gives to the interface forces: u = Phi eta - G_res C^T lambda,
    G_res = K_s^-1 - Phi diag(1/w2) Phi^T.  The reduced equations are the Galerkin projection of
    that extended system on T = [[Phi, -G_res C^T, 0], [0, I, 0], [0, 0, I]] (Rixen's DCB matrices
    with the joint's two rows): unknowns (eta, lambda, g), m + 2 J of them.  With every free mode,
    G_res = 0 and the reduction is the full model (tested).  The compatibility rows are multiplied
    by each connection's stiffness, which leaves the solution and puts every residual in N.  The
    reduced K is indefinite and its mass singular (g has none): a saddle point, which the HBM
    solves like any square system."""
    subs = substructures(structure, "dcb")
    C, k = joint_operator(structure)
    for g in structure.contacts:
        if g.load is not None:
            raise RomError("dcb: a contact group with its own load operator cannot be dual-assembled")
    n, J = structure.num_dofs, C.shape[0]
    Tm, Ta = [], np.zeros((n, J))
    for sub, num in zip(subs, _split(options.modes, len(subs))):
        w2, Phi, lu = _free_modes(sub, num, "dcb")
        blk = np.zeros((n, num))
        blk[sub.dofs] = Phi
        Tm.append(blk)
        Cs = C[:, sub.dofs].T.toarray()  # the interface force patterns on this substructure
        Ta[sub.dofs] = _residual_flexibility(lu, Phi, w2, Cs)
    Tm = np.hstack(Tm)
    m = Tm.shape[1]
    U = np.hstack([Tm, -Ta, np.zeros((n, J))])  # u of (eta, lambda, g)
    q = m + 2 * J
    lam, gap = np.arange(m, m + J), np.arange(m + J, q)
    El = sp.csr_matrix((np.ones(J), (np.arange(J), lam)), shape=(J, q))
    Eg = sp.csr_matrix((np.ones(J), (np.arange(J), gap)), shape=(J, q))
    Ks = structure.K - (structure.links.matrix if structure.links is not None else 0)
    CU = C @ U
    K = U.T @ (Ks @ U) + El.T @ CU + CU.T @ El - (El.T @ Eg + Eg.T @ El).toarray()
    num_links = 0 if structure.links is None else structure.links.stiffness.size
    if num_links:
        K[gap[J - num_links:], gap[J - num_links:]] += structure.links.stiffness
    # compatibility rows in N: times each connection's stiffness (the largest where it has none)
    s = np.where(k > 0, k, k.max() if k.max() > 0 else 1.0)
    S = np.ones(q)
    S[lam] = s
    Mr, Dr = U.T @ (structure.M @ U), U.T @ (structure.D @ U)
    check_basis(Tm, Mr[:m, :m], "dcb free modes")  # (lambda and g are no Ritz coordinates of u alone)
    rows, contacts = 0, []
    for g in structure.contacts:
        r = g.gap.shape[0]
        contacts.append(ContactGroup(g.pairs, sp.csr_matrix(Eg[rows:rows + r]), names=g.names, coords=g.coords,
                                     areas=g.areas))
        rows += r
    outputs = {name: U[dof].copy() for name, dof in structure.outputs.items()}
    red = Structure(K=sp.csr_matrix(S[:, None] * K), M=sp.csr_matrix(S[:, None] * Mr),
                    D=sp.csr_matrix(S[:, None] * Dr), fc=S * (U.T @ structure.fc), fs=S * (U.T @ structure.fs),
                    contacts=tuple(contacts),
                    dof_names=(*(f"dcb.eta{i}" for i in range(m)), *(f"dcb.lambda{j}" for j in range(J)),
                               *(f"dcb.g{j}" for j in range(J))),
                    outputs=outputs, info={"kind": "rom:dcb", "full_dofs": n},
                    f0=None if structure.f0 is None else S * (U.T @ structure.f0))
    return ReducedModel("dcb", red, U, n, info={"modes": m, "multipliers": J, "gaps": J}, indefinite=True)


def characteristic_constraint_modes(structure: Structure, options: RomOptions) -> ReducedModel:
    Tm, Ts = craig_bampton_basis(structure, options, "cc")
    nb = Ts.shape[1]
    C, _ = joint_operator(structure)
    num = options.interface_modes if options.interface_modes is not None else max(1, nb // 2)
    if not 1 <= num <= nb:
        raise RomError(f"cc: interface_modes = {num} must be in [1, {nb}] (the boundary DOFs)")
    Kb = Ts.T @ (structure.K_lin @ Ts)
    Mb = Ts.T @ (structure.M @ Ts)
    _, Q = eigen(Kb, Mb, num, what="cc: interface")
    return project(structure, np.hstack([Tm, Ts @ Q]), "cc", info={"modes": Tm.shape[1], "statics": num})


def mode_derivatives(structure: Structure, Phi: np.ndarray, w2: np.ndarray) -> np.ndarray:
    """d phi_i / d log k_j of the stuck modes, for every mode i and contact component j.

    For each mass-normalised mode phi_i of the stuck structure and each contact component j
    (stiffness k_j, gap row g_j), the exact derivative solves the bordered system
    [[K - w_i^2 M, M phi_i], [phi_i^T M, 0]] [v; c] = [-(k_j g_j^T g_j phi_i - dw2 M phi_i); 0],
    dw2 = k_j (g_j phi_i)^2.  Returns shape (n, modes, components).
    """
    n = structure.num_dofs
    G = sp.vstack([g.gap for g in structure.contacts]).tocsr()
    k = np.concatenate([g.pairs.stiffness.ravel() for g in structure.contacts])
    GT = G.T.toarray()
    K, M = structure.K_lin, structure.M
    out = np.empty((n, Phi.shape[1], k.size))
    for i in range(Phi.shape[1]):
        phi = Phi[:, i]
        Mphi = M @ phi
        gphi = G @ phi  # (J,)
        rhs = -(GT * (k * gphi) - np.outer(Mphi, k * gphi**2))
        A = sp.bmat([[K - w2[i] * M, sp.csr_matrix(Mphi[:, None])], [sp.csr_matrix(Mphi[None, :]), None]], format="csc")
        try:
            v = Factorized(A, what=f"TVD: bordered matrix of mode {i + 1}").solve(np.vstack([rhs, np.zeros((1, k.size))]))
        except LinAlgError as exc:
            raise RomError(f"{exc} (a repeated eigenvalue?)") from exc
        out[:, i] = v[:n]
    return out


def static_modal_derivatives(structure: Structure, Phi: np.ndarray, num: int) -> tuple[np.ndarray, np.ndarray]:
    """The paper's TVDs (Eq. 12), POD-compressed: K_lin^-1 (dK_lin/dq_j) b_i for every pair of
    vectors b_i, b_j of the linear basis (the stuck modes Phi and the static modes Psi of every
    contact component), minus their M-projection on Phi, in the M inner product.

    dK_lin/dq_j for contact springs: the stiffness k_c of component c is taken to change in
    proportion to its own gap, dk_c/dg_c = k_c / l (one length l for every component, which the
    POD's normalisation removes: the same relative softening as any spring nears slip or lift-off),
    so dK_lin/dq_j = sum_c (k_c / l) (g_c b_j) g_c^T g_c and

        K_lin^-1 (dK_lin/dq_j) b_i = (1 / l) sum_c (g_c b_i)(g_c b_j) psi_c,   psi_c = K_lin^-1 g_c^T k_c:

    every derivative is a combination of the static modes (dK_lin has rank one per component).
    Weighting: each b is scaled to a largest gap of 1 before its products are formed, so that a
    mode's mass normalisation and a static mode's unit p weigh alike; the POD then keeps what the
    pairs' gaps excite most.  The snapshots (s of them, s = q(q+1)/2 for q basis vectors) are
    never formed: with A = G [Phi, Psi] (J, q) and W the (J, s) weights, W W^T = (P o P + (A o A)
    (A o A)^T) / 2 with P = A A^T (o: elementwise), a J x J matrix.
    Returns (num vectors, M-orthonormal and M-orthogonal to Phi; the singular values)."""
    n = structure.num_dofs
    if num == 0:
        return np.zeros((n, 0)), np.zeros(0)
    G = sp.vstack([g.gap for g in structure.contacts]).tocsr()
    k = np.concatenate([g.pairs.stiffness.ravel() for g in structure.contacts])
    Kl, M = structure.K_lin, structure.M
    try:
        Psi = Factorized(Kl, what="tvd (eq12): K_lin").solve(G.T.toarray() * k)  # (n, J)
    except LinAlgError as exc:
        raise RomError(str(exc)) from exc
    A = G @ np.hstack([Phi, Psi])  # (J, q): the gaps of every basis vector
    top = np.abs(A).max(axis=0)
    A = A / np.where(top > 0, top, 1.0)
    P = A @ A.T
    A2 = A * A
    WW = 0.5 * (P * P + A2 @ A2.T)  # (J, J)
    Z = Psi - Phi @ (Phi.T @ (M @ Psi))  # the static modes, less their M-projection on Phi
    lam, Q = np.linalg.eigh(0.5 * (Z.T @ (M @ Z) + (Z.T @ (M @ Z)).T))
    keep = lam > 1e-12 * max(lam.max(), 1e-300)
    Y = Z @ (Q[:, keep] / np.sqrt(lam[keep]))  # M-orthonormal basis of their span
    R = np.sqrt(lam[keep])[:, None] * Q[:, keep].T  # Z = Y R
    C = R @ WW @ R.T
    s2, U = np.linalg.eigh(0.5 * (C + C.T))
    order = np.argsort(s2)[::-1]
    s2, U = np.clip(s2[order], 0.0, None), U[:, order]
    sv = np.sqrt(s2)
    avail = int(np.sum(s2 > 1e-12 * s2[0])) if s2.size and s2[0] > 0 else 0
    if avail < num:
        raise RomError(f"tvd (eq12): only {avail} independent trial-vector derivatives exist, {num} asked")
    return Y @ U[:, :num], sv


TVD_KINDS = ("eigen", "eq12")


def trial_vector_derivatives(structure: Structure, Phi: np.ndarray, w2: np.ndarray, num: int,
                             against: np.ndarray | None = None, kind: str = "eigen") -> tuple[np.ndarray, np.ndarray]:
    """``num`` POD-compressed trial-vector derivatives of the stuck modes Phi: ``kind`` "eigen",
    the exact eigenvector derivatives with respect to the stiffness of each contact component
    (mode_derivatives: one per mode and component before POD), in the M inner product, after
    removing their M-projection on ``against`` (default Phi); "eq12", the paper's static modal
    derivatives (static_modal_derivatives).  Returns (num vectors, all singular values)."""
    if kind not in TVD_KINDS:
        raise RomError(f"tvd_kind = {kind!r}: choose from {', '.join(TVD_KINDS)}")
    if num == 0:
        return np.zeros((structure.num_dofs, 0)), np.zeros(0)
    if kind == "eq12":
        return static_modal_derivatives(structure, Phi, num)
    D = mode_derivatives(structure, Phi, w2)
    V = D.reshape(D.shape[0], -1)
    vecs, sv = pod(V, structure.M, num, against=Phi if against is None else against)
    if vecs.shape[1] < num:
        raise RomError(f"tvd: only {vecs.shape[1]} independent trial-vector derivatives exist, {num} asked")
    return vecs, sv


def tvd_method(structure: Structure, options: RomOptions) -> ReducedModel:
    w2, Phi = eigen(structure.K_lin, structure.M, options.modes, what="tvd: stuck structure")
    V, sv = trial_vector_derivatives(structure, Phi, w2, options.tvd, kind=options.tvd_kind)
    return project(structure, np.hstack([Phi, V]), "tvd",
                   info={"modes": Phi.shape[1], "tvd": V.shape[1], "tvd_kind": options.tvd_kind,
                         "tvd_singular_values": sv[:10].tolist()})
