"""The mesh of the ParaView export: every cell of the continuum with its nodes in VTK's order.

Checked against VTK itself (pyvista's cell sizes of the cells as written add up to the body's
area or volume; a node order VTK does not expect folds or twists a cell and changes its measure)
and against VTK's documented node order of its quadratic cells (each edge node at its edge's
middle, each face node at its face's centre), which export.py relies on when it writes dolfinx's
degree-2 Lagrange cells as VTK's quadratic ones.
"""
from __future__ import annotations

import numpy as np
import pytest

from jointfem.fem.continuum import ContinuumSpec, build_mesh

# VTK's quadratic cells: the vertex pairs of the edge nodes (in node order after the corners) and
# the corner quadruples of the face nodes (vtkQuadraticTriangle, vtkBiQuadraticQuad,
# vtkQuadraticTetra, vtkTriQuadraticHexahedron)
_EDGES = {
    6: [(0, 1), (1, 2), (2, 0)],
    9: [(0, 1), (1, 2), (2, 3), (3, 0)],
    10: [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)],
    27: [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7)],
}
_FACES = {9: [(0, 1, 2, 3)],
          27: [(0, 3, 7, 4), (1, 2, 6, 5), (0, 1, 5, 4), (3, 2, 6, 7), (0, 1, 2, 3), (4, 5, 6, 7), tuple(range(8))]}
# what export.py writes for each (VTK type dolfinx gives, nodes per cell)
_WRITTEN = {(5, 3): 5, (9, 4): 9, (10, 4): 10, (12, 8): 12, (69, 6): 22, (70, 9): 28, (71, 10): 24, (72, 27): 29}

CASES = [  # (geometry, dim, degree, structured): every cell type jointfem's meshes have
    ("bar", 2, 1, True), ("bar", 2, 2, True), ("bar", 3, 1, True), ("bar", 3, 2, True),
    ("lap", 2, 1, False), ("lap", 2, 2, False), ("lap", 3, 1, False),
]


@pytest.mark.parametrize("geometry,dim,degree,structured", CASES)
def test_cells_in_vtk_order_tile_the_body(geometry, dim, degree, structured):
    import pyvista as pv

    spec = ContinuumSpec(geometry=geometry, dim=dim, degree=degree, structured=structured, size=0.01,
                         size_normal=0.006, kt_total=3e4, kn=2e11, pressure=8e4)
    mesh = build_mesh(spec)
    cells = mesh.cell_nodes
    assert cells.shape[0] == mesh.cells
    assert np.array_equal(np.unique(cells), np.arange(mesh.coords.shape[0]))  # every node is in a cell
    X = mesh.coords
    n = cells.shape[1]
    if degree == 2:
        corners = {6: 3, 9: 4, 10: 4, 27: 8}[n]
        for j, (a, b) in enumerate(_EDGES[n]):
            np.testing.assert_allclose(X[cells[:, corners + j]], 0.5 * (X[cells[:, a]] + X[cells[:, b]]),
                                       atol=1e-12, err_msg=f"edge node {corners + j}")
        for j, face in enumerate(_FACES.get(n, [])):
            k = corners + len(_EDGES[n]) + j
            np.testing.assert_allclose(X[cells[:, k]], X[cells[:, list(face)]].mean(axis=1), atol=1e-12,
                                       err_msg=f"face node {k}")
    vtk_type = _WRITTEN[(mesh.vtk_cell_type, n)]
    grid = pv.UnstructuredGrid({vtk_type: cells}, X)
    sizes = grid.compute_cell_sizes(length=False, area=dim == 2, volume=dim == 3)
    measure = np.asarray(sizes.cell_data["Area" if dim == 2 else "Volume"])
    bodies = 2 if geometry == "lap" else 1
    body = bodies * spec.length * spec.height * (spec.width if dim == 3 else 1.0)
    assert np.all(measure > 0)
    assert measure.sum() == pytest.approx(body, rel=1e-9)
