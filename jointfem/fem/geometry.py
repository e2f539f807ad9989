"""Gmsh geometry builders for two substructures whose contact surfaces carry identical nodes.

Every builder makes boxes (rectangles in 2D) with the OpenCASCADE kernel, fragments the
boxes *of one substructure* among themselves (never across the joint, so the two contact
surfaces stay separate entities with their own nodes) and meshes them with transfinite,
recombined (hexahedral / quadrilateral) elements.  The number of elements along a curve
depends only on its length and the mesh size, so the two faces of the joint, which have
the same extent, get the same nodes.  The matching is checked after assembly
(``jointfem.fem.continuum``), not assumed.

Physical groups (read back by dolfinx as cell and facet tags):

    cells:   1 = substructure A, 2 = substructure B
    facets: 11 = clamp of A, 12 = clamp of B, 21 = contact surface of A, 22 = contact surface of B,
            31 = outer face of A, 32 = outer face of B (opposite the joint: where a bolt's washer sits)

Axes: x along the bars, y the stacking (normal) direction, z the width (3D).
All lengths in m.  Only this module and ``jointfem.fem`` touch gmsh.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

CELL_A, CELL_B = 1, 2
CLAMP_A, CLAMP_B = 11, 12
CONTACT_A, CONTACT_B = 21, 22
OUTER_A, OUTER_B = 31, 32


@dataclass(frozen=True)
class Box:
    """An axis-aligned block of one substructure: lower corner and size (dz = 0 in 2D)."""

    sub: int  # 0 = A, 1 = B
    x: float
    y: float
    dx: float
    dy: float
    z: float = 0.0
    dz: float = 0.0


@dataclass(frozen=True)
class Layout:
    """The blocks of a jointed structure and where its clamps and contact surfaces lie.

    clamps: per substructure, (axis, coordinate) of its clamped face, the plane x_axis = coordinate
        (None: unsupported); the bars are clamped at an end face (axis 0).
    contact: (x0, x1, y) of the joint plane y = const between x0 and x1 (full width in 3D).
    outer: per substructure, the y of its face opposite the joint, where a bolt's washer sits.
    """

    dim: int
    boxes: tuple[Box, ...]
    clamps: tuple[tuple[int, float] | None, tuple[int, float] | None]
    contact: tuple[float, float, float] | None
    extent: float  # the model size, m (for tolerances)
    outer: tuple[float, float] | None = None

    def outer_clamped(self, sub: int) -> bool:
        """Is substructure ``sub``'s outer face its clamp (the stack's base)?  Then a washer there
        loads the clamp, and the face carries no washer tag."""
        return self.outer is not None and self.clamps[sub] == (1, self.outer[sub])


def _ends(x_a: float, x_b: float, clamped: tuple[bool, bool]):
    """Clamps at the end faces x = x_a of A and x = x_b of B, where ``clamped`` says so."""
    return tuple((0, x) if c else None for x, c in zip((x_a, x_b), clamped))


def lap_layout(dim: int, length: float, height: float, width: float, overlap: float,
               clamped: tuple[bool, bool] = (True, True)) -> Layout:
    """Two bars of ``length`` x ``height`` (x ``width`` in 3D), B stacked on top of A, overlapping by
    ``overlap`` at the joint: the continuum twin of the beam2d model (paper Fig. 3)."""
    x0 = length - overlap
    boxes = [Box(0, 0.0, 0.0, x0, height, 0.0, width), Box(0, x0, 0.0, overlap, height, 0.0, width),
             Box(1, x0, height, overlap, height, 0.0, width), Box(1, length, height, x0, height, 0.0, width)]
    return Layout(dim, tuple(_flat(b, dim) for b in boxes), _ends(0.0, 2 * length - overlap, clamped),
                  (x0, length, height), 2 * length - overlap, (0.0, 2 * height))


def stack_layout(dim: int, length: float, height: float, width: float,
                 clamped: tuple[bool, bool] = (True, False)) -> Layout:
    """A block B of ``length`` x ``height`` (x ``width`` in 3D) lying on a base A of the same
    footprint, the joint their whole common face y = height.  A's clamp is its bottom face y = 0,
    B's its top face y = 2 height: pressed on a clamped base, the classic check of a contact law."""
    boxes = [Box(0, 0.0, 0.0, length, height, 0.0, width), Box(1, 0.0, height, length, height, 0.0, width)]
    clamps = tuple((1, y) if c else None for y, c in zip((0.0, 2 * height), clamped))
    return Layout(dim, tuple(_flat(b, dim) for b in boxes), clamps, (0.0, length, height),
                  max(length, 2 * height, width if dim == 3 else 0.0), (0.0, 2 * height))


def brb_layout(length: float = 0.42, side: float = 0.0254, overlap: float = 0.12,
               clamped: tuple[bool, bool] = (False, False)) -> Layout:
    """Brake-Reuss-like beam: two halves of ``length`` with a ``side`` x ``side`` section, each
    reduced to half thickness over the ``overlap``, where they lie on each other."""
    x0, half = length - overlap, side / 2
    # the full sections are split at half thickness so that every block is a hexahedron whose
    # faces conform to its neighbours' (transfinite meshing needs it)
    boxes = [Box(0, 0.0, 0.0, x0, half, 0.0, side), Box(0, 0.0, half, x0, half, 0.0, side),
             Box(0, x0, 0.0, overlap, half, 0.0, side),
             Box(1, x0, half, overlap, half, 0.0, side),
             Box(1, length, 0.0, x0, half, 0.0, side), Box(1, length, half, x0, half, 0.0, side)]
    return Layout(3, tuple(boxes), _ends(0.0, 2 * length - overlap, clamped), (x0, length, half), 2 * length - overlap,
                  (0.0, side))


def bar_layout(dim: int, length: float, height: float, width: float, clamped_end: bool = False) -> Layout:
    """One bar clamped at x = 0, and at x = length too if ``clamped_end`` (the Euler-Bernoulli validation)."""
    return Layout(dim, (_flat(Box(0, 0.0, 0.0, length, height, 0.0, width), dim),), _ends(0.0, length, (True, clamped_end)),
                  None, length)


def _flat(b: Box, dim: int) -> Box:
    return b if dim == 3 else Box(b.sub, b.x, b.y, b.dx, b.dy)


_GMSH_READY = False


def ensure_gmsh():
    """Initialise gmsh once per process (gmsh 4.8 has no isInitialized), silently."""
    global _GMSH_READY
    from . import compat  # (first: it notes SIGINT's action before gmsh changes it)

    with compat.sigint_kept():
        import gmsh

        if not _GMSH_READY:
            gmsh.initialize(readConfigFiles=False)
            gmsh.option.setNumber("General.Terminal", 0)
            _GMSH_READY = True
    return gmsh


def divisions(length: float, size: float) -> int:
    """Elements along an edge of ``length`` for a target element ``size`` (at least 1)."""
    return max(1, math.ceil(length / size - 1e-9))


def build(layout: Layout, size: float, *, name: str = "jointfem", size_normal: float | None = None,
          structured: bool = True, size_joint: float | None = None):
    """Mesh ``layout`` in the current gmsh session (gmsh must be initialised by the caller).

    size: element size along x and z, m; size_normal: along y (default ``size``).
    size_joint: element size along x over the joint's x-range and along z everywhere (a structured
    mesh's z-divisions run through every block), so that the interface carries more pairs without
    refining the bars away from it (default ``size``; structured meshes only).
    structured: transfinite quadrilaterals/hexahedra; otherwise unstructured triangles/tetrahedra
    of ``size``, with B's contact face meshed as a periodic copy (identity map) of A's, so that
    the two faces still carry the same nodes.
    Returns the number of mesh nodes.
    """
    import gmsh

    occ = gmsh.model.occ
    gmsh.model.add(name)
    tags: dict[int, list[int]] = {0: [], 1: []}
    for b in layout.boxes:
        if layout.dim == 3:
            tags[b.sub].append(occ.addBox(b.x, b.y, b.z, b.dx, b.dy, b.dz))
        else:
            tags[b.sub].append(occ.addRectangle(b.x, b.y, 0.0, b.dx, b.dy))
    d = layout.dim
    for sub in (0, 1):
        if len(tags[sub]) > 1:  # glue the blocks of one substructure, never across the joint
            out, _ = occ.fragment([(d, t) for t in tags[sub][:1]], [(d, t) for t in tags[sub][1:]])
            tags[sub] = [t for dd, t in out if dd == d]
    occ.synchronize()

    hn = size_normal or size
    hj = size_joint or size
    jx = layout.contact[:2] if layout.contact is not None else None
    if not structured:
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.MeshSizeMin", min(size, hn))
    for _, c in (gmsh.model.getEntities(1) if structured else []):
        x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(1, c)  # padded by the OCC tolerance
        length = occ.getMass(1, c)  # exact
        if (y1 - y0) > max(x1 - x0, z1 - z0):  # along y, the stacking direction
            n = divisions(length, hn)
        elif (z1 - z0) > (x1 - x0):  # along z
            n = divisions(length, hj)
        else:  # along x: fine where it lies over the joint
            inside = jx is not None and x0 >= jx[0] - 1e-6 * layout.extent and x1 <= jx[1] + 1e-6 * layout.extent
            n = divisions(length, hj if inside else size)
        gmsh.model.mesh.setTransfiniteCurve(c, n + 1)
    for _, s in (gmsh.model.getEntities(2) if structured else []):
        gmsh.model.mesh.setTransfiniteSurface(s)
        gmsh.model.mesh.setRecombine(2, s)
    if d == 3 and structured:
        for _, v in gmsh.model.getEntities(3):
            gmsh.model.mesh.setTransfiniteVolume(v)

    for sub, cell in ((0, CELL_A), (1, CELL_B)):
        if tags[sub]:
            gmsh.model.addPhysicalGroup(d, tags[sub], cell)
    eps = 1e-5 * layout.extent  # OCC pads bounding boxes by its tolerance (1e-7 m)
    big = 10 * layout.extent
    sub_boxes = {s: [b for b in layout.boxes if b.sub == s] for s in (0, 1)}

    def faces_in(x0, y0, z0, x1, y1, z1, sub):
        own = _own_entities(d - 1, tags[sub], d)
        found = gmsh.model.getEntitiesInBoundingBox(x0 - eps, y0 - eps, z0 - eps, x1 + eps, y1 + eps, z1 + eps, d - 1)
        return sorted(t for dd, t in found if t in own)

    def plane(axis, value):  # the bounding box of the plane x_axis = value
        lo, hi = [-big] * 3, [big] * 3
        lo[axis] = hi[axis] = value
        return (*lo, *hi)

    for end, clamp in enumerate(layout.clamps):
        sub = end if sub_boxes[1] else 0  # a single bar carries both clamps
        if clamp is None or not sub_boxes[sub]:
            continue
        f = faces_in(*plane(*clamp), sub)
        if f:
            gmsh.model.addPhysicalGroup(d - 1, f, (CLAMP_A, CLAMP_B)[end])
    for sub, y in enumerate(layout.outer or ()):
        if layout.outer_clamped(sub):
            continue
        f = faces_in(*plane(1, y), sub)
        if f:
            gmsh.model.addPhysicalGroup(d - 1, f, (OUTER_A, OUTER_B)[sub])
    if layout.contact is not None:
        x0, x1, y = layout.contact
        faces = [faces_in(x0, y, -big, x1, y, big, sub) for sub in (0, 1)]
        for sub in (0, 1):
            if faces[sub]:
                gmsh.model.addPhysicalGroup(d - 1, faces[sub], (CONTACT_A, CONTACT_B)[sub])
        if not structured and len(faces[0]) == len(faces[1]) == 1:
            identity = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
            gmsh.model.mesh.setPeriodic(d - 1, faces[1], faces[0], identity)
    gmsh.model.mesh.generate(d)
    return len(gmsh.model.mesh.getNodes()[0])


def _own_entities(dim: int, parents: list[int], pdim: int) -> set[int]:
    import gmsh

    own = set()
    for p in parents:
        for dd, t in gmsh.model.getBoundary([(pdim, p)], combined=False, oriented=False, recursive=False):
            own.add(t)
    return own
