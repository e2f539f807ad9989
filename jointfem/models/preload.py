"""The static preload of a joint: the nonlinear static contact problem under bolt loads.

    K u + G^T f(G u) = F,     f_n = kn max(g_n - g0, 0),     f_t = kt g_t while closed, 0 while open,

with G the pairs' gap operator (local frames: tangential components, then the normal), g_n > 0
an approach (compression; the Jenkins law's N = N0 + kn g_n) and g0 >= 0 each pair's initial gap
from the geometry (a crowned or measured interface; 0 for flat faces).  The normal law is unilateral;
tangentially each closed pair holds by its stuck spring throughout the preload (the loading
path: the bolts tighten proportionally and nothing slips), which also holds a body that only the
joint supports.  The problem is piecewise linear, so Newton with an active set on the closed
pairs is exact once the set stops changing.

What the dynamic problem takes from it (fem.continuum, ``[contact] preload = "static"``): per pair
N0 = kn (g_n - g0): the normal force of a closed pair, and for an open one -kn times its static
gap g0 - g_n (contact.jenkins: open at rest until the motion closes it).  The static
tangential forces are not carried into the dynamics (the slider starts unloaded); their largest
ratio to mu N is reported, so that a user can see how far the preload is from slipping.

Plain NumPy/SciPy: the continuum layer hands over K, G and F.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..linalg import Factorized, LinAlgError


@dataclass(frozen=True)
class StaticContact:
    u: np.ndarray  # (n,) static displacement, m
    gaps: np.ndarray  # (P, m) local relative displacement, m (normal last: > 0 approach)
    force: np.ndarray  # (P, m) contact force, N (normal last: compression positive)
    closed: np.ndarray  # (P,) bool
    kn: np.ndarray  # (P,) N/m
    iterations: int
    g0: np.ndarray | None = None  # (P,) the geometric initial gaps, m (None: flat faces)

    @property
    def N0(self) -> np.ndarray:
        """The dynamic law's N0 per pair, kn (g_n - g0): the normal force of a closed pair, -kn
        times the static gap of an open one."""
        return self.kn * (self.gaps[:, -1] - (0.0 if self.g0 is None else self.g0))

    def tangential_use(self, mu: np.ndarray) -> np.ndarray:
        """|f_t| / (mu N) per closed pair (0 for open ones): above 1 the preload itself would slip."""
        ft = np.linalg.norm(self.force[:, :-1], axis=1)
        lim = mu * self.force[:, -1]
        return np.where(self.closed & (lim > 0), ft / np.where(lim > 0, lim, 1.0), 0.0)


def solve_static_contact(K: sp.spmatrix, G: sp.spmatrix, kt: np.ndarray, kn: np.ndarray, F: np.ndarray, *,
                         num_tangential: int, g0: np.ndarray | None = None, max_iter: int = 50,
                         what: str = "static preload") -> StaticContact:
    """Solve K u + G^T f(G u) = F for pairs with ``num_tangential`` tangential components and a
    normal one (rows of G per pair: t1, [t2], n), stiffnesses kt, kn (N/m) and initial gaps g0 (m,
    default 0) per pair.  Raises LinAlgError naming ``what`` when the active set cycles or a system
    is singular."""
    P = kt.size
    m = num_tangential + 1
    if G.shape[0] != P * m:
        raise ValueError(f"{what}: G has {G.shape[0]} rows, expected {P} pairs x {m}")
    k = np.column_stack([np.repeat(kt[:, None], num_tangential, axis=1), kn])  # (P, m)
    offset = np.zeros((P, m))  # f = k (g - offset) on a closed pair
    if g0 is not None:
        offset[:, -1] = g0
    closed = np.ones(P, bool)  # all closed first: a body that only the joint holds stays held
    seen = set()
    G = sp.csr_matrix(G)
    for it in range(1, max_iter + 1):
        kc = (k * closed[:, None]).ravel()
        Kt = (K + G.T @ sp.diags(kc) @ G).tocsc()
        rhs = F + G.T @ (kc * offset.ravel())
        u = Factorized(Kt, what=f"{what}: the stiffness with {int(closed.sum())} of {P} pairs closed").solve(rhs)
        g = (G @ u).reshape(P, m)
        new = g[:, -1] > offset[:, -1]
        if np.array_equal(new, closed):
            force = k * (g - offset) * closed[:, None]
            return StaticContact(u, g, force, closed, np.asarray(kn, float), it,
                                 None if g0 is None else np.asarray(g0, float))
        key = new.tobytes()
        if key in seen:
            raise LinAlgError(f"{what}: the set of closed pairs cycles after {it} iterations "
                              f"({int(new.sum())} of {P} closed): no static contact state found")
        seen.add(key)
        closed = new
    raise LinAlgError(f"{what}: the set of closed pairs still changes after {max_iter} iterations")
