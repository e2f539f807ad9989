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


def force_vectors(forces, index: dict, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(fc, fs, f0) of ForceSpecs on named DOFs: f = fc cos(omega t) + fs sin(omega t) + f0, N."""
    fc, fs, f0 = np.zeros(n), np.zeros(n), np.zeros(n)
    for f in forces:
        fc[index[f.dof]] += f.amplitude * np.cos(f.phase)
        fs[index[f.dof]] += f.amplitude * np.sin(f.phase)
        f0[index[f.dof]] += f.static
    return fc, fs, f0


def gap_operator(components: list[list[tuple[str, str]]], index: dict, n: int) -> sp.csr_matrix:
    """The gap operator of elements whose components join DOF a to DOF b (or ground): row
    (element, component) holds g = u_a - u_b."""
    m = len(components[0])
    rows, cols, vals = [], [], []
    for p, comps in enumerate(components):
        for c, (a, b) in enumerate(comps):
            rows.append(p * m + c)
            cols.append(index[a])
            vals.append(1.0)
            if b != GROUND:
                rows.append(p * m + c)
                cols.append(index[b])
                vals.append(-1.0)
    return sp.csr_matrix((vals, (rows, cols)), shape=(len(components) * m, n))


def jenkins_groups(elements: list, components: list[list[tuple[str, str]]], names: list[str], index: dict,
                   n: int) -> list[ContactGroup]:
    """Jenkins pairs (anything with kt, kn, mu, N0 and tangential/normal axes or DOF pairs), one
    group per (number of tangential components, normal or not), their components as DOF pairs."""
    groups: dict[tuple[int, bool], list[int]] = {}
    for i, e in enumerate(elements):
        groups.setdefault((len(e.tangential), e.normal is not None), []).append(i)
    out = []
    for (nt, has_normal), idx in groups.items():
        es = [elements[i] for i in idx]
        pairs = JenkinsPairs(kt=[e.kt for e in es], kn=[e.kn for e in es], mu=[e.mu for e in es],
                             N0=[e.N0 for e in es], num_tangential=nt, has_normal=has_normal)
        out.append(ContactGroup(pairs, gap_operator([components[i] for i in idx], index, n),
                                names=tuple(names[i] for i in idx)))
    return out


def create_lumped(spec: LumpedSpec) -> Structure:
    names = dof_names(spec)
    index = {nm: i for i, nm in enumerate(names)}
    n = len(names)
    M = sp.diags(np.array([m.m for m in spec.masses for _ in m.dofs], dtype=float)).tocsr()
    K = _link_matrix(spec.springs, index, n)
    D = _link_matrix(spec.dampers, index, n)
    fc, fs, f0 = force_vectors(spec.forces, index, n)
    comps = [[(f"{j.a}.{ax}", GROUND if j.b == GROUND else f"{j.b}.{ax}")
              for ax in list(j.tangential) + ([j.normal] if j.normal is not None else [])] for j in spec.jenkins]
    contacts = jenkins_groups(list(spec.jenkins), comps, [f"{j.a}-{j.b}" for j in spec.jenkins], index, n)
    for law, elems in ((CubicSprings(k3=[c.value for c in spec.cubic]) if spec.cubic else None, spec.cubic),
                       (UnilateralSprings(k=[u.k for u in spec.unilateral], gap=[u.gap for u in spec.unilateral])
                        if spec.unilateral else None, spec.unilateral)):
        if law is not None:  # g = u_a - u_b, one component per element
            contacts.append(ContactGroup(law, gap_operator([[(e.a, e.b)] for e in elems], index, n),
                                         names=tuple(f"{law.name}:{e.a}-{e.b}" for e in elems)))
    outputs = {nm: index[nm] for nm in spec.outputs}
    return Structure(K=K, M=M, D=D, fc=fc, fs=fs, contacts=tuple(contacts), dof_names=names, outputs=outputs,
                     info={"kind": "lumped"}, f0=f0 if np.any(f0) else None)
