"""ParaView export of a result folder (``jointfem export``): VTU files a user opens in ParaView.

At a chosen branch point:

* ``field_<i>.vtu`` and ``field_<i>.xdmf`` (continuum runs, which write shape.npz): the mesh's
  cells with the displacement harmonics at every node as vector fields, ``u_0`` (the mean),
  ``u_<k>_cos`` and ``u_<k>_sin`` for k = 1..H (m), and the first harmonic's amplitude ``|u_1|``
  (m).  A ROM's coordinates are expanded to the nodes through its basis.  ParaView's "Warp By
  Vector" on ``u_1_cos`` draws the deformed body.  The XDMF holds its data inline as XML (one
  file, no HDF5 beside it) and opens in ParaView and meshio;
* ``pairs_<i>.vtu`` (any model whose pairs have positions): every contact pair as a point with its
  dissipated energy per cycle (J), tangential amplitude (m), peak normal force (N) and the share of
  the period it spends stuck, slipping and separated.

Pairs are vertices; ParaView's "Point Gaussian" representation draws them.  Written with meshio.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .harmonics import Harmonics
from .results import OutputError, atomic_write
from .viz import fractions, load, pick_point


# VTK's cell types (as dolfinx.plot gives them, jointfem.fem.continuum) -> meshio's names.  At
# degree 2 dolfinx gives VTK's Lagrange cells (69-72); written as VTK's quadratic cells, whose node
# order is the same at degree 2 (tests/test_export.py checks every edge node at its edge's middle),
# because XDMF has no Lagrange cells.
_CELLS = {(5, 3): "triangle", (9, 4): "quad", (10, 4): "tetra", (12, 8): "hexahedron",
          (69, 6): "triangle6", (70, 9): "quad9", (71, 10): "tetra10", (72, 27): "hexahedron27"}


def _cells(shape: dict, num_nodes: int) -> list:
    """meshio's cell blocks of a shape.npz: the mesh's cells, or (a folder written before they were
    kept) every node as a vertex."""
    if "cell_nodes" in shape:
        nodes = np.asarray(shape["cell_nodes"], dtype=np.int64)
        name = _CELLS.get((int(shape["vtk_cell_type"]), nodes.shape[1]))
        if name is None:
            raise OutputError(f"shape.npz: VTK cell type {int(shape['vtk_cell_type'])} with {nodes.shape[1]} "
                              f"nodes is not one jointfem writes")
        return [(name, nodes)]
    return [("vertex", np.arange(num_nodes)[:, None])]


def export_point(folder, *, point: str | None = "peak", omega: float | None = None, out=None) -> list[Path]:
    """Write the VTU files of one branch point of ``folder`` into ``out`` (default folder/export).
    Returns the paths written."""
    import meshio

    folder = Path(folder)
    data = load(folder)
    i = pick_point(data, point, omega)
    out = Path(out) if out is not None else folder / "export"
    written = []
    h = Harmonics(int(data["H"]), int(data["N"]))
    q = int(data["num_dofs"])
    U = data["U"][i]
    info = {"omega_rad_s": float(data["omega"][i]), "point": i}

    shape_path = folder / "shape.npz"
    if shape_path.is_file():
        with np.load(shape_path) as z:
            shape = {k: z[k] for k in z.files}
        X = shape["node_coords"]
        nodes, comps = shape["dof_node"], shape["dof_comp"]
        fields = {}
        for k in range(h.H + 1):
            for label, sl in ((f"u_{k}_cos" if k else "u_0", h.cos(k, q)), *(((f"u_{k}_sin", h.sin(k, q)),) if k else ())):
                z = U[sl]
                if "recovery" in shape:
                    z = shape["recovery"] @ z
                u = np.zeros((X.shape[0], 3))
                u[nodes, comps] = z
                fields[label] = u
        fields["|u_1|"] = np.sqrt(np.sum(fields["u_1_cos"] ** 2 + fields["u_1_sin"] ** 2, axis=1))
        pts = np.zeros((X.shape[0], 3))
        pts[:, :X.shape[1]] = X
        mesh = meshio.Mesh(pts, _cells(shape, X.shape[0]), point_data=fields)
        path = out / f"field_{i}.vtu"
        atomic_write(path, lambda p: meshio.write(p, mesh, file_format="vtu"))
        written.append(path)
        path = out / f"field_{i}.xdmf"
        atomic_write(path, lambda p: meshio.write(p, mesh, file_format="xdmf", data_format="XML"))
        written.append(path)

    if "pair_coords" in data and data["pair_coords"].size:
        C = np.asarray(data["pair_coords"], float)
        pts = np.zeros((C.shape[0], 3))
        pts[:, :C.shape[1]] = C
        share = fractions(data, i)
        pair_data = {"energy_J": data["pair_energy_J"][i], "tangential_amp_m": data["pair_tangential_amp_m"][i],
                     "peak_normal_N": data["pair_peak_normal_N"][i], "stick_share": share[:, 0],
                     "slip_share": share[:, 1], "separated_share": share[:, 2]}
        if "pair_area_m2" in data:  # continua: per unit area too (independent of the mesh)
            area = np.asarray(data["pair_area_m2"], float)
            pair_data.update({"area_m2": area, "energy_per_area_J_m2": pair_data["energy_J"] / area,
                              "peak_pressure_Pa": pair_data["peak_normal_N"] / area})
        mesh = meshio.Mesh(pts, [("vertex", np.arange(C.shape[0])[:, None])], point_data=pair_data)
        path = out / f"pairs_{i}.vtu"
        atomic_write(path, lambda p: meshio.write(p, mesh, file_format="vtu"))
        written.append(path)
    if not written:
        raise OutputError(f"{folder}: nothing to export at point {i} (omega = {info['omega_rad_s']:.6g} rad/s): "
                          f"no shape.npz (a continuum run) and no pair positions")
    return written
