"""2D (plane stress) and 3D linear-elastic substructures from gmsh and dolfinx, joined by
node-to-node Jenkins pairs on their node-matched contact surfaces.

Pipeline (each stage timed in ``Structure.info["timings"]``):

1. mesh: ``jointfem.fem.geometry`` builds the gmsh model on rank 0; dolfinx distributes it.
2. assembly: dolfinx assembles K and M (Lagrange degree 1 or 2) as PETSc matrices on all
   ranks, without boundary conditions.
3. gather: every rank receives K and M in a *canonical* DOF order that does not depend on
   the number of ranks: nodes sorted by (substructure, z, y, x), then the components.  The
   two faces of the joint carry coincident nodes; the substructure id tells them apart.
4. interface: the contact nodes of both faces are matched by position (KD-tree) to 1e-10
   of the model size; nodal areas are the consistent boundary integrals of the scalar shape
   functions, the nodal normal is the area-weighted outward normal of substructure A.
5. clamped DOFs are eliminated (not penalised), so no spurious eigenvalue reaches the modes.

The result is a plain ``Structure`` (scipy matrices, replicated on every rank); the solvers
never see dolfinx.  Gap of pair p, in the frame (t1, [t2], n) of its A-side node:
``g = R (u_A - u_B)``, with n the outward normal of A, so that ``g_n > 0`` is compression.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ..contact.jenkins import JenkinsPairs
from ..linalg import LinAlgError
from ..linalg import allgather_rows as _allgather
from ..models.structure import ContactGroup, Structure
from . import compat
from . import geometry as geo

GEOMETRIES = ("lap", "brb", "bar", "stack")
COMPONENTS = ("ux", "uy", "uz")


class ContinuumError(ValueError):
    """The mesh or the interface cannot make a valid jointed model (names what and where)."""


@dataclass(frozen=True)
class Bolt:
    """A bolt: its axis crosses the joint plane at (x, z); ``force`` N is spread over the
    contact nodes within ``radius`` m, in proportion to their areas (the preload patch)."""

    x: float
    z: float
    radius: float
    force: float


@dataclass(frozen=True)
class GapProfile:
    """The interface's initial normal gap g0(x, z) >= 0, m, between the faces at rest (before any
    preload): ``crown``, a spherical crown touching at ``centre`` (x, z) with ``radius`` of
    curvature, g0 = |p - centre|^2 / (2 radius) (in 2D the cylinder (x - x_c)^2 / (2 radius));
    ``table``, measured topology, g0 interpolated linearly from ``points`` (x, z, gap) rows (2D: x,
    gap), the mesoscale topology of a real interface.  ``source``: where the table came from."""

    kind: str  # "crown" | "table"
    centre: tuple[float, ...] = ()
    radius: float = 0.0
    points: tuple[tuple[float, ...], ...] = ()
    source: str = ""

    def at(self, xz: np.ndarray, dim: int, where: str) -> np.ndarray:
        """g0 at the pair positions ``xz`` (P, 2): (x, z) columns (z unused in 2D)."""
        if self.kind == "crown":
            d = xz[:, :dim - 1] - np.asarray(self.centre[:dim - 1])
            return np.sum(d * d, axis=1) / (2.0 * self.radius)
        pts = np.asarray(self.points, float)
        if dim == 2:
            x = pts[:, 0]
            order = np.argsort(x)
            out = (xz[:, 0] < x.min() - 1e-12) | (xz[:, 0] > x.max() + 1e-12)
            g = np.interp(xz[:, 0], x[order], pts[order, 1])
        else:
            from scipy.interpolate import LinearNDInterpolator

            interp = LinearNDInterpolator(pts[:, :2], pts[:, 2])
            g = interp(xz)  # NaN outside the points' convex hull
            out = ~np.isfinite(g)
            if out.any():
                # a pair on the hull's edge is inside or out by round-off (Qhull's test of a node at
                # x = 1e-19 against an edge at x = 0 went either way with the CPU's kernels, issue 51):
                # moved towards the table's centroid by 1e-9 of its distance, it is inside unless it
                # lies farther out than that (g0 changes by its slope times that distance)
                c = pts[:, :2].mean(axis=0)
                g[out] = interp(xz[out] + 1e-9 * (c - xz[out]))
                out = ~np.isfinite(g)
        if out.any():
            k = int(np.flatnonzero(out)[0])
            raise ContinuumError(f"{where}: {int(out.sum())} contact pairs lie outside the points of {self.source} "
                                 f"(the first at x = {xz[k, 0]:.6g}, z = {xz[k, 1]:.6g} m): the table must cover "
                                 f"the whole interface")
        return np.asarray(g, float)


@dataclass(frozen=True)
class Support:
    """A soft support, such as a bungee cord: springs of ``stiffness`` N/m (along x, y, z) from
    the outer face that ``at`` lies on to ground, shared equally by that face's nodes within
    ``radius`` m of ``at`` (the nearest node if 0).  A patch of nodes also resists rotation."""

    at: tuple[float, ...]
    stiffness: tuple[float, ...]
    radius: float = 0.0


@dataclass(frozen=True)
class ContinuumSpec:
    geometry: str = "lap"  # "lap" | "brb" | "bar" | "stack" (a block on a base: overlap = length)
    dim: int = 3
    length: float = 0.3  # m, each bar (brb: each half, 0.42)
    height: float = 0.006  # m, each bar (brb: the square section's side, 0.0254)
    width: float = 0.025  # m (2D: the plane-stress thickness)
    overlap: float = 0.03  # m
    clamped: tuple[bool, bool] = (True, True)
    size: float = 0.005  # m, element size along x and z
    size_normal: float | None = None  # m, along y (default: size)
    size_joint: float | None = None  # m, along x over the joint and along z (default: size)
    degree: int = 2
    structured: bool = True  # transfinite quads/hexes; False: triangles/tetrahedra, periodic contact faces
    young: float = 2.1e11  # Pa
    poisson: float = 0.3
    density: float = 7850.0  # kg/m^3
    kt: float = 0.0  # N/m^3: tangential contact stiffness per area (or kt_total)
    kn: float = 0.0  # N/m^3
    kt_total: float = 0.0  # N/m for the whole joint, spread by area
    kn_total: float = 0.0
    mu: float = 0.3
    pressure: float = 0.0  # Pa, uniform preload over the contact surface
    bolts: tuple[Bolt, ...] = ()
    patches_only: bool = False  # only the nodes under a bolt patch are contact pairs
    # "uniform": N0 from the pressure and the bolt patches on the interface; "static": the bolts load
    # the outer faces under their washers (radius) and a static contact solve gives N0 per pair and
    # the gaps of the pairs it leaves open (models.preload)
    preload: str = "uniform"
    gap: GapProfile | None = None  # the interface's initial gaps from its geometry (None: flat faces)
    # the static solve's tangential law while the bolts tighten: "stuck" (each closed pair on its kt:
    # nothing slips) or "frictionless" (no tangential force: what the dynamics, whose sliders start
    # unloaded, assume; the bodies must then be held tangentially by clamps or supports)
    preload_path: str = "stuck"
    supports: tuple[Support, ...] = ()  # soft springs to ground (a free-free test article's bungees)
    rayleigh_alpha: float = 0.0  # 1/s
    rayleigh_beta: float = 0.0  # s
    force_at: tuple[float, ...] = (0.15, 0.0, 0.0125)  # m, the force acts at the nearest node
    force_dir: str = "uy"
    force: float = 1.0  # N
    outputs: tuple[tuple[str, tuple[float, ...], str], ...] = ()  # (name, point, component)
    mesh_file: str | None = None  # write the gmsh mesh here (through meshio)
    source: str = "<continuum>"  # the scene file, for error messages

    def supported(self) -> tuple[bool, bool]:
        """Per substructure (A, B): is it clamped, or does a support lie on one of its blocks?"""
        held = list(self.clamped)
        layout = self.layout()
        tol = 1e-9 * layout.extent
        for s in self.supports:
            p = tuple(s.at) + (0.0,) * (3 - len(s.at))
            for b in layout.boxes:
                lo, hi = (b.x, b.y, b.z), (b.x + b.dx, b.y + b.dy, b.z + b.dz)
                if all(a - tol <= c <= e + tol for c, a, e in zip(p[:self.dim], lo, hi)):
                    held[b.sub] = True
        return held[0], held[1]

    def layout(self) -> geo.Layout:
        if self.geometry == "lap":
            return geo.lap_layout(self.dim, self.length, self.height, self.width, self.overlap, self.clamped)
        if self.geometry == "brb":
            return geo.brb_layout(self.length, self.height, self.overlap, self.clamped)
        if self.geometry == "stack":
            return geo.stack_layout(self.dim, self.length, self.height, self.width, self.clamped)
        return geo.bar_layout(self.dim, self.length, self.height, self.width, self.clamped[1])


@dataclass
class Mesh:
    """The assembled, gathered model before contact and supports are applied (all ranks)."""

    dim: int
    coords: np.ndarray  # (num_nodes, 3), canonical order
    sub: np.ndarray  # (num_nodes,) 0 = A, 1 = B
    K: sp.csr_matrix  # (dim*num_nodes,)^2, N/m
    M: sp.csr_matrix  # kg
    clamped: np.ndarray  # node ids
    contact: tuple[np.ndarray, np.ndarray]  # node ids of the contact faces of A and B
    area: np.ndarray  # (num_nodes,) consistent nodal area on the contact faces, m^2
    normal: np.ndarray  # (num_nodes, 3) area-weighted outward normal on the contact faces
    extent: float
    timings: dict = field(default_factory=dict)
    cells: int = 0
    # (num_bolts, num_nodes): per bolt, the integral of each node's shape function over the outer
    # faces' area under its washer, m^2 (a clamped outer face excluded): the consistent nodal shares
    # of a uniform washer pressure, computed where the spec's preload is "static"
    washers: np.ndarray | None = None
    # (num_cells, nodes per cell): every cell's canonical node ids in VTK's order, and its VTK cell
    # type (5 triangle, 9 quad, 10 tetra, 12 hexahedron; 69-72 their Lagrange forms at degree 2),
    # for the ParaView export of the deformed body
    cell_nodes: np.ndarray | None = None
    vtk_cell_type: int = 0


@dataclass
class Assembled:
    """Stages 1-2 on every rank: the distributed dolfinx mesh, its spaces and tags, and K, M as the
    PETSc matrices dolfinx assembled (no boundary conditions; block size dim)."""

    layout: geo.Layout
    mesh: object
    V: object  # vector Lagrange space
    W: object  # scalar Lagrange space
    cell_tags: object
    facet_tags: object
    K: object  # PETSc Mat, N/m
    M: object  # PETSc Mat, kg
    thick: float  # the plane-stress width in 2D, 1 in 3D
    timings: dict


def assemble(spec: ContinuumSpec, comm=None) -> Assembled:
    """Stages 1-2: gmsh on rank 0, the mesh distributed by dolfinx, K and M assembled by dolfinx."""
    compat.import_dolfinx()
    gmsh = geo.ensure_gmsh()  # (it imports gmsh with SIGINT's action kept)
    import ufl
    from mpi4py import MPI

    comm = comm or MPI.COMM_WORLD
    layout = spec.layout()
    t0 = time.perf_counter()
    try:
        if comm.rank == 0:
            geo.build(layout, spec.size, size_normal=spec.size_normal, structured=spec.structured,
                      size_joint=spec.size_joint)
            if spec.mesh_file:
                _write_mesh(spec.mesh_file, layout.dim)
        mesh, cell_tags, facet_tags = compat.model_to_mesh(gmsh.model, comm, layout.dim)
    finally:
        if comm.rank == 0:
            gmsh.model.remove()
    t1 = time.perf_counter()

    d = layout.dim
    V = compat.vector_space(mesh, spec.degree)
    W = compat.scalar_space(mesh, spec.degree)
    E, nu, rho = spec.young, spec.poisson, spec.density
    mu_l = E / (2 * (1 + nu))
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    thick = 1.0
    if d == 2:  # plane stress, per unit thickness times the width
        lam = 2 * lam * mu_l / (lam + 2 * mu_l)
        thick = spec.width
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)

    def eps(w):
        return ufl.sym(ufl.grad(w))

    def sigma(w):
        return 2 * mu_l * eps(w) + lam * ufl.tr(eps(w)) * ufl.Identity(d)

    Kp = compat.assemble_matrix(thick * ufl.inner(sigma(u), eps(v)) * ufl.dx)
    Mp = compat.assemble_matrix(thick * rho * ufl.inner(u, v) * ufl.dx)
    t2 = time.perf_counter()
    return Assembled(layout, mesh, V, W, cell_tags, facet_tags, Kp, Mp, thick,
                     {"mesh_s": t1 - t0, "assembly_s": t2 - t1})


def build_mesh(spec: ContinuumSpec, comm=None) -> Mesh:
    """Stages 1-3: gmsh, dolfinx assembly, gather in canonical order."""
    import ufl
    from mpi4py import MPI

    comm = comm or MPI.COMM_WORLD
    asm = assemble(spec, comm)
    layout, mesh, V, W, cell_tags, facet_tags = asm.layout, asm.mesh, asm.V, asm.W, asm.cell_tags, asm.facet_tags
    Kp, Mp, thick, d = asm.K, asm.M, asm.thick, layout.dim
    t2 = time.perf_counter()

    # canonical node order from the vector space's blocks
    gid, X = compat.owned_blocks(V)
    all_gid = _allgather(comm, gid)
    all_X = _allgather(comm, X)
    all_sub = _allgather(comm, _substructure_of_blocks(V, cell_tags)[:gid.size])
    num_nodes = all_gid.size
    q = 1e-9 * layout.extent
    key = np.round(all_X / q).astype(np.int64)
    order = np.lexsort((key[:, 0], key[:, 1], key[:, 2], all_sub))
    kk = np.column_stack([all_sub[order], key[order]])
    if num_nodes > 1 and np.any(np.all(kk[1:] == kk[:-1], axis=1)):
        raise ContinuumError(f"{spec.source}: two nodes of one substructure coincide: the mesh is broken")
    canon = np.empty(num_nodes, dtype=np.int64)  # global block id -> canonical node id
    canon[all_gid[order]] = np.arange(num_nodes)
    coords = all_X[order]
    sub = all_sub[order].astype(np.int32)

    local_cells, vtk_type = compat.vtk_cells(V)
    per_cell = comm.allreduce(local_cells.shape[1], op=MPI.MAX)  # a rank may own no cell
    rows = canon[compat.local_to_global(V, local_cells.ravel())].reshape(-1, per_cell) if local_cells.size \
        else np.zeros((0, per_cell), dtype=np.int64)
    cell_nodes = _allgather(comm, rows)
    cell_nodes = cell_nodes[np.lexsort(cell_nodes.T[::-1])]  # the same order whatever the partition's
    vtk_type = comm.allreduce(vtk_type, op=MPI.MAX)

    K = _gather_matrix(Kp, canon, d, comm, num_nodes)
    M = _gather_matrix(Mp, canon, d, comm, num_nodes)

    # scalar space: node map by position, then facet nodes, areas and normals
    wgid, WX = compat.owned_blocks(W)
    nW = wgid.size
    w_canon = _match_rows(kk, np.column_stack([_substructure_of_blocks(W, cell_tags)[:nW],
                                               np.round(WX / q).astype(np.int64)]))
    if np.any(w_canon < 0):
        raise ContinuumError(f"{spec.source}: the scalar and vector spaces disagree on the nodes")
    all_w_canon = _allgather(comm, w_canon)

    def facet_nodes(tag):
        loc = compat.facet_blocks(W, facet_tags, tag)
        loc = loc[loc < nW]
        return np.unique(_allgather(comm, w_canon[loc]))

    def gather_nodal(values):
        out = np.zeros(num_nodes)
        out[all_w_canon] = _allgather(comm, values[:nW])
        return out

    clamped = np.unique(np.concatenate([facet_nodes(t) for t in (geo.CLAMP_A, geo.CLAMP_B)])) \
        if facet_tags is not None else np.zeros(0, dtype=np.int64)
    area = np.zeros(num_nodes)
    normal = np.zeros((num_nodes, 3))
    contact = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))
    if layout.contact is not None:
        ds = ufl.Measure("ds", domain=mesh, subdomain_data=facet_tags)
        w = ufl.TestFunction(W)
        nrm = ufl.FacetNormal(mesh)
        contact = (facet_nodes(geo.CONTACT_A), facet_nodes(geo.CONTACT_B))
        for tag in (geo.CONTACT_A, geo.CONTACT_B):
            area += gather_nodal(compat.assemble_vector(thick * w * ds(tag)))
            for i in range(d):
                normal[:, i] += gather_nodal(compat.assemble_vector(thick * w * nrm[i] * ds(tag)))
    washers = None
    if spec.preload == "static" and spec.bolts and layout.outer is not None:
        washers = np.array([gather_nodal(v) for v in _washer_integrals(mesh, W, facet_tags, spec.bolts, thick)])
    t3 = time.perf_counter()
    Kp.destroy()
    Mp.destroy()
    return Mesh(d, coords, sub, K, M, clamped, contact, area, normal, layout.extent,
                dict(asm.timings, gather_s=t3 - t2),
                cells=mesh.topology.index_map(d).size_global, washers=washers, cell_nodes=cell_nodes,
                vtk_cell_type=vtk_type)


# Gauss points per direction on a face for the washer's disc (its indicator is not a polynomial):
# degree 18 gives 10 x 10 points on a quadrilateral face, so the disc's rim is placed to about a
# tenth of an element; the total force is exact whatever the rule (washer_loads normalises)
WASHER_QUADRATURE_DEGREE = 18


def _washer_integrals(mesh, W, facet_tags, bolts, thick: float) -> list[np.ndarray]:
    """Per bolt, the owned entries of  int_{outer faces, |x - axis| <= radius} w_i dA  (thick: the
    2D width, where the washer is a strip |x - x_b| <= radius across it)."""
    import ufl

    x = ufl.SpatialCoordinate(mesh)
    centre = [compat.constant(mesh, 0.0) for _ in range(3)]  # x, z, radius
    r2 = (x[0] - centre[0]) ** 2 + ((x[2] - centre[1]) ** 2 if mesh.geometry.dim == 3 else 0)
    under = ufl.conditional(ufl.le(r2, centre[2] ** 2), 1.0, 0.0)
    ds = ufl.Measure("ds", domain=mesh, subdomain_data=facet_tags,
                     metadata={"quadrature_degree": WASHER_QUADRATURE_DEGREE})
    form = thick * under * ufl.TestFunction(W) * (ds(geo.OUTER_A) + ds(geo.OUTER_B))
    out = []
    for bolt in bolts:
        for c, v in zip(centre, (bolt.x, bolt.z, bolt.radius)):
            c.value = v
        out.append(compat.assemble_vector(form))
    return out


def _substructure_of_blocks(space, cell_tags) -> np.ndarray:
    """0 (A) or 1 (B) for every local block (owned and ghost) of ``space``."""
    imap = space.dofmap.index_map
    sub = np.zeros(imap.size_local + imap.num_ghosts, dtype=np.int8)
    sub[compat.cell_blocks(space, cell_tags.find(geo.CELL_B))] = 1
    return sub


def _match_rows(ref: np.ndarray, query: np.ndarray) -> np.ndarray:
    """Index in ``ref`` of each row of ``query`` (integer rows), -1 where absent; vectorised."""
    both = np.vstack([ref, query])
    _, inv = np.unique(both, axis=0, return_inverse=True)
    inv = inv.ravel()
    where = np.full(inv.max() + 1, -1, dtype=np.int64)
    where[inv[:ref.shape[0]]] = np.arange(ref.shape[0])
    return where[inv[ref.shape[0]:]]


def _gather_matrix(A, canon: np.ndarray, d: int, comm, num_nodes: int) -> sp.csr_matrix:
    """The PETSc matrix (block size d) on every rank as scipy CSR in canonical order."""
    indptr, indices, data = A.getValuesCSR()
    r0, r1 = A.getOwnershipRange()
    rows = np.repeat(np.arange(r0, r1), np.diff(indptr))

    def to_canon(i):
        return d * canon[i // d] + i % d

    r = _allgather(comm, to_canon(rows))
    c = _allgather(comm, to_canon(indices.astype(np.int64)))
    v = _allgather(comm, data)
    n = d * num_nodes
    return sp.csr_matrix((v, (r, c)), shape=(n, n))


def _write_mesh(path: str, dim: int):
    """The gmsh mesh of the current model, through meshio (format from the suffix: .msh, .vtu, .xdmf)."""
    import gmsh
    import meshio

    tags, xyz, _ = gmsh.model.mesh.getNodes()
    index = {int(t): i for i, t in enumerate(tags)}
    cells = []
    kinds = {2: ("triangle", 3), 3: ("quad", 4), 4: ("tetra", 4), 5: ("hexahedron", 8)}  # gmsh element types
    for etype, _, nodes in zip(*gmsh.model.mesh.getElements(dim)):
        if int(etype) not in kinds:
            continue
        name, nper = kinds[int(etype)]
        conn = np.array([index[int(t)] for t in nodes]).reshape(-1, nper)
        cells.append((name, conn))
    points = xyz.reshape(-1, 3)[:, :dim] if dim == 2 else xyz.reshape(-1, 3)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    # a name of this process's own: two runs that build the same scene's mesh at once (a benchmark's
    # pool) each write whole and replace the file atomically, with the same content
    tmp = out.with_name(f"{out.stem}.{os.getpid()}.tmp{out.suffix}")
    tag = [np.zeros(len(c[1]), dtype=int) for c in cells]
    meshio.write(tmp, meshio.Mesh(points, cells, cell_data={"gmsh:physical": tag, "gmsh:geometrical": tag}), **({"file_format": "gmsh22", "binary": False}
                                                      if out.suffix == ".msh" else {}))
    tmp.replace(out)


def match_interface(mesh: Mesh, source: str = "<continuum>") -> tuple[np.ndarray, np.ndarray]:
    """Pairs (a, b) of coincident contact nodes of A and B, checked to 1e-10 of the model size."""
    from scipy.spatial import cKDTree

    a, b = mesh.contact
    if a.size == 0 or b.size == 0:
        raise ContinuumError(f"{source}: the contact surface is empty (A has {a.size} nodes, B has {b.size}): "
                             f"the substructures do not overlap")
    tol = 1e-10 * mesh.extent
    dist, j = cKDTree(mesh.coords[b]).query(mesh.coords[a])
    bad = dist > tol
    if a.size != b.size or np.any(bad) or np.unique(j).size != j.size:
        worst = float(dist.max())
        raise ContinuumError(
            f"{source}: the contact surfaces do not match node to node: A has {a.size} nodes, B has {b.size}; "
            f"{int(bad.sum())} A nodes have no B node within {tol:.1e} m (worst {worst:.3e} m). "
            f"Mesh both faces with the same divisions (the builders do), or use matching/periodic meshing")
    return a, b[j]


def frames(normal: np.ndarray, dim: int) -> np.ndarray:
    """Orthonormal frames (P, m, dim): rows t1, [t2], n.  t1 is the x axis projected on the
    tangent plane (z in the rare case that n is along x)."""
    n = normal[:, :dim] / np.linalg.norm(normal[:, :dim], axis=1, keepdims=True)
    if dim == 2:
        t1 = np.column_stack([n[:, 1], -n[:, 0]])
        t1 *= np.where(t1[:, :1] < 0, -1.0, 1.0)
        return np.stack([t1, n], axis=1)
    ref = np.tile([1.0, 0.0, 0.0], (n.shape[0], 1))
    along = np.abs(n[:, 0]) > 0.9
    ref[along] = [0.0, 0.0, 1.0]
    t1 = ref - np.sum(ref * n, axis=1, keepdims=True) * n
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    return np.stack([t1, t2, n], axis=1)


def gap_entries(a: np.ndarray, b: np.ndarray, R: np.ndarray):
    """(values, (rows, columns)) of the gap operator: row p*m + i of pair p (nodes a[p] of A, b[p]
    of B, frame R[p] (m, d)) is R[p, i] on A's DOFs d*a[p] + c and -R[p, i] on B's."""
    P, m, d = R.shape
    rows = np.repeat(np.arange(P * m), 2 * d)
    both = np.concatenate([d * a[:, None] + np.arange(d), d * b[:, None] + np.arange(d)], axis=1)  # (P, 2d)
    cols = np.broadcast_to(both[:, None, :], (P, m, 2 * d)).ravel()
    return np.concatenate([R, -R], axis=2).ravel(), (rows, cols)


def washer_loads(mesh: Mesh, spec: ContinuumSpec) -> np.ndarray:
    """The bolts' forces on the outer faces (all DOFs, N): each bolt pushes the face of A opposite
    the joint towards B, and B's towards A, by ``force`` N, a uniform pressure over the washer (the
    disc of ``radius`` about its axis; a strip across the width in 2D) in consistent nodal shares
    (Mesh.washers).  A clamped outer face (the stack's base) takes its washer's load in its clamp."""
    d = mesh.dim
    if mesh.washers is None or mesh.washers.shape[0] != len(spec.bolts):
        raise ContinuumError(f"{spec.source}: the mesh carries no washer integrals for these {len(spec.bolts)} bolts "
                             f"(build it from a spec with preload = \"static\" and the same bolts)")
    a_nodes = mesh.contact[0]
    n = mesh.normal[a_nodes].sum(axis=0)
    n = n / np.linalg.norm(n)  # A's outward normal on the joint: from A to B
    F = np.zeros(d * mesh.coords.shape[0])
    layout = spec.layout()
    on_clamp = [layout.outer_clamped(sub) for sub in (0, 1)]
    if all(on_clamp):
        raise ContinuumError(f"{spec.source}: both outer faces are clamped, so the bolts' washers load nothing: "
                             f"leave one body free of its clamp (geometry.clamped)")
    for k, (bolt, w) in enumerate(zip(spec.bolts, mesh.washers)):
        for sub, sign in ((0, 1.0), (1, -1.0)):
            if on_clamp[sub]:
                continue
            ws = np.where(mesh.sub == sub, w, 0.0)
            if not ws.sum() > 0:
                raise ContinuumError(f"{spec.source}: bolt {k} at x = {bolt.x}, z = {bolt.z} m with radius "
                                     f"{bolt.radius} m covers none of the outer face of {'AB'[sub]} (no quadrature "
                                     f"point of the face lies under its washer)")
            for i in range(d):
                F[i::d] += sign * bolt.force * n[i] * ws / ws.sum()
    return F


def support_springs(mesh: Mesh, spec: ContinuumSpec) -> np.ndarray:
    """The supports' springs to ground on the diagonal of K (all DOFs, N/m)."""
    d = mesh.dim
    k = np.zeros(d * mesh.coords.shape[0])
    lo, hi = mesh.coords.min(axis=0), mesh.coords.max(axis=0)
    h = 1e-9 * mesh.extent
    for j, s in enumerate(spec.supports):
        at = np.zeros(3)
        at[:len(s.at)] = s.at
        faces = [(i, v) for i in range(d) for v in (lo[i], hi[i]) if abs(at[i] - v) <= h]
        if not faces:
            raise ContinuumError(f"{spec.source}: support {j} at {list(s.at)} m does not lie on an outer face of the "
                                 f"model's box {lo[:d].tolist()} .. {hi[:d].tolist()} m")
        i, v = faces[0]
        face = np.flatnonzero(np.abs(mesh.coords[:, i] - v) <= h)
        r = np.linalg.norm(mesh.coords[face] - at, axis=1)
        if s.radius > 0:
            nodes = face[r <= s.radius]
        else:  # the nearest node, if it lies within an element size
            nodes = face[[np.argmin(r)]] if r.min() <= spec.size else face[:0]
        if not nodes.size:
            raise ContinuumError(f"{spec.source}: support {j} at {list(s.at)} m with radius {s.radius} m covers "
                                 f"no node of its face")
        if np.isin(nodes, mesh.clamped).any():
            raise ContinuumError(f"{spec.source}: support {j} at {list(s.at)} m lies on a clamped face")
        for c in range(d):
            np.add.at(k, d * nodes + c, s.stiffness[c] / nodes.size)
    return k


def pair_springs(spec: ContinuumSpec, xz: np.ndarray, area: np.ndarray):
    """The pairs kept (all, or those under a bolt patch), and their N0 (N), kt and kn (N/m) from the
    nodal areas: a uniform pressure plus each bolt's force shared by area over its patch (zero with
    preload = "static", whose solve sets N0 later).  xz (P, 2): the pairs' (x, z), m."""
    N0 = spec.pressure * area
    under = np.zeros(area.size, dtype=bool)
    for k, bolt in enumerate(spec.bolts if spec.preload == "uniform" else ()):
        inside = np.hypot(xz[:, 0] - bolt.x, xz[:, 1] - bolt.z) <= bolt.radius
        if not inside.any():
            raise ContinuumError(f"{spec.source}: bolt {k} at x = {bolt.x}, z = {bolt.z} m with radius "
                                 f"{bolt.radius} m covers no contact node")
        N0 = N0 + bolt.force * inside * area / area[inside].sum()
        under |= inside
    keep = under if spec.patches_only else np.ones(area.size, dtype=bool)
    if spec.preload == "static":
        N0 = np.zeros(area.size)  # from the static solve
    area, N0 = area[keep], N0[keep]
    total = area.sum()
    return keep, N0, spec.kt * area + spec.kt_total * area / total, spec.kn * area + spec.kn_total * area / total


def static_preload(mesh: Mesh, spec: ContinuumSpec, K, G, free, kt, kn, g0=None):
    """The static contact state under the bolts' washer loads (models.preload)."""
    from ..models.preload import solve_static_contact

    F = washer_loads(mesh, spec)
    if np.abs(np.delete(F, free)).max(initial=0.0) > 0:
        raise ContinuumError(f"{spec.source}: a bolt's washer covers a clamped node")
    frictionless = spec.preload_path == "frictionless"
    try:
        return solve_static_contact(K, G, 0.0 * kt if frictionless else kt, kn, F[free], num_tangential=mesh.dim - 1,
                                    g0=g0, what=f"{spec.source}: static preload")
    except LinAlgError as exc:
        why = ("with preload_path = \"frictionless\" the joint holds nothing tangentially: clamp each body or "
               "hold it by [[support]]s" if frictionless else
               "a body held by the joint alone needs the joint closed under the bolts")
        raise ContinuumError(f"{exc} ({why})") from None


def create_continuum(spec: ContinuumSpec, comm=None, mesh: Mesh | None = None) -> Structure:
    """The jointed continuum as a Structure (clamped DOFs eliminated), replicated on every rank."""
    mesh = mesh or build_mesh(spec, comm)
    d = mesh.dim
    nn = mesh.coords.shape[0]
    n_all = d * nn
    t0 = time.perf_counter()
    groups = ()
    pair_info = {}
    if mesh.contact[0].size or mesh.contact[1].size:
        a, b = match_interface(mesh, spec.source)
        area = 0.5 * (mesh.area[a] + mesh.area[b])
        if np.any(area <= 0):
            raise ContinuumError(f"{spec.source}: {int(np.sum(area <= 0))} contact nodes have zero area "
                                 f"(the corners of degree-2 triangles do): use structured quadrilateral/hexahedral "
                                 f"elements ([mesh] structured = true) or degree = 1")
        keep, N0, kt, kn = pair_springs(spec, mesh.coords[a][:, [0, 2]], area)
        a, b, area = a[keep], b[keep], area[keep]
        total = area.sum()
        g0 = None
        if spec.gap is not None:
            g0 = spec.gap.at(mesh.coords[a][:, [0, 2]], d, spec.source)
            g0 = np.where(g0 > 1e-12 * mesh.extent, g0, 0.0)  # a gap of the coordinates' round-off is contact
            if spec.preload == "uniform":  # no preload (the scene checks): each pair open by its g0
                N0 = np.where(g0 > 0, -kn * g0, N0)
        P = a.size
        gap_all = sp.csr_matrix(gap_entries(a, b, frames(mesh.normal[a], d)), shape=(P * d, n_all))
    clamped_dofs = (d * mesh.clamped[:, None] + np.arange(d)[None, :]).ravel()
    free = np.setdiff1d(np.arange(n_all), clamped_dofs)
    K = mesh.K[free][:, free].tocsr()
    if spec.supports:
        K = (K + sp.diags(support_springs(mesh, spec)[free])).tocsr()
    if mesh.contact[0].size or mesh.contact[1].size:
        if spec.preload == "static":
            st = static_preload(mesh, spec, K, gap_all[:, free].tocsr(), free, kt, kn, g0)
            N0 = st.N0
            use = st.tangential_use(np.full(P, spec.mu))
            pair_info = {"preload": "static", "preload_path": spec.preload_path, "static_iterations": st.iterations,
                         "pairs_closed": int(st.closed.sum()),
                         "pairs_open": int((~st.closed).sum()), "bolt_force_N": float(sum(b.force for b in spec.bolts)),
                         "contact_area_closed_m2": float(area[st.closed].sum()),
                         "peak_pressure_Pa": float((N0 / area).max()),
                         "largest_static_gap_m": float(max(-(st.N0 / kn).min(), 0.0)),
                         "static_tangential_use_max": float(use.max())}
        pairs = JenkinsPairs(kt=kt, kn=kn, mu=np.full(P, spec.mu), N0=N0, num_tangential=d - 1, has_normal=True)
        pair_info = {"num_pairs": int(P), "contact_area_m2": float(total), "preload_N": float(np.maximum(N0, 0).sum()),
                     **pair_info}
        if g0 is not None:
            pair_info.update(geometric_gap_max_m=float(g0.max()), pairs_open_at_rest=int((N0 < 0).sum()))
    M = mesh.M[free][:, free].tocsr()
    node_of = free // d
    comp_of = free % d
    names = tuple(f"{'AB'[mesh.sub[i]]}.{i}.{COMPONENTS[c]}" for i, c in zip(node_of, comp_of))
    loaded = np.flatnonzero(~np.isin(np.arange(nn), mesh.clamped))  # nodes a force or an output may sit on
    if pair_info:
        coords = mesh.coords[a]
        groups = (ContactGroup(pairs, gap_all[:, free].tocsr(), names=tuple(f"pair{p}" for p in range(P)),
                               coords=coords, areas=area),)

    def nearest(point, comp, what):
        p = np.zeros(3)
        p[:len(point)] = point
        i = loaded[np.argmin(np.linalg.norm(mesh.coords[loaded] - p, axis=1))]
        if comp not in COMPONENTS[:d]:
            raise ContinuumError(f"{spec.source}: {what}: component {comp!r} is not one of {COMPONENTS[:d]}")
        return int(np.searchsorted(free, d * i + COMPONENTS.index(comp))), i

    fc = np.zeros(free.size)
    fi, fnode = nearest(spec.force_at, spec.force_dir, "[force]")
    fc[fi] = spec.force
    outputs = {}
    for name, point, comp in spec.outputs:
        outputs[f"{name}.{comp}"] = nearest(point, comp, f"[output].{name}")[0]
    D = (spec.rayleigh_alpha * M + spec.rayleigh_beta * K).tocsr()
    timings = dict(mesh.timings, contact_s=time.perf_counter() - t0)
    info = {"kind": f"continuum{d}d", "geometry": spec.geometry, "free_dofs": int(free.size),
            "nodes": int(nn), "cells": int(mesh.cells), "degree": spec.degree, "timings": timings,
            "supported": bool(mesh.clamped.size or spec.supports), "force_node": mesh.coords[fnode].tolist(), **pair_info,
            # for pictures of the deformed shape (jointfem.viz): where each DOF sits and points
            "geometry": {"node_coords": mesh.coords, "dof_node": node_of, "dof_comp": comp_of,
                         **({} if mesh.cell_nodes is None else
                            {"cell_nodes": mesh.cell_nodes, "vtk_cell_type": mesh.vtk_cell_type})}}
    return Structure(K=K, M=M, D=D, fc=fc, fs=np.zeros_like(fc), contacts=groups, dof_names=names,
                     outputs=outputs, info=info, substructure=mesh.sub[node_of].astype(np.int32))
