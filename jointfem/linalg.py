"""Sparse/dense linear algebra for the offline stage (scipy backend).

Only this module, the mesh and the fem modules may touch an eigen- or linear-solver
package directly; the PETSc/SLEPc backend of the continuum models plugs in here.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

DENSE_LIMIT = 2500  # dense eigh below this many DOFs: exact and fast enough


class LinAlgError(RuntimeError):
    """An offline solve failed (singular matrix, unconverged eigenvalues)."""


def eigen(K, M, num: int, *, what: str = "model") -> tuple[np.ndarray, np.ndarray]:
    """The ``num`` lowest eigenpairs of K phi = w^2 M phi, mass-normalised.

    Returns (w2 ascending, Phi of shape (n, num)).  Raises LinAlgError if fewer exist.
    """
    n = K.shape[0]
    if num < 1:
        return np.zeros(0), np.zeros((n, 0))
    if num > n:
        raise LinAlgError(f"{what}: {num} modes asked, but it has only {n} DOFs")
    if n <= DENSE_LIMIT or num >= n - 1:
        Kd = K.toarray() if sp.issparse(K) else np.asarray(K)
        Md = M.toarray() if sp.issparse(M) else np.asarray(M)
        # The inverse problem M phi = (1/w2) K phi resolves the lowest modes to machine precision
        # relative to themselves (the direct one only relative to the stiffest mode: 1e-7 on the
        # beam) and admits a singular M (MacNeal's reduced mass).  Rigid-body modes make K singular:
        # then the direct problem.
        try:
            mu, V = sla.eigh(Md, Kd, subset_by_index=[n - num, n - 1])
            mu, V = mu[::-1], V[:, ::-1]
            if mu[-1] <= 0:
                raise LinAlgError(f"{what}: only {int(np.sum(mu > 0))} finite eigenvalues, {num} asked")
            w2, Phi = 1.0 / mu, V
        except np.linalg.LinAlgError:
            try:
                w2, Phi = sla.eigh(Kd, Md, subset_by_index=[0, num - 1])
            except np.linalg.LinAlgError as exc:
                raise LinAlgError(f"{what}: neither K nor M is positive definite") from exc
    else:
        w2, Phi = spla.eigsh(sp.csc_matrix(K), k=num, M=sp.csc_matrix(M), sigma=0.0, which="LM")
        order = np.argsort(w2)
        w2, Phi = w2[order], Phi[:, order]
    # mass-normalise (eigh already does; eigsh nearly) and fix the sign for reproducibility
    Mphi = M @ Phi
    Phi = Phi / np.sqrt(np.einsum("ij,ij->j", Phi, Mphi))
    sign = np.sign(Phi[np.argmax(np.abs(Phi), axis=0), np.arange(Phi.shape[1])])
    return w2, Phi * sign


class Factorized:
    """A sparse LU of a square matrix, with a clear error when it is singular."""

    def __init__(self, A, *, what: str = "matrix"):
        self.what = what
        A = sp.csc_matrix(A)
        try:
            self._lu = spla.splu(A)
        except RuntimeError as exc:
            raise LinAlgError(f"{what} is singular ({exc}): a substructure without supports "
                              f"(rigid-body modes) cannot be factorised") from exc
        d = np.abs(self._lu.U.diagonal())
        if d.size and d.min() <= 1e-13 * d.max():
            raise LinAlgError(f"{what} is numerically singular (pivot ratio {d.min() / d.max():.1e}): "
                              f"a substructure without supports (rigid-body modes)?")

    def solve(self, B: np.ndarray) -> np.ndarray:
        B = B.toarray() if sp.issparse(B) else np.asarray(B, dtype=float)
        return self._lu.solve(B)


def pod(V: np.ndarray, M, num: int, against: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The ``num`` dominant POD vectors of the snapshots V in the M inner product, after removing
    their M-projection on ``against``.  Returns (vectors M-orthonormal, singular values, all)."""
    if against is not None and against.size:
        V = V - against @ (against.T @ (M @ V))
    C = V.T @ (M @ V)
    C = 0.5 * (C + C.T)
    s, W = np.linalg.eigh(C)
    order = np.argsort(s)[::-1]
    s, W = np.clip(s[order], 0.0, None), W[:, order]
    num = min(num, int(np.sum(s > 1e-12 * s[0])) if s.size and s[0] > 0 else 0)
    return (V @ W[:, :num]) / np.sqrt(s[:num]), np.sqrt(s)
