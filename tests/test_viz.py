"""Pictures of result folders, checked on the PNG files themselves (off-screen, no display).

Two real runs: a 3D lap joint that sticks and slips (25 pairs, penalty ROM) and the jointed
beam with a stiffer tangential joint, which sticks, slips and separates along its branch.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jointfem import viz
from jointfem.cli import main
from jointfem.results import OutputError, load_branch
from conftest import ROOT


def _png(path: Path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB"))


def _colour_pixels(img: np.ndarray, box, k: int) -> int:
    x0, y0, x1, y1 = box
    crop = img[y0:y1, x0:x1].reshape(-1, 3)
    return int(np.all(crop == viz.state_rgb()[k], axis=1).sum())


def _legend_pixels(img: np.ndarray, pic, k: int) -> int:
    """Pixels of state k's colour outside the picture's map: its swatch in the legend."""
    h, w = img.shape[:2]
    return _colour_pixels(img, (0, 0, w, h), k) - _colour_pixels(img, pic.map_box, k)


def _viridis_colours(img: np.ndarray) -> int:
    """Distinct colours of the image within 2 levels of matplotlib's viridis (a colour bar's gradient)."""
    import matplotlib

    ramp = np.round(matplotlib.colormaps["viridis"](np.linspace(0, 1, 256))[:, :3] * 255).astype(int)
    px = np.unique(img.reshape(-1, 3).astype(int), axis=0)
    return int((np.abs(px[:, None, :] - ramp[None]).max(axis=-1).min(axis=1) <= 2).sum())


def _assert_picture(pic):
    img = _png(pic.path)
    assert img.shape[:2] == (pic.size[1], pic.size[0])  # the size asked for
    assert img.reshape(-1, 3).std(axis=0).max() > 10  # not blank
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 20
    assert not list(pic.path.parent.glob("*.tmp*"))
    return img


@pytest.fixture(scope="module")
def stick_slip(tmp_path_factory):
    pytest.importorskip("dolfinx")
    text = (ROOT / "demos" / "lap3d.toml").read_text()
    text = (text.replace("size = 0.01 ", "size = 0.015 ").replace("samples = 256", "samples = 1024")
            .replace("kt_total = 3.0e4", "kt = 2.0e11").replace("pressure = 8.0e4", "pressure = 2.0e5")
            .replace("amplitude = 1.0 ", "amplitude = 3.0 ").replace('file = "../meshes/lap3d.msh"', ""))
    d = tmp_path_factory.mktemp("viz")
    (d / "lap3d.toml").write_text(text)
    out = d / "out"
    assert main(["frf", str(d / "lap3d.toml"), "--method", "penalty", "--modes", "10", "--quiet",
                 "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def separating(tmp_path_factory):
    text = (ROOT / "demos" / "beam2d.toml").read_text().replace("kt = 1.0e4 ", "kt = 3.0e5 ")
    d = tmp_path_factory.mktemp("viz_beam")
    (d / "beam.toml").write_text(text)
    out = d / "out"
    assert main(["frf", str(d / "beam.toml"), "--harmonics", "3", "--samples", "1024", "--method", "penalty",
                 "--modes", "10", "--quiet", "--plots", "--out", str(out)]) == 0
    return out


def test_interface_map_stick_slip(stick_slip):
    """At a point where some pairs mostly stick and others mostly slip, the state map shows both
    colours (in the map, not only in the legend); every panel has its colour bar."""
    data = viz.load(stick_slip)
    dom = viz.dominant(data)
    mixed = [i for i in range(dom.shape[0]) if {0, 1} <= set(np.unique(dom[i]))]
    assert mixed, "the run must have a point where pairs stick and slip"
    pics = viz.plot_folder(stick_slip, point=str(mixed[0]))
    inter = [p for p in pics if p.path.name.startswith("interface_")][0]
    img = _assert_picture(inter)
    assert inter.size == (1600, 800)
    for k in (0, 1):
        assert _colour_pixels(img, inter.map_box, k) > 50, viz.STATE_NAMES[k]
    assert _colour_pixels(img, inter.map_box, 2) == 0  # nothing separates in this run
    assert inter.legends == ["stick", "slip", "separated"]
    # ... and drawn: a swatch of every state's colour outside the map, separated's too though
    # nothing separates (measured 99 pixels or more)
    assert all(_legend_pixels(img, inter, k) > 50 for k in range(3))
    assert len(inter.colorbars) == 6
    branch = [p for p in pics if p.path.name == "states_branch.png"][0]
    bimg = _assert_picture(branch)
    assert all(_colour_pixels(bimg, branch.map_box, k) > 20 for k in (0, 1))
    shape = [p for p in pics if p.path.name.startswith("shape_")][0]
    simg = _assert_picture(shape)
    assert shape.size == (1200, 600) and shape.colorbars == ["first-harmonic displacement amplitude [m]"]
    # the colour bar is drawn: a viridis gradient along the bottom 15 % of the picture, below the
    # model (measured 336 distinct colours of the ramp there)
    assert _viridis_colours(simg[int(0.85 * simg.shape[0]):]) > 200


def test_state_map_separating(separating):
    """`frf --plots` draws the branch map; the beam sticks, slips and separates along it: all three
    colours inside the axes.  The beam's 3 pairs lie on a line: the interface map draws points."""
    branch = viz.plot_folder(separating)[0]
    img = _assert_picture(branch)
    data = viz.load(separating)
    assert set(np.unique(viz.dominant(data))) == {0, 1, 2}
    for k in range(3):
        assert _colour_pixels(img, branch.map_box, k) > 5, viz.STATE_NAMES[k]  # the beam slips at one point only
    assert branch.legends == ["stick", "slip", "separated"]
    assert all(_legend_pixels(img, branch, k) > 50 for k in range(3))  # drawn: measured 180 or more
    assert (separating / "states_branch.png").is_file()
    inter = sorted(separating.glob("interface_*.png"))
    assert inter
    _assert_picture(viz.Picture(inter[0], (1600, 800)))


def test_plot_cli_errors(tmp_path, separating, capsys):
    assert main(["plot", str(tmp_path)]) == 2
    assert "no branch.npz" in capsys.readouterr().err
    assert main(["plot", str(separating), "--point", "100000"]) == 2
    assert "points" in capsys.readouterr().err
    assert main(["plot", str(separating), "--omega", "1700", "--quiet"]) == 0


def test_frf_picture_has_rom_size_axis(separating):
    """frf.png of a penalty-ROM run: the size asked for (7.5 x 6.5 in at 120 dpi), not blank, with
    the ROM size on a second axis (its labels right of the lower panel), which a run of fixed size lacks."""
    from jointfem.results import load_branch

    img = _png(separating / "frf.png")
    assert img.shape[:2] == (780, 900)
    assert img.reshape(-1, 3).std(axis=0).max() > 10
    sizes = load_branch(separating / "branch.npz")["rom_size"]
    assert sizes.max() > sizes.min()  # the active set changed along the branch, so the axis is drawn
    # the second axis's tick labels and label lie right of the lower panel's right spine (the
    # rightmost column dark over half the panel's height): measured 458-794 dark pixels there in
    # pictures with the axis, 0-49 without (every frf.png of a suite run, 2026-12-06).  Not the exact
    # grey of its dotted line: how many pixels keep it depends on where the line falls between pixel
    # rows (245 on one machine, 19 under OpenBLAS's Sandybridge kernel on another, same axis drawn)
    dark = img.astype(float).mean(axis=2) < 128
    lower = dark[img.shape[0] // 2:]
    counts = lower.sum(axis=0)
    spine = int(np.flatnonzero(counts > 0.5 * counts.max()).max())
    assert int(lower[:, spine + 2:].sum()) > 200

def test_paraview_export_holds_the_solved_fields(tmp_path):
    """`jointfem export` at a point of a continuum run: field_<i>.vtu and field_<i>.xdmf carry the
    mesh's cells (60 biquadratic quadrilaterals, as VTK's own readers see them) and every node's
    harmonics (the first harmonic at the output node equals the solved coefficients), and
    pairs_<i>.vtu every pair's energy and state shares as in branch.npz."""
    import meshio
    import pyvista as pv
    from vtkmodules.vtkIOXdmf2 import vtkXdmfReader  # ParaView's XDMF reader

    out = tmp_path / "l2"
    r = subprocess.run([sys.executable, "-m", "jointfem", "frf", str(ROOT / "demos" / "lap2d.toml"), "--harmonics", "1",
                        "--samples", "32", "--set", "solver.omega_range=[1600, 1610]", "--out", str(out), "--quiet"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    r = subprocess.run([sys.executable, "-m", "jointfem", "export", str(out), "--point", "3"], capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr
    b = load_branch(out / "branch.npz")
    with np.load(out / "shape.npz") as z:
        node, comp, num_nodes = z["dof_node"], z["dof_comp"], z["node_coords"].shape[0]
    field = meshio.read(out / "export" / "field_3.vtu")
    q = int(b["num_dofs"])
    dof = int(b["output_dofs"][0])
    np.testing.assert_allclose(field.point_data["u_1_cos"][node[dof], comp[dof]], b["U"][3, q + dof], rtol=1e-12)
    np.testing.assert_allclose(field.point_data["u_1_sin"][node[dof], comp[dof]], b["U"][3, 2 * q + dof], rtol=1e-12)
    grid = pv.read(out / "export" / "field_3.vtu")
    assert grid.n_cells == 60 and set(grid.celltypes) == {28}  # VTK_BIQUADRATIC_QUAD
    assert grid.n_points == num_nodes
    reader = vtkXdmfReader()
    reader.SetFileName(str(out / "export" / "field_3.xdmf"))
    reader.Update()
    xdmf = pv.wrap(reader.GetOutputDataObject(0))
    assert xdmf.n_cells == 60 and set(xdmf.celltypes) == {28}
    np.testing.assert_array_equal(np.asarray(xdmf.point_data["u_1_cos"]), field.point_data["u_1_cos"])
    pairs = meshio.read(out / "export" / "pairs_3.vtu")
    np.testing.assert_allclose(pairs.point_data["energy_J"], b["pair_energy_J"][3])
    share = sum(pairs.point_data[k] for k in ("stick_share", "slip_share", "separated_share"))
    np.testing.assert_allclose(share, 1.0)
    assert pairs.points.shape == (b["pair_coords"].shape[0], 3)
    # per unit area: the pairs' areas tile the 30 mm x 25 mm overlap, and at this stuck point every
    # pair's normal load swings about its preload, p = 80 kPa times its area (the edge pairs have half
    # the area and half the force: per pair 4.0 to 16.2 N, per area 82 to 98 kPa)
    area = pairs.point_data["area_m2"]
    assert area.sum() == pytest.approx(0.03 * 0.025, rel=1e-12)
    assert pairs.point_data["peak_pressure_Pa"].min() >= 8.0e4
    assert pairs.point_data["peak_pressure_Pa"].max() < 1.5e5
    np.testing.assert_allclose(pairs.point_data["energy_per_area_J_m2"] * area, b["pair_energy_J"][3])


def test_state_map_shows_each_share_not_the_dominant_state(tmp_path):
    """A pair separated for 30 % of every period (never its dominant state) and one stuck all
    period: the branch map draws separation in proportion, 0.3 / 2.0 = 15 % of the coloured area
    (pixel rounding allows 13-17 %); the old dominant-state map drew none."""
    n_pts, N = 40, 100
    states = np.zeros((n_pts, N, 2), np.int8)
    states[:, 70:, 0] = 2
    data = {"states": states, "omega": np.linspace(1000.0, 1100.0, n_pts)}
    pic = viz.plot_state_map(data, tmp_path / "s.png")
    img = _assert_picture(pic)
    red, blue = (_colour_pixels(img, pic.map_box, k) for k in (2, 0))
    assert pic.states_shown == (0, 2) and set(np.unique(viz.dominant(data))) == {0}
    assert 0.13 < red / (red + blue) < 0.17
    assert _colour_pixels(img, pic.map_box, 1) == 0
