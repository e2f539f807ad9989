"""Off-screen pictures of a result folder: contact-state maps of the interface (pyvista) and the
state of every pair along the branch (matplotlib).  No display and no xvfb are needed: VTK from
PyPI renders off-screen.

Everything is read back from ``branch.npz`` (written by ``jointfem frf``, ``nma`` or ``force``): the
contact state of every pair at every time sample of every point, the per-pair energy, tangential
amplitude and peak normal force, and the pairs' reference positions.  Nothing is recomputed.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .contact.law import STATE_NAMES
from .harmonics import Harmonics
from .results import OutputError, load_branch

# one colour per contact state, shared by every picture (stick, slip, separated)
STATE_COLORS = ("#2c7bb6", "#fdae61", "#d7191c")


def state_rgb() -> np.ndarray:
    return np.array([[int(c[i:i + 2], 16) for i in (1, 3, 5)] for c in STATE_COLORS])


@dataclass
class Picture:
    """What a picture shows, for the caller and the tests: its file, size and legends."""

    path: Path
    size: tuple[int, int]
    legends: list[str] = field(default_factory=list)
    colorbars: list[str] = field(default_factory=list)
    states_shown: tuple[int, ...] = ()
    map_box: tuple[int, int, int, int] | None = None  # (x0, y0, x1, y1) image pixels of the state map, no legend


def load(folder) -> dict:
    folder = Path(folder)
    path = folder / "branch.npz"
    if not path.is_file():
        raise OutputError(f"{folder}: no branch.npz here (is it a folder written by `jointfem frf`?)")
    data = load_branch(path)
    if "output_names" not in data:  # a force sweep's folder written before it held its output layout
        raise OutputError(f"{folder}: branch.npz has no output layout (a `jointfem force` folder of an older "
                          f"jointfem?): run the command again to plot or export it")
    return data


def is_force(data: dict) -> bool:
    """A `jointfem force` branch: its points are force levels at one omega, not frequencies."""
    return "force_N" in data


def pick_point(data: dict, point: str | None = None, omega: float | None = None, output: str | None = None) -> int:
    """Index of the branch point: 'peak' (largest first-harmonic amplitude of the first output),
    an index, or the point nearest to omega (rad/s)."""
    n = data["omega"].size
    if omega is not None:
        if is_force(data):
            raise OutputError(f"--omega = {omega:g}: a force sweep's points are all at omega = "
                              f"{float(data['omega'][0]):.6g} rad/s: choose one with --point")
        return int(np.argmin(np.abs(data["omega"] - omega)))
    if point in (None, "peak"):
        amp = _output_amplitude(data, output)
        return int(np.argmax(amp))
    try:
        i = int(point)
    except ValueError:
        raise OutputError(f"--point = {point!r}: must be 'peak' or a point index") from None
    if not -n <= i < n:
        raise OutputError(f"--point = {i}: the branch has {n} points (0 to {n - 1})")
    return i % n


def _output_amplitude(data: dict, output: str | None) -> np.ndarray:
    names = list(data["output_names"])
    j = names.index(output) if output in names else 0
    U = data["U"]
    q = int(data["num_dofs"])
    if "output_dofs" in data:
        row = np.zeros(q)
        row[int(data["output_dofs"][j])] = 1.0
    else:
        row = data["output_recovery"][j]
    c, s = (U[:, sl] @ row for sl in _first_harmonic(data, q))
    return np.hypot(c, s)


def _first_harmonic(data: dict, q: int) -> tuple[slice, slice]:
    """Slices of the cosine and sine of harmonic 1 of q signals in a stored coefficient vector."""
    h = Harmonics(int(data["H"]), int(data["N"]))
    return h.cos(1, q), h.sin(1, q)


def fractions(data: dict, i: int) -> np.ndarray:
    """Share of the period each pair spends stuck, slipping, separated at point i, shape (P, 3)."""
    st = data["states"][i]  # (N, P)
    return np.stack([(st == k).mean(axis=0) for k in range(3)], axis=1)


def dominant(data: dict) -> np.ndarray:
    """Dominant state of every pair at every point, shape (points, P)."""
    st = data["states"]
    counts = np.stack([(st == k).sum(axis=1) for k in range(3)], axis=-1)  # (points, P, 3)
    return counts.argmax(axis=-1)


# ---- matplotlib: pairs against frequency ---------------------------------------------------

def plot_state_map(data: dict, path: Path, *, title: str = "") -> Picture:
    """Every pair (rows) at every branch point (columns at its frequency, Hz, as in frf.png; along a
    backbone at log10 of its amplitude, as in backbone.png): a
    stacked bar per pair and point whose parts are the shares of the period it sticks (bottom),
    slips and is separated (top), so that a state held for part of the period shows in proportion
    instead of being hidden by the dominant one."""
    from matplotlib.collections import PolyCollection
    from matplotlib.patches import Patch

    from .plots import pyplot, readable_axes

    plt = pyplot()
    share = np.stack([fractions(data, i) for i in range(data["states"].shape[0])])  # (points, P, 3)
    n_pts, P = share.shape[:2]
    fig, ax = plt.subplots(figsize=(8, 1.8 + 0.2 * min(P, 30)))
    backbone = "xi" in data and "amplitude" in data  # a nonlinear mode's folder (jointfem nma)
    force = is_force(data)
    # along a backbone the columns stand at log10 of its amplitude, as backbone.png's axis; along a
    # force sweep at log10 of the force, as force.png's; else at Hz, as frf.png's
    f = (np.log10(data["amplitude"]) if backbone else np.log10(data["force_N"]) if force
         else data["omega"] / (2 * np.pi))
    # each point's column reaches halfway to its neighbours along the branch (where the branch turns
    # back, later points are drawn over earlier ones), and is at least 0.2 % of the range wide
    mid = 0.5 * (f[1:] + f[:-1])
    lo = np.append(f[0] - (mid[0] - f[0] if f.size > 1 else 0.5), mid)
    hi = np.append(mid, f[-1] + (f[-1] - mid[-1] if f.size > 1 else 0.5))
    lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
    grow = np.maximum(0.002 * (np.ptp(f) or 1.0) - (hi - lo), 0.0)
    x0 = np.repeat(lo - 0.5 * grow, P)
    x1 = np.repeat(hi + 0.5 * grow, P)
    row = np.tile(np.arange(P, dtype=float), n_pts) - 0.45
    bottom = row.copy()
    for k in range(3):
        h = 0.9 * share[..., k].reshape(-1)
        keep = h > 0
        verts = np.stack([np.column_stack([x0, bottom]), np.column_stack([x1, bottom]),
                          np.column_stack([x1, bottom + h]), np.column_stack([x0, bottom + h])], axis=1)[keep]
        ax.add_collection(PolyCollection(verts, facecolors=STATE_COLORS[k], edgecolors="none", antialiased=False))
        bottom = bottom + h
    ax.set_xlim(x0.min(), x1.max())
    ax.set_ylim(-0.6, P - 0.4)
    ax.set_xlabel(f"log10 of the first-harmonic amplitude at {data['output']} [m]" if backbone
                  else f"log10 of the force amplitude [N] at {float(data['omega'][0]):.6g} rad/s" if force
                  else "frequency [Hz]")
    if not (backbone or force):
        readable_axes(ax)
    ax.set_ylabel("contact pair")
    shown = tuple(k for k in range(3) if (share[..., k] > 0).any())
    labels = [STATE_NAMES[k] for k in range(3)]
    ax.legend([Patch(color=STATE_COLORS[k]) for k in range(3)], labels, loc="upper left", bbox_to_anchor=(1.0, 1.0),
              fontsize=8, title="share of\nthe period", title_fontsize=8)
    ax.set_title(title or "contact state of every pair along the branch", fontsize=10)
    fig.tight_layout()
    fig.set_dpi(100)
    fig.canvas.draw()
    w, h = fig.canvas.get_width_height()
    bb = ax.get_window_extent()
    box = (int(np.ceil(bb.x0)) + 1, int(np.ceil(h - bb.y1)) + 1, int(bb.x1) - 1, int(h - bb.y0) - 1)
    path = Path(path)
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=100)
    plt.close(fig)
    tmp.replace(path)
    return Picture(path, (int(w), int(h)), legends=labels, states_shown=shown, map_box=box)


# ---- pyvista: interface maps at one point ----------------------------------------------------

def _plane(coords: np.ndarray):
    """Centre, normal and in-plane axes of the pairs' positions (SVD), and their dimension."""
    c = coords.mean(axis=0)
    _, s, vt = np.linalg.svd(coords - c, full_matrices=True)
    rank = int(np.sum(s > 1e-9 * max(s[0], 1e-300))) if s.size else 0
    return c, vt[2], vt[0], vt[1], rank


def per_pair_fields(data: dict, i: int) -> list[tuple[str, np.ndarray | None, str]]:
    """(label, values per pair or None, colour map) of the dissipation, the tangential amplitude and
    the peak normal load at point i: per unit area where the pairs' areas are known (continua:
    J/m^2 and the peak contact pressure in Pa, which do not depend on the mesh), per pair otherwise."""
    def get(key):
        return np.asarray(data[key][i], float) if key in data else None

    W, ta, pn = get("pair_energy_J"), get("pair_tangential_amp_m"), get("pair_peak_normal_N")
    area = np.asarray(data["pair_area_m2"], float) if "pair_area_m2" in data else None
    if area is not None and area.size and np.all(area > 0):
        return [("dissipated energy per cycle per area [J/m^2]", None if W is None else W / area, "viridis"),
                ("tangential amplitude [m]", ta, "plasma"),
                ("peak contact pressure [Pa]", None if pn is None else pn / area, "cividis")]
    return [("dissipated energy per cycle [J]", W, "viridis"), ("tangential amplitude [m]", ta, "plasma"),
            ("peak normal force [N]", pn, "cividis")]


def plot_interface(data: dict, i: int, path: Path, *, title: str = "", window=(1600, 800)) -> Picture:
    """Interface maps at branch point i: dominant state (legend), the share of the period stuck,
    slipping and separated, dissipated energy per cycle, tangential amplitude and peak normal
    force (colour bars).  Off-screen."""
    if "pair_coords" not in data:
        raise OutputError("branch.npz has no pair positions (pair_coords): written by an older jointfem?")
    import pyvista as pv
    import vtk

    vtk.vtkLogger.SetStderrVerbosity(vtk.vtkLogger.VERBOSITY_OFF)
    coords = np.asarray(data["pair_coords"], dtype=float)
    P = coords.shape[0]
    c, n, t1, t2, rank = _plane(coords)
    pts = pv.PolyData(coords)
    surface = None
    if rank >= 2 and P >= 3:
        flat = pv.PolyData(np.column_stack([(coords - c) @ t1, (coords - c) @ t2, np.zeros(P)]))
        tri = flat.delaunay_2d()
        surface = pv.PolyData(coords, tri.faces)
    frac = fractions(data, i)
    dom = frac.argmax(axis=1)
    fields = [
        ("share of the period stuck", frac[:, 0], "Blues"),
        ("share of the period slipping", frac[:, 1], "Oranges"),
        ("share of the period separated", frac[:, 2], "Reds"),
        *per_pair_fields(data, i),
    ]
    span = np.ptp(coords, axis=0).max() or 1.0
    spacing = span / max(np.sqrt(P), 1.0)
    radius = 0.18 * spacing if rank >= 2 else 0.04 * span

    pl = pv.Plotter(off_screen=True, window_size=list(window), shape=(2, 4), border=False)
    pl.set_background("white")

    def view():
        if rank >= 2:
            pl.view_vector(n, viewup=t2)
        else:
            pl.view_vector(np.cross(t1, [0.0, 0.0, 1.0]) if abs(t1[2]) < 0.9 else [0.0, 1.0, 0.0], viewup=[0, 0, 1])
        pl.reset_camera()

    spheres = pts.glyph(geom=pv.Sphere(radius=radius, theta_resolution=12, phi_resolution=12), scale=False,
                        orient=False)
    per_point = spheres.n_points // P
    pl.subplot(0, 0)
    rgb = state_rgb()[dom]
    spheres["rgb"] = np.repeat(rgb, per_point, axis=0).astype(np.uint8)
    if surface is not None:
        pl.add_mesh(surface, color="#dddddd", lighting=False)
    pl.add_mesh(spheres, scalars="rgb", rgb=True, lighting=False)
    pl.add_legend([[STATE_NAMES[k], STATE_COLORS[k]] for k in range(3)], bcolor="white", face="rectangle",
                  size=(0.9, 0.14), loc="lower center")
    pl.add_text("dominant state", font_size=9, color="black")
    view()
    bars = []
    for k, (label, values, cmap) in enumerate(fields):
        r, col = divmod(k + 1, 4)
        pl.subplot(r, col)
        pl.add_text(label, font_size=9, color="black")
        if values is None:
            continue
        values = np.asarray(values, dtype=float)
        target = surface.copy() if surface is not None else spheres.copy()
        if surface is not None:
            target[label] = values
        else:
            target[label] = np.repeat(values, per_point)
        if label.startswith("share"):
            clim = [0.0, 1.0]
        else:
            clim = [float(values.min()), float(values.max())]
            if clim[1] - clim[0] <= 1e-9 * max(abs(clim[0]), abs(clim[1]), 1e-300):  # constant field
                pad = 0.01 * abs(clim[0]) or 1.0
                clim = [clim[0] - pad, clim[0] + pad]
        pl.add_mesh(target, scalars=label, cmap=cmap, clim=clim, lighting=False,
                    # the panel's own text names the quantity: the bar's title (which VTK draws over its
                    # tick labels on a horizontal bar) is blank, unique per bar as pyvista keys bars by it
                    scalar_bar_args={"title": " " * (k + 1), "color": "black", "vertical": False,
                                     "width": 0.8, "position_x": 0.1, "position_y": 0.05, "title_font_size": 10,
                                     "label_font_size": 9})
        bars.append(label)
        view()
    pl.subplot(1, 3)
    omega = float(data["omega"][i])
    force = f"force = {float(data['force_N'][i]):.6g} N\n" if is_force(data) else ""
    pl.add_text(f"{title}\npoint {i} of {data['omega'].size}\n{force}omega = {omega:.6g} rad/s\n"
                f"f = {omega / 2 / np.pi:.6g} Hz\n{P} pairs\nstick / slip / separated:\n"
                + " / ".join(f"{x:.2f}" for x in frac.mean(axis=0)), font_size=10, color="black",
                position="upper_left")
    path = Path(path)
    tmp = path.with_name(path.stem + ".tmp.png")
    pl.screenshot(str(tmp))
    pl.close()
    tmp.replace(path)
    W, H = window
    return Picture(path, tuple(window), legends=[STATE_NAMES[k] for k in range(3)], colorbars=bars,
                   states_shown=tuple(int(k) for k in np.unique(dom)),
                   map_box=(0, int(0.06 * H), W // 4, int(0.36 * H)))  # the top-left panel above its legend


def plot_shape(folder, i: int, path: Path, *, title: str = "", window=(1200, 600)) -> Picture:
    """The deformed shape at branch point i: the first-harmonic displacement at the phase of its
    largest norm, scaled to a tenth of the model size, coloured by its magnitude, over the
    undeformed nodes, with a ruler.  Needs shape.npz (continuum runs of `jointfem frf`)."""
    import pyvista as pv
    import vtk

    vtk.vtkLogger.SetStderrVerbosity(vtk.vtkLogger.VERBOSITY_OFF)
    folder = Path(folder)
    data = load(folder)
    with np.load(folder / "shape.npz") as z:
        shape = {k: z[k] for k in z.files}
    q = int(data["num_dofs"])
    U = data["U"][i]
    zc, zs = (U[sl] for sl in _first_harmonic(data, q))
    if "recovery" in shape:
        zc, zs = shape["recovery"] @ zc, shape["recovery"] @ zs
    X = shape["node_coords"]
    nodes, comps = shape["dof_node"], shape["dof_comp"]
    phases = np.linspace(0.0, np.pi, 33)
    best, disp = -1.0, None
    for ph in phases:
        u = np.zeros_like(X)
        u[nodes, comps] = zc * np.cos(ph) + zs * np.sin(ph)
        nrm = np.linalg.norm(u, axis=1).max()
        if nrm > best:
            best, disp = nrm, u
    extent = float(np.ptp(X, axis=0).max())
    scale = 0.1 * extent / best if best > 0 else 1.0
    cloud = pv.PolyData(X + scale * disp)
    cloud["|u| [m]"] = np.linalg.norm(disp, axis=1)
    pl = pv.Plotter(off_screen=True, window_size=list(window))
    pl.set_background("white")
    pl.add_mesh(pv.PolyData(X), color="#bbbbbb", point_size=2, render_points_as_spheres=False)
    pl.add_mesh(cloud, scalars="|u| [m]", cmap="viridis", point_size=4, render_points_as_spheres=False,
                scalar_bar_args={"title": "first-harmonic displacement amplitude [m]", "color": "black", "vertical": False,
                                 "width": 0.6, "position_x": 0.2, "position_y": 0.04})
    lo = X.min(axis=0)
    ruler = 10 ** np.floor(np.log10(extent / 3))
    pl.add_ruler(lo + [0.0, -0.15 * extent, 0.0], lo + [ruler, -0.15 * extent, 0.0], title=f"{ruler:g} m",
                 number_labels=2, font_size_factor=0.6, label_color="black", tick_color="black")
    omega = float(data["omega"][i])
    pl.add_text(f"{title}  point {i}, omega = {omega:.6g} rad/s ({omega / 2 / np.pi:.6g} Hz)\n"
                f"displacement x {scale:.3g} (largest {best:.3e} m)", font_size=10, color="black")
    pl.view_xy()
    pl.camera.azimuth = -25
    pl.camera.elevation = 25
    pl.reset_camera()
    path = Path(path)
    tmp = path.with_name(path.stem + ".tmp.png")
    pl.screenshot(str(tmp))
    pl.close()
    tmp.replace(path)
    return Picture(path, tuple(window), colorbars=["first-harmonic displacement amplitude [m]"])


def plot_folder(folder, *, point: str | None = "peak", omega: float | None = None) -> list[Picture]:
    """All pictures of a result folder into the folder: states_branch.png, and interface_<i>.png
    when the pairs' positions are known."""
    folder = Path(folder)
    data = load(folder)
    if data["states"].ndim != 3 or data["states"].shape[2] == 0:
        raise OutputError(f"{folder}: the model has no contact pairs: nothing to draw")
    i = pick_point(data, point, omega)
    pics = [plot_state_map(data, folder / "states_branch.png",
                           title=f"{folder.name}: share of the period in each state, per pair")]
    if "pair_coords" in data or (folder / "shape.npz").is_file():
        pics += _plot_vtk_isolated(folder, i, folder.name)
    return pics


def _vtk_child(folder: str, i: int, title: str, queue) -> None:
    try:
        pics = []
        data = load(folder)
        if "pair_coords" in data:
            pics.append(plot_interface(data, i, Path(folder) / f"interface_{i}.png", title=title))
        if (Path(folder) / "shape.npz").is_file():
            pics.append(plot_shape(folder, i, Path(folder) / f"shape_{i}.png", title=title))
        queue.put(pics)
    except BaseException as exc:  # noqa: BLE001 - reported by the parent
        queue.put(OutputError(f"pictures of {folder}: {exc}"))


def _plot_vtk_isolated(folder: Path, i: int, title: str) -> list[Picture]:
    """plot_interface and plot_shape in a fresh interpreter.  The VTK wheel aborts in std::regex (scalar-bar label
    formats) once dolfinx/PETSc are loaded in the same process (measured: SIGABRT from
    vtkScalarBarActor::LayoutTicks after a continuum run), so the picture is drawn where they are not."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    proc = ctx.Process(target=_vtk_child, args=(str(folder), i, title, queue))
    proc.start()
    import queue as queue_mod

    result = None
    while result is None:
        try:
            result = queue.get(timeout=1.0)
        except queue_mod.Empty:
            if not proc.is_alive():
                raise OutputError(f"pictures of {folder}: the renderer died (exit code {proc.exitcode})") from None
    proc.join()
    if isinstance(result, BaseException):
        raise result
    return result
