"""The jointed continuum kept distributed (issue 17): K, M and K_lin stay the PETSc matrices that
dolfinx assembled, in dolfinx's own DOF numbering and row ownership, and nothing of the size of
the model is gathered onto a rank.

What crosses the ranks is of the size of the interface or smaller: the contact nodes of both faces
(matched into pairs on every rank), the node a force or an output sits on, counts.  Clamped DOFs
are not eliminated, which would renumber the distributed matrices, but made identity rows of K
and zero rows of M: their eigenvalues are infinite, far from the shift-invert target, and every
mode and static mode is zero there, so the reduced model is the one of the eliminated DOFs
(tests/test_distributed.py checks it against the replicated model to 1e-8).

Supported: jointed geometries (lap, stack) with clamps, a uniform pressure and bolt patches on the
interface (preload = "uniform"); checked against the replicated model on the 2D and 3D lap joints.  The static preload solve, initial gaps and soft supports
still need the replicated model (jointfem.fem.continuum), and say so.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..contact.jenkins import JenkinsPairs
from ..linalg import allgather_rows, allreduce
from . import compat
from . import geometry as geo
from .continuum import (COMPONENTS, ContinuumError, ContinuumSpec, _substructure_of_blocks, assemble, frames,
                        gap_entries, pair_springs)


@dataclass
class DistributedModel:
    """The jointed continuum with K, M and K_lin as distributed PETSc matrices (rows r0 to r1 on
    this rank of n), the contact pairs replicated (their laws, names, positions, areas) and the
    gap operator as this rank's columns ``gap_local`` (J, r1 - r0).  Forces and outputs sit on
    single rows (global indices)."""

    K: object  # PETSc Mat: elastic stiffness, N/m (clamped rows: identity)
    M: object  # PETSc Mat, kg (clamped rows: zero)
    K_lin: object  # PETSc Mat: K with every contact pair stuck, N/m
    n: int  # rows of the matrices (free and clamped DOFs)
    rows: tuple[int, int]
    comm: object  # mpi4py
    pairs: JenkinsPairs
    gap_local: sp.csr_matrix
    names: tuple[str, ...]
    coords: np.ndarray  # (P, 3) A-side node positions, m
    areas: np.ndarray  # (P,) m^2
    force: tuple[int, float]  # (row, N): the harmonic force's amplitude (cosine)
    outputs: dict[str, int]  # name -> row
    rayleigh: tuple[float, float]  # D = alpha M + beta K
    info: dict = field(default_factory=dict)

    @property
    def num_dofs(self) -> int:
        """Unknowns of the model once its clamped DOFs are eliminated (as the replicated one counts)."""
        return int(self.info["free_dofs"])

    def destroy(self) -> None:
        for A in (self.K, self.M, self.K_lin):
            A.destroy()


def _refuse(spec: ContinuumSpec) -> None:
    why = []
    if spec.preload == "static":
        why.append('preload = "static" (the static contact solve)')
    if spec.gap is not None:
        why.append("[contact.gap] (initial gaps)")
    if spec.supports:
        why.append("[[support]] springs")
    if spec.geometry == "brb":
        why.append('geometry = "brb"')
    if why:
        raise ContinuumError(f"{spec.source}: the distributed offline stage does not take {', '.join(why)} yet: "
                             f"run without it (the replicated model)")


def _nearest_row(X, gid, sub, free_nodes, point, comp, d, key_scale, comm, what, source):
    """Global row of the free node nearest ``point`` (ties: the lowest (substructure, z, y, x), the
    replicated model's canonical order), from each rank's best candidate."""
    if comp not in COMPONENTS[:d]:
        raise ContinuumError(f"{source}: {what}: component {comp!r} is not one of {COMPONENTS[:d]}")
    p = np.zeros(3)
    p[:len(point)] = point
    cand = np.full((1, 6), np.inf)
    if free_nodes.size:
        dist = np.linalg.norm(X[free_nodes] - p, axis=1)
        key = np.round(X[free_nodes] / key_scale)
        order = np.lexsort((key[:, 0], key[:, 1], key[:, 2], sub[free_nodes], dist))
        i = free_nodes[order[0]]
        cand[0] = [dist[order[0]], sub[i], key[order[0], 2], key[order[0], 1], key[order[0], 0], gid[i]]
    allc = allgather_rows(comm, cand)
    best = allc[np.lexsort(allc[:, :5][:, ::-1].T)[0]]
    return int(d * best[5] + COMPONENTS.index(comp)), np.asarray(best[1:5])


def create_distributed(spec: ContinuumSpec, comm=None) -> DistributedModel:
    """The jointed continuum of ``spec`` kept distributed (see the module's docstring)."""
    import ufl
    from mpi4py import MPI
    from petsc4py import PETSc

    comm = comm or MPI.COMM_WORLD
    _refuse(spec)
    asm = assemble(spec, comm)
    t0 = time.perf_counter()
    layout, V, facet_tags, d = asm.layout, asm.V, asm.facet_tags, asm.layout.dim
    K, M = asm.K, asm.M
    gid, X = compat.owned_blocks(V)
    n_own = gid.size
    sub = _substructure_of_blocks(V, asm.cell_tags)[:n_own]
    r0, r1 = K.getOwnershipRange()
    n = K.getSize()[0]
    if n_own and (r0, r1) != (d * int(gid[0]), d * (int(gid[0]) + n_own)):
        raise ContinuumError(f"{spec.source}: the matrix rows are not the vector space's blocks")

    def owned_nodes(tag):
        loc = compat.facet_blocks(V, facet_tags, tag)
        return np.unique(loc[loc < n_own])

    clamped = np.unique(np.concatenate([owned_nodes(t) for t in (geo.CLAMP_A, geo.CLAMP_B)])) \
        if facet_tags is not None else np.zeros(0, dtype=np.int64)
    clamped_rows = (d * gid[clamped][:, None] + np.arange(d)).ravel().astype(PETSc.IntType)
    K.zeroRowsColumns(clamped_rows, 1.0)
    M.zeroRowsColumns(clamped_rows, 0.0)
    num_clamped = int(allreduce(comm, np.array([clamped_rows.size]))[0])

    # the contact faces: each rank's owned nodes, then the whole interface on every rank (O(pairs))
    if layout.contact is None:
        raise ContinuumError(f"{spec.source}: the distributed offline stage is for jointed models: this one has no "
                             f"contact interface")
    ds = ufl.Measure("ds", domain=asm.mesh, subdomain_data=facet_tags)
    v = ufl.TestFunction(V)
    e0 = ufl.as_vector([1.0] + [0.0] * (d - 1))
    nrm = ufl.FacetNormal(asm.mesh)
    is_clamped = np.zeros(n_own, bool)
    is_clamped[clamped] = True
    faces = []
    for tag in (geo.CONTACT_A, geo.CONTACT_B):
        nodes = owned_nodes(tag)
        area = compat.assemble_vector(asm.thick * ufl.inner(v, e0) * ds(tag))[:d * n_own].reshape(-1, d)[:, 0]
        normal = compat.assemble_vector(asm.thick * ufl.inner(v, nrm) * ds(tag))[:d * n_own].reshape(-1, d)
        normal3 = np.zeros((nodes.size, 3))
        normal3[:, :d] = normal[nodes]
        faces.append(allgather_rows(comm, np.column_stack([gid[nodes], X[nodes], area[nodes], normal3,
                                                           is_clamped[nodes]])))
    fa, fb = faces
    if fa.shape[0] == 0 or fb.shape[0] == 0:
        raise ContinuumError(f"{spec.source}: the contact surface is empty (A has {fa.shape[0]} nodes, B has "
                             f"{fb.shape[0]}): the substructures do not overlap")
    q = 1e-9 * layout.extent
    key = np.round(fa[:, 1:4] / q)
    fa = fa[np.lexsort((key[:, 0], key[:, 1], key[:, 2]))]  # the replicated model's canonical order of A's nodes
    from scipy.spatial import cKDTree

    tol = 1e-10 * layout.extent
    dist, j = cKDTree(fb[:, 1:4]).query(fa[:, 1:4])
    if fa.shape[0] != fb.shape[0] or np.any(dist > tol) or np.unique(j).size != j.size:
        raise ContinuumError(f"{spec.source}: the contact surfaces do not match node to node: A has {fa.shape[0]} "
                             f"nodes, B has {fb.shape[0]} (worst distance {float(dist.max()):.3e} m)")
    fb = fb[j]
    area = 0.5 * (fa[:, 4] + fb[:, 4])
    if np.any(area <= 0):
        raise ContinuumError(f"{spec.source}: {int(np.sum(area <= 0))} contact nodes have zero area: use structured "
                             f"quadrilateral/hexahedral elements or degree = 1")
    keep, N0, kt, kn = pair_springs(spec, fa[:, [1, 3]], area)
    fa, fb, area = fa[keep], fb[keep], area[keep]
    P = fa.shape[0]
    pairs = JenkinsPairs(kt=kt, kn=kn, mu=np.full(P, spec.mu), N0=N0, num_tangential=d - 1, has_normal=True)
    a, b = fa[:, 0].astype(np.int64), fb[:, 0].astype(np.int64)
    vals, (rows, cols) = gap_entries(a, b, frames(fa[:, 5:8], d))
    held = np.repeat(np.concatenate([np.repeat(fa[:, 8:9] > 0, d, axis=1), np.repeat(fb[:, 8:9] > 0, d, axis=1)],
                                    axis=1)[:, None, :], d, axis=1).ravel()  # clamped DOFs drop out, as eliminated
    vals = np.where(held, 0.0, vals)
    J = P * d
    mine = (cols >= r0) & (cols < r1)
    gap_local = sp.csr_matrix((vals[mine], (rows[mine], cols[mine] - r0)), shape=(J, r1 - r0))
    # K_lin = K + G^T Kc G: this rank's rows of the pairs' springs, added to K in one merge
    kc = pairs.stiffness.ravel()
    per_pair = 2 * d
    G3 = vals.reshape(P, d, per_pair) * np.sqrt(kc).reshape(P, d, 1)
    blocks = np.einsum("pia,pib->pab", G3, G3)  # (P, 2d, 2d)
    dofs = cols.reshape(P, d, per_pair)[:, 0, :]
    br = np.broadcast_to(dofs[:, :, None], blocks.shape).ravel()
    bc = np.broadcast_to(dofs[:, None, :], blocks.shape).ravel()
    own = (br >= r0) & (br < r1)
    C = sp.csr_matrix((blocks.ravel()[own], (br[own] - r0, bc[own])), shape=(r1 - r0, n))
    C.sum_duplicates()
    C.sort_indices()
    Cp = PETSc.Mat().createAIJ(size=((r1 - r0, n), (r1 - r0, n)), csr=(C.indptr.astype(PETSc.IntType),
                               C.indices.astype(PETSc.IntType), C.data), comm=PETSc.COMM_WORLD)
    Cp.assemble()
    K_lin = K.duplicate(copy=True)
    K_lin.axpy(1.0, Cp, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    Cp.destroy()

    free_nodes = np.flatnonzero(~is_clamped)
    args = (X, gid, sub, free_nodes)
    frow, _ = _nearest_row(*args, spec.force_at, spec.force_dir, d, q, comm, "[force]", spec.source)
    outputs = {f"{name}.{comp}": _nearest_row(*args, point, comp, d, q, comm, f"[output].{name}", spec.source)[0]
               for name, point, comp in spec.outputs}
    info = {"kind": f"continuum{d}d", "geometry": spec.geometry, "free_dofs": n - num_clamped, "matrix_rows": n,
            "offline": "distributed", "mpi_ranks": comm.size, "nodes": n // d,
            "cells": int(asm.mesh.topology.index_map(d).size_global), "degree": spec.degree,
            "timings": dict(asm.timings, contact_s=time.perf_counter() - t0),
            "num_pairs": int(P), "contact_area_m2": float(area.sum()), "preload_N": float(np.maximum(N0, 0).sum())}
    return DistributedModel(K, M, K_lin, n, (r0, r1), comm, pairs, gap_local, tuple(f"pair{p}" for p in range(P)),
                            fa[:, 1:4].copy(), area, (frow, spec.force), outputs,
                            (spec.rayleigh_alpha, spec.rayleigh_beta), info)
