"""The paper's jointed beam (Sec. 5, Fig. 3): two 2D Euler-Bernoulli frame beams, DOFs
(ux, uy, rz) per node, each clamped at its outer end, overlapping at the joint.

Geometry (all SI): beam 1 runs from x = 0 to x = L along y = 0, clamped at x = 0.
Beam 2 lies on top of it (centroid at y = h) from x = L - L_o to x = 2L - L_o,
clamped at its right end.  The overlap L_o spans ``num_pairs - 1`` elements and
its ``num_pairs`` coincident node pairs carry a Jenkins element each:

* tangential gap (along x) between the contact faces, with the half-height
  lever arms of both beams: g_t = (ux1 - h/2 rz1) - (ux2 + h/2 rz2);
* normal gap, compression positive: g_n = uy1 - uy2, N = N0 + kn g_n;
* a linear rotational spring kr between rz1 and rz2.

kt, kn, kr, mu and N0 are per pair.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..contact.jenkins import JenkinsPairs
from .structure import ContactGroup, Links, Structure

COMPONENTS = ("ux", "uy", "rz")


@dataclass(frozen=True)
class Beam2DSpec:
    length: float = 0.3  # m, each beam
    width: float = 0.025  # m
    height: float = 0.006  # m
    density: float = 7850.0  # kg/m^3
    young: float = 2.1e11  # Pa
    elements: int = 20  # per beam
    num_pairs: int = 3  # joint node pairs (overlap = num_pairs - 1 elements)
    kt: float = 1e4  # N/m per pair
    kn: float = 5e6  # N/m per pair
    kr: float = 8e6  # N m/rad per pair
    mu: float = 0.3
    N0: float = 20.0  # N per pair
    damping: str = "modal"  # "modal" or "rayleigh"
    modal_ratio: float = 0.005
    rayleigh_alpha: float = 0.0  # 1/s
    rayleigh_beta: float = 0.0  # s
    force: float = 1.0  # N, amplitude of the y force at the middle of beam 1 (cos)
    outputs: tuple[str, ...] = ("b1.mid.uy",)


def element_matrices(E: float, A: float, I: float, rho: float, le: float) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness and consistent mass of a 2D Euler-Bernoulli frame element, DOFs (ux, uy, rz) x 2."""
    k = np.zeros((6, 6))
    ea, ei = E * A / le, E * I
    k[np.ix_([0, 3], [0, 3])] = ea * np.array([[1, -1], [-1, 1]])
    b = [1, 2, 4, 5]
    k[np.ix_(b, b)] = ei / le**3 * np.array(
        [[12, 6 * le, -12, 6 * le], [6 * le, 4 * le**2, -6 * le, 2 * le**2],
         [-12, -6 * le, 12, -6 * le], [6 * le, 2 * le**2, -6 * le, 4 * le**2]])
    m = np.zeros((6, 6))
    ma = rho * A * le
    m[np.ix_([0, 3], [0, 3])] = ma / 6 * np.array([[2, 1], [1, 2]])
    m[np.ix_(b, b)] = ma / 420 * np.array(
        [[156, 22 * le, 54, -13 * le], [22 * le, 4 * le**2, 13 * le, -3 * le**2],
         [54, 13 * le, 156, -22 * le], [-13 * le, -3 * le**2, -22 * le, 4 * le**2]])
    return k, m


def assemble_beam(spec: Beam2DSpec, num_nodes: int) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """K and M of one free beam with ``num_nodes`` nodes (3 DOFs each)."""
    A = spec.width * spec.height
    I = spec.width * spec.height**3 / 12.0
    le = spec.length / (num_nodes - 1)
    ke, me = element_matrices(spec.young, A, I, spec.density, le)
    ne = num_nodes - 1
    dofs = (3 * np.arange(ne)[:, None] + np.arange(6)[None, :])
    rows = np.repeat(dofs, 6, axis=1).ravel()
    cols = np.tile(dofs, (1, 6)).ravel()
    n = 3 * num_nodes
    K = sp.csr_matrix((np.tile(ke.ravel(), ne), (rows, cols)), shape=(n, n))
    M = sp.csr_matrix((np.tile(me.ravel(), ne), (rows, cols)), shape=(n, n))
    return K, M


def dof_names(spec: Beam2DSpec) -> tuple[str, ...]:
    """Free DOF names, 'b{beam}.{node}.{comp}' (clamped nodes removed)."""
    ne = spec.elements
    names = [f"b1.{i}.{c}" for i in range(1, ne + 1) for c in COMPONENTS]
    names += [f"b2.{i}.{c}" for i in range(0, ne) for c in COMPONENTS]
    return tuple(names)


def resolve_dof(spec: Beam2DSpec, name: str) -> str:
    """Expand the aliases 'b1.mid.uy', 'b2.mid.rz', 'b1.tip.uy' (free end at the joint) to node names."""
    parts = name.split(".")
    if len(parts) == 3 and parts[1] in ("mid", "tip"):
        ne = spec.elements
        beam = parts[0]
        if parts[1] == "mid":
            node = ne // 2
        else:
            node = ne if beam == "b1" else 0
        return f"{beam}.{node}.{parts[2]}"
    return name


def create_beam2d(spec: Beam2DSpec) -> Structure:
    """The jointed beam as a Structure (clamped DOFs eliminated)."""
    ne, npair = spec.elements, spec.num_pairs
    nn = ne + 1
    K1, M1 = assemble_beam(spec, nn)
    K = sp.block_diag([K1, K1]).tocsr()
    M = sp.block_diag([M1, M1]).tocsr()
    n_all = 6 * nn
    off2 = 3 * nn

    def dof(beam: int, node: int, comp: int) -> int:
        return (0 if beam == 1 else off2) + 3 * node + comp

    # Joint: beam-1 nodes ne-npair+1..ne coincide with beam-2 nodes 0..npair-1.
    h2 = spec.height / 2
    rows, cols, vals = [], [], []
    kr_rows, kr_cols = [], []
    for p in range(npair):
        a, b = ne - npair + 1 + p, p
        r = 2 * p
        rows += [r] * 4
        cols += [dof(1, a, 0), dof(1, a, 2), dof(2, b, 0), dof(2, b, 2)]
        vals += [1.0, -h2, -1.0, -h2]
        rows += [r + 1] * 2
        cols += [dof(1, a, 1), dof(2, b, 1)]
        vals += [1.0, -1.0]
        kr_rows.append(dof(1, a, 2))
        kr_cols.append(dof(2, b, 2))
    gap_all = sp.csr_matrix((vals, (rows, cols)), shape=(2 * npair, n_all))
    Lr = sp.csr_matrix((np.r_[np.ones(npair), -np.ones(npair)], (np.r_[np.arange(npair), np.arange(npair)],
                        np.r_[kr_rows, kr_cols])), shape=(npair, n_all))
    K = (K + spec.kr * (Lr.T @ Lr)).tocsr()

    clamped = np.r_[[dof(1, 0, c) for c in range(3)], [dof(2, ne, c) for c in range(3)]]
    free = np.setdiff1d(np.arange(n_all), clamped)
    K, M = K[free][:, free].tocsr(), M[free][:, free].tocsr()
    gap = gap_all[:, free].tocsr()
    names = dof_names(spec)
    index = {nm: i for i, nm in enumerate(names)}

    fc = np.zeros(free.size)
    fc[index[f"b1.{ne // 2}.uy"]] = spec.force
    pairs = JenkinsPairs(kt=np.full(npair, spec.kt), kn=np.full(npair, spec.kn), mu=np.full(npair, spec.mu),
                         N0=np.full(npair, spec.N0), num_tangential=1, has_normal=True)
    le = spec.length / ne
    x = spec.length - (npair - 1) * le + le * np.arange(npair)
    coords = np.column_stack([x, np.full(npair, h2), np.zeros(npair)])
    group = ContactGroup(pairs, gap, names=tuple(f"pair{p}" for p in range(npair)), coords=coords)

    if spec.damping == "rayleigh":
        D = (spec.rayleigh_alpha * M + spec.rayleigh_beta * K).tocsr()
    else:
        D = modal_damping(K + group.stuck_stiffness, M, spec.modal_ratio)
    outputs = {nm: index[resolve_dof(spec, nm)] for nm in spec.outputs}
    substructure = (free >= off2).astype(np.int32)  # 0: beam 1, 1: beam 2
    links = Links(Lr[:, free].tocsr(), np.full(npair, spec.kr))
    return Structure(K=K, M=M, D=D, fc=fc, fs=np.zeros_like(fc), contacts=(group,), dof_names=names,
                     outputs=outputs, info={"kind": "beam2d", "free_dofs": int(free.size)},
                     substructure=substructure, links=links)


def modal_damping(K: sp.spmatrix, M: sp.spmatrix, ratio: float) -> sp.csr_matrix:
    """D = M Phi diag(2 zeta omega) Phi^T M with mass-normalised modes of (K, M): every mode gets ``ratio``."""
    w2, Phi = sla.eigh(K.toarray(), M.toarray())
    w = np.sqrt(np.clip(w2, 0.0, None))
    MPhi = M @ Phi
    return sp.csr_matrix((MPhi * (2.0 * ratio * w)) @ MPhi.T)


def cantilever_frequencies(spec: Beam2DSpec, num: int = 4) -> np.ndarray:
    """First ``num`` bending frequencies (rad/s) of one beam clamped at x = 0 (FE), for validation."""
    K1, M1 = assemble_beam(spec, spec.elements + 1)
    bending = np.flatnonzero(np.arange(K1.shape[0]) % 3 != 0)  # (uy, rz): axial is uncoupled
    free = bending[bending >= 3]  # node 0 clamped
    w2 = sla.eigh(K1[free][:, free].toarray(), M1[free][:, free].toarray(), eigvals_only=True)
    return np.sqrt(w2[:num])
