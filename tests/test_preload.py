"""The static preload (issue 16): bolts load the outer faces under their washers, a static contact
solve (models.preload) gives each pair its normal force N0, or its gap if it stays open, and the
dynamic problem starts from that state.

* a two-body hand case against its closed form (closed, and pulled open);
* the 3D lap joint with body B held by the joint alone: equilibrium (the pairs' normal forces sum
  to the bolt force to 1e-8), a symmetric bolt gives a symmetric pressure, stiff contact leaves
  part of the interface open with its gap, and the dynamic problem solves from that state;
* a block pressed on a clamped base (geometry "stack") against the closed form of uniaxial
  compression, in 3D and 2D, and with a washer smaller than the block: equilibrium and symmetry;
* one-line scene errors.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from conftest import ROOT

from jointfem.analysis.frf import SweepOptions, compute_frf, solve_at
from jointfem.harmonics import Harmonics
from jointfem.models.preload import solve_static_contact
from jointfem.rom import RomOptions, build_rom
from jointfem.scene import SceneError, create_structure, load_scene


def two_bodies(Fy):
    """DOFs (a_x, a_y, b_x, b_y); a on springs 1, 1 to ground, b on 1, 0.5; one pair g = u_a - u_b
    (t = x, n = y) with kt = 2, kn = 4; the force Fy on b_y."""
    K = sp.diags([1.0, 1.0, 1.0, 0.5]).tocsr()
    G = sp.csr_matrix(np.array([[1.0, 0, -1.0, 0], [0, 1.0, 0, -1.0]]))
    return solve_static_contact(K, G, np.array([2.0]), np.array([4.0]), np.array([0.0, 0.0, 0.0, Fy]),
                                num_tangential=1)


def test_hand_case_closed_and_open():
    # pushed together (b_y down): closed; a_y + 4 (a_y - b_y) = 0 and 0.5 b_y - 4 (a_y - b_y) = -3
    st = two_bodies(-3.0)
    A = np.array([[5.0, -4.0], [-4.0, 4.5]])
    ay, by = np.linalg.solve(A, [0.0, -3.0])
    assert st.closed.all() and st.iterations == 1
    assert st.N0[0] == pytest.approx(4.0 * (ay - by), rel=1e-12)
    assert st.N0[0] == pytest.approx(-ay, rel=1e-12)  # a is held by its spring alone: N = -k_a a_y
    # pulled apart: open after one change of the active set, b_y = 6, g0 = 6, N0 = -kn g0
    st = two_bodies(3.0)
    assert not st.closed.any() and st.iterations == 2
    assert st.gaps[0, 1] == pytest.approx(-6.0, rel=1e-12) and st.N0[0] == pytest.approx(-24.0, rel=1e-12)


def test_hand_case_with_an_initial_gap():
    """The same two bodies with g0: pushed by 3 N across g0 = 0.5 they close (f_n = kn (g_n - g0));
    across g0 = 10 they do not (b_y = -6 alone, the gap left 4, N0 = -kn 4)."""
    K = sp.diags([1.0, 1.0, 1.0, 0.5]).tocsr()
    G = sp.csr_matrix(np.array([[1.0, 0, -1.0, 0], [0, 1.0, 0, -1.0]]))
    F = np.array([0.0, 0.0, 0.0, -3.0])
    st = solve_static_contact(K, G, np.array([2.0]), np.array([4.0]), F, num_tangential=1, g0=np.array([0.5]))
    # a_y + 4 (a_y - b_y - 0.5) = 0,  0.5 b_y - 4 (a_y - b_y - 0.5) = -3
    ay, by = np.linalg.solve([[5.0, -4.0], [-4.0, 4.5]], [2.0, -5.0])
    assert st.closed.all() and st.N0[0] == pytest.approx(4.0 * (ay - by - 0.5), rel=1e-12) and st.N0[0] > 0
    st = solve_static_contact(K, G, np.array([2.0]), np.array([4.0]), F, num_tangential=1, g0=np.array([10.0]))
    assert not st.closed.any() and st.gaps[0, 1] == pytest.approx(6.0, rel=1e-12)
    assert st.N0[0] == pytest.approx(-16.0, rel=1e-12)


def bolted(tmp_path, kn="2.0e11", extra=""):
    """demos/lap3d_friction.toml with body B unclamped (held by the joint and the bolt alone) and
    one bolt (750 N, washer radius 8 mm) at the middle of the overlap, preload from the static solve."""
    text = (ROOT / "demos" / "lap3d_friction.toml").read_text()
    text = text.replace("pressure = 1.0e6", f'preload = "static"\n{extra}\n[[contact.bolt]]\nx = 0.285\nz = 0.0125\n'
                                            f'radius = 0.008\nforce = 750.0')
    text = text.replace("[geometry]\n", '[geometry]\nclamped = ["A"]\n').replace("kn = 2.0e11", f"kn = {kn}")
    p = tmp_path / "bolted.toml"
    p.write_text(text)
    return p


def mirror(xz, axis, about):
    """Index of each point's mirror image about the plane where column ``axis`` equals ``about``."""
    image = xz.copy()
    image[:, axis] = 2 * about - image[:, axis]
    key = {tuple(k): i for i, k in enumerate(np.round(xz / 1e-7).astype(np.int64))}
    return np.array([key[tuple(k)] for k in np.round(image / 1e-7).astype(np.int64)])


def test_bolted_lap_equilibrium_symmetry_and_dynamics(tmp_path):
    """kn = 2e11 N/m^3: every pair closes.  B is held by the joint alone, so its normal forces sum
    to the bolt's 750 N (measured 3.0e-12 relative), symmetric about the bolt's plane, peaking
    under the washer above the uniform 1 MPa; a short sweep of the stuck-linearised joint runs."""
    s = create_structure(load_scene(bolted(tmp_path)))
    pairs, coords = s.contacts[0].pairs, s.contacts[0].coords
    assert s.info["preload"] == "static" and s.info["pairs_open"] == 0
    assert pairs.N0.sum() == pytest.approx(750.0, rel=1e-8)
    np.testing.assert_allclose(pairs.N0[mirror(coords[:, [0, 2]], 1, 0.0125)], pairs.N0, rtol=1e-8)
    pressure = pairs.N0 / s.contacts[0].areas
    assert pressure.max() > 1.0e6 and s.info["peak_pressure_Pa"] == pytest.approx(pressure.max())
    assert s.info["static_tangential_use_max"] < 0.1  # the preload is far from slipping


def test_stiff_contact_leaves_pairs_open_with_their_gaps(tmp_path):
    """kn = 1e14 N/m^3: the plates cannot follow the bolt's pressure cone, and the pairs away from
    the washer open (16 of 25, gaps from 8.3e-9 to 3.0e-7 m).  Equilibrium holds over the closed pairs;
    open pairs start with N0 = -kn g0 < 0 and add nothing to the stuck linearisation; the exact
    condensation sweeps from that state, and the penalty ROM solves it too."""
    s = create_structure(load_scene(bolted(tmp_path, kn="1.0e14")))
    pairs = s.contacts[0].pairs
    closed = pairs.N0 > 0
    assert 0 < s.info["pairs_open"] == int((~closed).sum()) and s.info["pairs_closed"] == int(closed.sum())
    assert pairs.N0[closed].sum() == pytest.approx(750.0, rel=1e-8)
    assert pairs.initial_gap[~closed].min() > 0 and pairs.initial_gap.max() == pytest.approx(
        s.info["largest_static_gap_m"], rel=1e-12)
    assert (pairs.stiffness[~closed] == 0).all() and (pairs.stiffness[closed] > 0).all()
    frf = compute_frf(build_rom(s, "exact", RomOptions()), SweepOptions(1800.0, 1810.0, Harmonics(1, 64)))
    assert frf.num_points >= 2 and np.all(np.isfinite(frf.U))
    # at this forcing (3 N near 1800 rad/s) the pairs open by more than 50 nm stay open all period,
    # those open by less than 50 nm (from 8.3 nm) close for part of it, and the closed pairs never open
    sep = (frf.states == 2).mean(axis=(0, 1))
    wide = pairs.initial_gap > 5e-8
    assert wide.sum() >= 10 and (sep[wide] == 1.0).all()
    assert ((sep[~closed & ~wide] > 0) & (sep[~closed & ~wide] < 1)).all() and (sep[closed] == 0).all()
    # one omega, three methods: the condensation is the full model's equations, to its round-off: at
    # kn = 1e14 its Newton stops at its floor (residual 6e-9 of the force, Problem.tol_floor 1e-8),
    # and the amplitudes then differ from full order's (stable to 1e-10 here) by -8.0e-7 (OpenBLAS
    # Prescott kernel), -1.4e-7 (Haswell), +4.7e-7 (SkylakeX; Cooperlake on an AMD EPYC) and 3.3e-9
    # (a Xeon's Prescott), measured 2026-12-07: bounded at 5e-6, six times the largest; the penalty ROM
    # with 10 modes and 3 TVDs (its open pairs active from the start) within its truncation (4.5e-3)
    h = Harmonics(1, 64)
    amp = {m: solve_at(s if m == "full" else build_rom(s, m, RomOptions(modes=10, tvd=3)), 1800.0, h).amplitudes
           for m in ("full", "exact", "penalty")}
    for out in amp["full"]:
        assert amp["exact"][out] == pytest.approx(amp["full"][out], rel=5e-6)
        assert amp["penalty"][out] == pytest.approx(amp["full"][out], rel=1e-2)


@pytest.mark.parametrize("extra, key, why", [
    ("pressure = 1.0e5", "contact.pressure", "comes from the static"),
    ("patches_only = true", "contact.patches_only", "decides which pairs"),
])
def test_static_preload_scene_errors(tmp_path, extra, key, why):
    with pytest.raises(SceneError, match=key.replace(".", r"\.")) as exc:
        load_scene(bolted(tmp_path, extra=extra))
    assert why in str(exc.value)


def test_bolts_default_to_the_static_preload(tmp_path):
    """Without a preload key, bolts load the outer faces through the static solve; with a pressure
    beside them the error names the default and the way to the patches."""
    p = bolted(tmp_path)
    p.write_text(p.read_text().replace('preload = "static"', ""))
    assert load_scene(p).model.preload == "static"
    p.write_text(p.read_text().replace("[[contact.bolt]]", "pressure = 1.0e5\n[[contact.bolt]]"))
    with pytest.raises(SceneError, match=r"contact\.pressure = 100000\.0: .*leave pressure out \(the default with "
                                         r"bolts; preload = \"uniform\""):
        load_scene(p)
    p.write_text(p.read_text().replace("pressure = 1.0e5", 'preload = "uniform"'))
    assert load_scene(p).model.preload == "uniform"


def test_static_preload_needs_a_bolt(tmp_path):
    text = (ROOT / "demos" / "lap3d_friction.toml").read_text().replace("pressure = 1.0e6", 'preload = "static"')
    p = tmp_path / "nobolt.toml"
    p.write_text(text)
    with pytest.raises(SceneError, match=r"contact\.preload = 'static': needs at least one"):
        load_scene(p)


@pytest.mark.slow
def test_static_preload_under_mpi_equals_serial(tmp_path):
    """`mpirun -n 2 jointfem modes` on the stiff bolted lap (distributed assembly, MUMPS for the
    static solve, SLEPc): the same contact state, so the same stuck frequencies, whose open pairs
    add no stiffness, as in serial, to 1e-8 (measured: every printed digit)."""
    import csv
    import os
    import subprocess
    import sys

    from test_continuum import _mpirun

    text = (ROOT / "demos" / "lap3d_bolted.toml").read_text().replace("kn = 2.0e11", "kn = 1.0e14")
    scene = tmp_path / "bolted.toml"
    scene.write_text(text)
    env = dict(os.environ, JOINTFEM_LINALG="petsc")
    args = [sys.executable, "-m", "jointfem", "modes", str(scene), "--out"]
    subprocess.run(args + [str(tmp_path / "serial")], check=True, env=env, cwd=ROOT, timeout=600, capture_output=True)
    subprocess.run(_mpirun() + args + [str(tmp_path / "mpi")], check=True, env=env, cwd=ROOT, timeout=600,
                   capture_output=True)

    def stuck(folder):
        with open(folder / "modes.csv") as fh:
            return np.array([float(r["stuck_omega_rad_s"]) for r in csv.DictReader(fh)])

    a, b = stuck(tmp_path / "serial"), stuck(tmp_path / "mpi")
    assert a.size >= 5
    np.testing.assert_allclose(b, a, rtol=1e-8)
    # the scene does leave pairs open (their gaps are what the two runs had to agree on)
    assert create_structure(load_scene(scene)).info["pairs_open"] > 0


def test_a_washer_that_covers_no_node_is_one_error(tmp_path):
    """A bolt whose washer holds no quadrature point of an outer face (radius 0.1 mm between the
    points) is named, with its position and radius, before any solve."""
    from jointfem.fem.continuum import ContinuumError

    p = bolted(tmp_path)
    p.write_text(p.read_text().replace("radius = 0.008", "radius = 0.0001").replace("x = 0.285", "x = 0.2811"))
    with pytest.raises(ContinuumError, match=r"bolt 0 at x = 0\.2811, z = 0\.0125 m with radius 0\.0001 m covers none "
                                             r"of the outer face of A \(no quadrature point"):
        create_structure(load_scene(p))


STACK = """kind = "continuum{dim}d"
name = "stack"
[solver]
omega_range = [1000.0, 2000.0]
[geometry]
shape = "stack"
length = 0.04
height = 0.01
width = 0.03
[mesh]
size = {size}
size_normal = 0.005
degree = {degree}
[material]
young = 2.0e11
poisson = {nu}
[contact]
kt = 1.0e13
kn = 1.0e13
mu = 0.3
preload = "static"
[[contact.bolt]]
x = 0.02
z = 0.015
radius = {radius}
force = 1200.0
"""


def stack(tmp_path, dim=3, size=0.01, degree=2, nu=0.0, radius=0.05):
    p = tmp_path / f"stack{dim}.toml"
    p.write_text(STACK.format(dim=dim, size=size, degree=degree, nu=nu, radius=radius))
    return create_structure(load_scene(p))


@pytest.mark.parametrize("dim, degree", [(3, 2), (3, 1), (2, 2)])
def test_block_pressed_on_a_base_is_uniaxial_compression(tmp_path, dim, degree):
    """A block on a base clamped at its bottom, pressed by a washer wider than the block, with
    Poisson's ratio 0: the exact solution is uniform uniaxial compression, which Lagrange elements of
    either degree hold exactly; so the washer's consistent load reaches the interface as the pressure
    p = F / (L W), every pair carries p times its area and closes by p / kn.  Measured 3.3e-14 (3D,
    degree 2); equal nodal shares of the washer's force, as before, missed it by O(1) (the corner and
    mid-side nodes of a degree-2 face carry 1/36 and 4/36 of an element's load, not the same)."""
    s = stack(tmp_path, dim=dim, degree=degree)
    g = s.contacts[0]
    p = 1200.0 / (0.04 * 0.03)
    assert s.info["pairs_open"] == 0 and s.info["num_pairs"] == g.areas.size > 4
    assert g.areas.sum() == pytest.approx(0.04 * 0.03, rel=1e-12)
    np.testing.assert_allclose(g.pairs.N0, p * g.areas, rtol=1e-10)
    # the closure: N0 = kn_pair g with kn_pair = kn area
    np.testing.assert_allclose(g.pairs.N0 / g.pairs.kn, p / 1.0e13, rtol=1e-10)
    assert s.info["static_tangential_use_max"] < 1e-10  # no Poisson effect: nothing pulls sideways


def test_washer_on_a_block_equilibrium_symmetry_and_convergence(tmp_path):
    """A 12 mm washer on the block's top (nu = 0.3): B is held by the joint alone, so the pairs'
    normal forces sum to the bolt's force (1e-10); the pressure is mirror-symmetric about both planes
    through the bolt (1e-8); it peaks on the axis above the mean F / (L W), and halving the elements
    moves that peak by less than 2 % (measured 1.888 and 1.877 MPa, 0.6 %; 1.878 MPa at 1.25 mm)."""
    peak = []
    for size in (0.005, 0.0025):
        s = stack(tmp_path, size=size, nu=0.3, radius=0.012)
        g = s.contacts[0]
        pr = g.pairs.N0 / g.areas  # an open pair's is -kn g0 / area < 0
        assert g.pairs.N0[pr > 0].sum() == pytest.approx(1200.0, rel=1e-10)
        for axis, about in ((0, 0.02), (1, 0.015)):
            np.testing.assert_allclose(pr[mirror(g.coords[:, [0, 2]], axis, about)], pr, rtol=1e-8)
        on_axis = np.argmin(np.hypot(g.coords[:, 0] - 0.02, g.coords[:, 2] - 0.015))
        assert pr[on_axis] == pytest.approx(pr.max(), rel=1e-12) and pr.max() > 1200.0 / (0.04 * 0.03)
        peak.append(pr.max())
    assert peak[1] == pytest.approx(peak[0], rel=0.02)


def crowned(tmp_path, gap_table: str, nu=0.3, radius=0.05, size=0.0025):
    p = tmp_path / "crowned.toml"
    p.write_text(STACK.format(dim=3, size=size, degree=2, nu=nu, radius=radius) + "[contact.gap]\n" + gap_table)
    return create_structure(load_scene(p))


def test_crowned_interface_touches_at_its_centre(tmp_path):
    """A spherical crown of radius 10 m between the block and its base (g0 up to 31 um at the
    corners), the block pressed by a washer wider than it and held by the joint alone: the pairs'
    normal forces still sum to the bolt's (1e-10); the pressure is symmetric about both mid-planes
    (1e-8); only a patch about the centre closes (measured 97 of 825 pairs), every open pair keeps
    part of its geometric gap (0 < static gap <= g0), and the closed patch holds the pairs nearest
    the centre.  The same crown given as a table of its values at the nodes (linear interpolation
    is exact there) gives the same normal forces to 1e-9."""
    s = crowned(tmp_path, 'kind = "crown"\nradius = 10.0\n')
    g = s.contacts[0]
    N0, xz = g.pairs.N0, g.coords[:, [0, 2]]
    closed = N0 > 0
    g0 = np.sum((xz - [0.02, 0.015]) ** 2, axis=1) / 20.0
    assert s.info["geometric_gap_max_m"] == pytest.approx(g0.max(), rel=1e-12)
    assert 0 < closed.sum() < closed.size / 4
    assert N0[closed].sum() == pytest.approx(1200.0, rel=1e-10)
    static_gap = g.pairs.initial_gap[~closed]
    assert (static_gap > 0).all() and (static_gap <= g0[~closed] * (1 + 1e-12)).all()
    r = np.hypot(*(xz - [0.02, 0.015]).T)
    assert r[closed].max() < r[~closed].min() + 1e-12
    for axis, about in ((0, 0.02), (1, 0.015)):
        np.testing.assert_allclose(N0[mirror(xz, axis, about)], N0, rtol=1e-8, atol=1e-10 * np.abs(N0).max())
    # the same crown as measured topology: a CSV of its values at the contact nodes
    rows = "\n".join(f"{x!r},{z!r},{gg!r}" for (x, z), gg in zip(xz, g0))
    (tmp_path / "topology.csv").write_text("x,z,gap\n" + rows + "\n")
    t = crowned(tmp_path, 'kind = "table"\nfile = "topology.csv"\n')
    np.testing.assert_allclose(t.contacts[0].pairs.N0, N0, rtol=1e-9, atol=1e-9 * np.abs(N0).max())


def test_a_uniform_geometric_gap_only_moves_the_block(tmp_path):
    """A gap of 5 um everywhere (a table of four corners) is closed by the press before any force
    passes: uniaxial compression again (nu = 0), each pair carrying p times its area (1e-10)."""
    (tmp_path / "flat.csv").write_text("x,z,gap\n0,0,5e-6\n0.04,0,5e-6\n0,0.03,5e-6\n0.04,0.03,5e-6\n")
    s = crowned(tmp_path, 'kind = "table"\nfile = "flat.csv"\n', nu=0.0, size=0.01)
    g = s.contacts[0]
    assert s.info["pairs_open"] == 0
    np.testing.assert_allclose(g.pairs.N0, 1200.0 / (0.04 * 0.03) * g.areas, rtol=1e-10)


def test_geometric_gaps_without_preload_start_open(tmp_path):
    """No bolts, no pressure: each pair of the crown starts open by its own g0 (N0 = -kn g0), the
    one at the centre (g0 = 0) closed without force."""
    text = STACK.format(dim=3, size=0.01, degree=2, nu=0.3, radius=0.05)
    text = text[:text.index("[[contact.bolt]]")].replace('preload = "static"\n', "")
    p = tmp_path / "free.toml"
    p.write_text(text + '[contact.gap]\nkind = "crown"\nradius = 10.0\ncentre = [0.02, 0.015]\n')
    s = create_structure(load_scene(p))
    g = s.contacts[0]
    g0 = np.sum((g.coords[:, [0, 2]] - [0.02, 0.015]) ** 2, axis=1) / 20.0
    np.testing.assert_allclose(g.pairs.initial_gap, g0, rtol=1e-12, atol=1e-15)
    assert s.info["pairs_open_at_rest"] == int((g0 > 1e-15).sum()) == g0.size - 1


@pytest.mark.parametrize("gap, csv, key, why", [
    ('kind = "table"\nfile = "none.csv"', None, "contact.gap.file", "cannot be read"),
    ('kind = "table"\nfile = "t.csv"', "x,y,gap\n0,0,0\n1,0,0\n0,1,0\n", "contact.gap.file", "the header x,z,gap"),
    ('kind = "table"\nfile = "t.csv"', "x,z,gap\n0,0,0\n1,0,-1e-6\n0,1,0\n", "contact.gap.file", "row 3 has gap"),
    ('kind = "crown"\nradius = -1.0', None, "contact.gap.radius", "> 0"),
    ('kind = "crown"\nradius = 1.0\ncentre = [0.02]', None, "contact.gap.centre", "must be [x, z]"),
    ('kind = "wavy"', None, "contact.gap.kind", "one of"),
])
def test_gap_profile_scene_errors(tmp_path, gap, csv, key, why):
    if csv is not None:
        (tmp_path / "t.csv").write_text(csv)
    p = tmp_path / "bad.toml"
    p.write_text(STACK.format(dim=3, size=0.01, degree=2, nu=0.3, radius=0.05) + "[contact.gap]\n" + gap + "\n")
    with pytest.raises(SceneError, match=key.replace(".", r"\.")) as exc:
        load_scene(p)
    assert why in str(exc.value)


def test_gap_table_must_cover_the_interface(tmp_path):
    """Pairs outside the measured points are one error naming the file and the first such pair."""
    from jointfem.fem.continuum import ContinuumError

    (tmp_path / "small.csv").write_text("x,z,gap\n0,0,0\n0.02,0,0\n0,0.03,0\n0.02,0.03,0\n")
    with pytest.raises(ContinuumError, match=r"contact pairs lie outside the points of .*small\.csv"):
        crowned(tmp_path, 'kind = "table"\nfile = "small.csv"\n', size=0.01)


def test_gaps_with_a_prescribed_pressure_are_refused(tmp_path):
    text = (ROOT / "demos" / "lap3d_friction.toml").read_text()
    p = tmp_path / "g.toml"
    p.write_text(text + '\n[contact.gap]\nkind = "crown"\nradius = 10.0\n')
    with pytest.raises(SceneError, match=r"contact\.gap\.kind = 'crown': initial gaps need preload"):
        load_scene(p)


def test_crowned_interface_in_2d(tmp_path):
    """The 2D crown (a cylinder, g0 = (x - x_c)^2 / (2 R)): equilibrium over the closed pairs (1e-10),
    a central patch (measured 7 of 33 pairs), and the table of its nodal values (header x,gap) equal."""
    def build(gap):
        p = tmp_path / "c2.toml"
        p.write_text(STACK.format(dim=2, size=0.0025, degree=2, nu=0.3, radius=0.05) + "[contact.gap]\n" + gap)
        return create_structure(load_scene(p)).contacts[0]

    g = build('kind = "crown"\nradius = 10.0\n')
    N0, x = g.pairs.N0, g.coords[:, 0]
    assert N0[N0 > 0].sum() == pytest.approx(1200.0, rel=1e-10) and 0 < (N0 > 0).sum() < N0.size / 3
    (tmp_path / "t.csv").write_text("x,gap\n" + "\n".join(f"{a!r},{(a - 0.02) ** 2 / 20.0!r}" for a in x) + "\n")
    np.testing.assert_allclose(build('kind = "table"\nfile = "t.csv"\n').pairs.N0, N0, rtol=1e-9,
                               atol=1e-9 * np.abs(N0).max())


def test_frictionless_loading_path(tmp_path):
    """preload_path = "frictionless": the static solve carries no tangential force, which is what
    the dynamics (sliders start unloaded) assume.  The block on its base, held sideways only by soft
    springs on its top face (x and z, 1 N/m each), with nu = 0: uniaxial compression, each pair
    carrying p times its area (1e-10), no tangential force at all.  Held by the joint alone it is
    refused in one line naming the way out."""
    from jointfem.fem.continuum import ContinuumError

    text = STACK.format(dim=3, size=0.01, degree=2, nu=0.0, radius=0.05).replace(
        'preload = "static"', 'preload = "static"\npreload_path = "frictionless"')
    p = tmp_path / "free.toml"
    p.write_text(text)
    with pytest.raises(ContinuumError, match=r"preload_path = \"frictionless\" the joint holds nothing tangentially"):
        create_structure(load_scene(p))
    p.write_text(text + "[[support]]\nat = [0.02, 0.02, 0.015]\nstiffness = [1.0, 0.0, 1.0]\nradius = 0.05\n")
    s = create_structure(load_scene(p))
    g = s.contacts[0]
    assert s.info["preload_path"] == "frictionless" and s.info["static_tangential_use_max"] == 0.0
    np.testing.assert_allclose(g.pairs.N0, 1200.0 / (0.04 * 0.03) * g.areas, rtol=1e-10)


def test_frictionless_path_on_the_bolted_lap(tmp_path):
    """The bolted lap clamped at both ends: with no tangential springs in the static solve the
    pressure stays mirror-symmetric (1e-8) and differs from the stuck path's by the plates' Poisson
    expansion (measured 0.13 % of the peak): not nothing, not large."""
    text = (ROOT / "demos" / "lap3d_bolted.toml").read_text()
    p = tmp_path / "lap.toml"
    p.write_text(text)
    stuck = create_structure(load_scene(p))
    p.write_text(text.replace('\npreload = "static"', '\npreload = "static"\npreload_path = "frictionless"'))
    free = create_structure(load_scene(p))
    a, b = stuck.contacts[0].pairs.N0, free.contacts[0].pairs.N0
    np.testing.assert_allclose(b[mirror(free.contacts[0].coords[:, [0, 2]], 1, 0.0125)], b, rtol=1e-8)
    assert free.info["static_tangential_use_max"] == 0.0 < stuck.info["static_tangential_use_max"]
    assert 1e-4 < np.abs(b - a).max() / a.max() < 0.05


def test_preload_path_needs_the_static_solve(tmp_path):
    text = (ROOT / "demos" / "lap3d_friction.toml").read_text().replace("pressure = 1.0e6",
                                                                         'pressure = 1.0e6\npreload_path = "frictionless"')
    p = tmp_path / "u.toml"
    p.write_text(text)
    with pytest.raises(SceneError, match=r"contact\.preload_path = 'frictionless': is the static solve's loading path"):
        load_scene(p)


def test_bolts_on_a_stack_clamped_on_both_faces_are_one_error(tmp_path):
    """Both outer faces clamped: the washers would load nothing; said before any solve."""
    from jointfem.fem.continuum import ContinuumError

    p = tmp_path / "both.toml"
    p.write_text(STACK.format(dim=3, size=0.01, degree=2, nu=0.3, radius=0.05).replace(
        'width = 0.03\n', 'width = 0.03\nclamped = ["A", "B"]\n', 1))
    with pytest.raises(ContinuumError, match=r"both outer faces are clamped, so the bolts' washers load nothing"):
        create_structure(load_scene(p))


@pytest.mark.parametrize("old, new, key, why", [
    ("width = 0.03\n", "width = 0.03\noverlap = 0.01\n", "geometry.overlap", "covers its base"),
    ('preload = "static"\n', 'preload = "static"\ngap = 1e-6\n', "contact.gap", "must be a table"),
])
def test_stack_and_gap_key_errors(tmp_path, old, new, key, why):
    """A stack has no overlap key (its joint is the whole length); [contact.gap] must be a table."""
    p = tmp_path / "bad.toml"
    p.write_text(STACK.format(dim=3, size=0.01, degree=2, nu=0.3, radius=0.05).replace(old, new, 1))
    with pytest.raises(SceneError, match=key.replace(".", r"\.")) as exc:
        load_scene(p)
    assert why in str(exc.value)
