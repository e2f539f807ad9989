"""Lumped models: point masses with 1-3 DOFs (x, y, z), springs and dampers between DOFs
or to ground, Jenkins elements between nodes or to ground, cubic springs and unilateral springs
with a gap between DOFs or to ground, harmonic and static forces.

A Jenkins element joins node ``a`` to node ``b`` (or ground).  Its gap is
g = u_a - u_b along its tangential axes (one or two) and, if it has one, its
normal axis; the normal force is N = N0 + kn g_n (compression positive), and
without a normal axis the normal load is the constant N0.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..contact.cubic import CubicSprings
from ..contact.jenkins import JenkinsPairs
from ..contact.unilateral import UnilateralSprings
from .structure import ContactGroup, Structure

GROUND = "ground"
AXES = ("x", "y", "z")


@dataclass(frozen=True)
class MassSpec:
    name: str
    m: float  # kg
    dofs: tuple[str, ...] = ("x",)


@dataclass(frozen=True)
class LinkSpec:
    """A spring (value = k, N/m) or damper (value = c, N s/m) between two DOFs; b may be ground."""

    a: str
    b: str
    value: float


@dataclass(frozen=True)
class JenkinsSpec:
    a: str  # node name
    b: str  # node name or ground
    tangential: tuple[str, ...]  # 1 or 2 axes
    normal: str | None
    kt: float
    kn: float
    mu: float
    N0: float


@dataclass(frozen=True)
class GapSpringSpec:
    """A unilateral spring between two DOFs (b may be ground): with g = u_a - u_b, the force
    k (g - gap) acts while g > gap."""

    a: str
    b: str
    k: float  # N/m
    gap: float = 0.0  # m


@dataclass(frozen=True)
class ForceSpec:
    dof: str
    amplitude: float  # N
    phase: float = 0.0  # rad: f = amplitude cos(omega t - phase)
    static: float = 0.0  # N, a constant force (the zeroth harmonic)


@dataclass(frozen=True)
class LumpedSpec:
    masses: tuple[MassSpec, ...]
    springs: tuple[LinkSpec, ...] = ()
    dampers: tuple[LinkSpec, ...] = ()
    jenkins: tuple[JenkinsSpec, ...] = ()
    forces: tuple[ForceSpec, ...] = ()
    outputs: tuple[str, ...] = ()
    cubic: tuple[LinkSpec, ...] = ()  # value = k3, N/m^3: force k3 (u_a - u_b)^3
    unilateral: tuple[GapSpringSpec, ...] = ()


def dof_names(spec: LumpedSpec) -> tuple[str, ...]:
    return tuple(f"{m.name}.{d}" for m in spec.masses for d in m.dofs)


def _link_matrix(links, index, n) -> sp.csr_matrix:
    rows, cols, vals = [], [], []
    for ln in links:
        ia = index[ln.a]
        ib = None if ln.b == GROUND else index[ln.b]
        for i, si in ((ia, 1.0), (ib, -1.0)):
            if i is None:
                continue
            for j, sj in ((ia, 1.0), (ib, -1.0)):
                if j is None:
                    continue
                rows.append(i)
                cols.append(j)
                vals.append(si * sj * ln.value)
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, n))


def create_lumped(spec: LumpedSpec) -> Structure:
    names = dof_names(spec)
    index = {nm: i for i, nm in enumerate(names)}
    n = len(names)
    M = sp.diags(np.array([m.m for m in spec.masses for _ in m.dofs], dtype=float)).tocsr()
    K = _link_matrix(spec.springs, index, n)
    D = _link_matrix(spec.dampers, index, n)
    fc, fs, f0 = np.zeros(n), np.zeros(n), np.zeros(n)
    for f in spec.forces:
        fc[index[f.dof]] += f.amplitude * np.cos(f.phase)
        fs[index[f.dof]] += f.amplitude * np.sin(f.phase)
        f0[index[f.dof]] += f.static
    groups: dict[tuple[int, bool], list[JenkinsSpec]] = {}
    for j in spec.jenkins:
        groups.setdefault((len(j.tangential), j.normal is not None), []).append(j)
    contacts = []
    for (nt, has_normal), elems in groups.items():
        m = nt + int(has_normal)
        rows, cols, vals = [], [], []
        for p, j in enumerate(elems):
            axes = list(j.tangential) + ([j.normal] if has_normal else [])
            for a, ax in enumerate(axes):
                rows.append(p * m + a)
                cols.append(index[f"{j.a}.{ax}"])
                vals.append(1.0)
                if j.b != GROUND:
                    rows.append(p * m + a)
                    cols.append(index[f"{j.b}.{ax}"])
                    vals.append(-1.0)
        gap = sp.csr_matrix((vals, (rows, cols)), shape=(len(elems) * m, n))
        pairs = JenkinsPairs(kt=[j.kt for j in elems], kn=[j.kn for j in elems], mu=[j.mu for j in elems],
                             N0=[j.N0 for j in elems], num_tangential=nt, has_normal=has_normal)
        contacts.append(ContactGroup(pairs, gap, names=tuple(f"{j.a}-{j.b}" for j in elems)))
    for law, elems in ((CubicSprings(k3=[c.value for c in spec.cubic]) if spec.cubic else None, spec.cubic),
                       (UnilateralSprings(k=[u.k for u in spec.unilateral], gap=[u.gap for u in spec.unilateral])
                        if spec.unilateral else None, spec.unilateral)):
        if law is None:
            continue
        rows, cols, vals = [], [], []
        for p, e in enumerate(elems):  # g = u_a - u_b, one component per element
            rows.append(p)
            cols.append(index[e.a])
            vals.append(1.0)
            if e.b != GROUND:
                rows.append(p)
                cols.append(index[e.b])
                vals.append(-1.0)
        gap = sp.csr_matrix((vals, (rows, cols)), shape=(len(elems), n))
        contacts.append(ContactGroup(law, gap, names=tuple(f"{law.name}:{e.a}-{e.b}" for e in elems)))
    outputs = {nm: index[nm] for nm in spec.outputs}
    return Structure(K=K, M=M, D=D, fc=fc, fs=fs, contacts=tuple(contacts), dof_names=names, outputs=outputs,
                     info={"kind": "lumped"}, f0=f0 if np.any(f0) else None)
