"""Continuation in the force amplitude at a fixed omega (jointfem.analysis.force)."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, sdof
from jointfem.analysis.force import compute_force_response
from jointfem.analysis.frf import solve_at
from jointfem.harmonics import Harmonics
from jointfem.models.lumped import create_lumped
from jointfem.rom import RomOptions, build_rom


def test_force_branch_is_linear_when_stuck_and_each_point_solves_the_scaled_problem():
    """SDOF Jenkins at 1.2 rad/s, force scale 0.01 to 1 of F = 1 N: at the start (stuck) the
    amplitude is the linear |F / (k + kt - w^2 + i c w)| to 1e-12; the branch reaches slip; and
    each point is the fixed-omega solution of the model with that force (solve_at, 1e-10).  The
    penalty ROM with its only mode gives the same branch (its active set grows along it): the full
    model solved at the ROM's force scales from the linear guess agrees to 1e-10."""
    h = Harmonics(7, 256)
    r = compute_force_response(create_lumped(sdof(1.0)), 1.2, h, 0.01, 1.0)
    a = r.amplitude("m.x")
    assert a[0] == pytest.approx(0.01 / abs(2.0 - 1.44 + 0.024j), rel=1e-12)
    assert (r.states == 1).any() and r.scale[-1] >= 1.0 and np.all(np.diff(r.scale) > 0)
    for k in (len(a) // 3, 2 * len(a) // 3, len(a) - 1):
        sol = solve_at(create_lumped(sdof(float(r.scale[k]))), 1.2, h, guess=r.U[k])
        assert sol.iterations <= 1 and sol.amplitudes["m.x"] == pytest.approx(a[k], rel=1e-10)
    p = compute_force_response(build_rom(create_lumped(sdof(1.0)), "penalty", RomOptions(modes=1)), 1.2, h, 0.01, 1.0)
    assert p.info["arrays"]["rom_size"].max() > p.info["arrays"]["rom_size"].min()  # it resized
    pa = p.amplitude("m.x")
    for k in range(0, len(pa), 4):  # the full model solved at the ROM's force scales: the same to round-off
        full = solve_at(create_lumped(sdof(float(p.scale[k]))), 1.2, h, )
        assert pa[k] == pytest.approx(full.amplitudes["m.x"], rel=1e-10)


def test_force_command_writes_its_files(tmp_path):
    out = tmp_path / "f"
    r = subprocess.run([sys.executable, "-m", "jointfem", "force", str(ROOT / "demos" / "sdof_jenkins.toml"),
                        "--omega", "1.2", "--scale", "0.05", "5", "--out", str(out), "--quiet"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    data = np.loadtxt(out / "force.csv", delimiter=",", skiprows=1)
    head = (out / "force.csv").read_text().splitlines()[0].split(",")
    assert head[:3] == ["force_scale", "force_N", "m.x_amp1_m"]
    assert data[0, 0] == pytest.approx(0.05) and data[-1, 0] >= 5.0
    np.testing.assert_allclose(data[:, 1], 0.2 * data[:, 0])  # the scene's force is 0.2 N
    s = json.loads((out / "summary.json").read_text())
    assert s["omega_rad_s"] == 1.2 and s["status"] == "complete" and s["num_points"] == data.shape[0]
    assert (out / "force.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # plot draws the force sweep (issue 50, item 9: plot and export stopped on a KeyError traceback):
    # the state map along the force, which the branch holds per point as force.csv does
    from jointfem import cli
    from jointfem.viz import fractions, load

    assert cli.main(["plot", str(out), "--quiet"]) == 0
    assert (out / "states_branch.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    b = load(out)
    np.testing.assert_allclose(b["force_N"], data[:, 1], rtol=1e-12)  # force.csv: 13 significant digits
    assert np.all(b["omega"] == 1.2) and list(b["output_names"]) == ["m.x"]
    assert fractions(b, 0)[0, 0] == 1.0 and fractions(b, -1)[0, 1] > 0  # stuck at 0.01 N, slipping at 1 N
    # a force sweep's points are all at one omega: --omega is refused in one line; export has nothing
    # to write for a lumped model (no positions, no mesh) and says so as for a sweep's folder
    for argv, words in ((["plot", str(out), "--omega", "1.2"], "a force sweep's points are all at omega = 1.2"),
                        (["export", str(out)], "nothing to export at point")):
        r = subprocess.run([sys.executable, "-m", "jointfem", *argv], capture_output=True, text=True)
        assert r.returncode == 2 and words in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (out / "export").exists()


def test_a_force_sweep_that_stops_keeps_its_points_and_resumes(tmp_path):
    """`jointfem force` stopped by its budget (max_points = 8) writes the converged points with
    status incomplete and exits 3 with one line that says how to go on; --resume then ends with
    the same branch as an uninterrupted run (points to 1e-8).  A folder of a frf run, or at
    another omega, is refused with one line."""
    text = (ROOT / "demos" / "sdof_jenkins.toml").read_text().replace("samples = 256\n",
                                                                     "samples = 256\nmax_points = 8\n")
    stopped = tmp_path / "sdof.toml"
    stopped.write_text(text)
    full = ROOT / "demos" / "sdof_jenkins.toml"
    a, b = tmp_path / "a", tmp_path / "b"
    args = ["--omega", "1.2", "--scale", "0.05", "5", "--quiet"]

    def run(*extra):
        return subprocess.run([sys.executable, "-m", "jointfem", "force", *extra, *args], capture_output=True,
                              text=True)

    r = run(str(stopped), "--out", str(a))
    assert r.returncode == 3 and r.stderr.count("\n") == 1 and f"--resume {a}" in r.stderr, r.stderr
    s = json.loads((a / "summary.json").read_text())
    assert s["status"] == "incomplete" and "max_points" in s["stop_reason"] and s["num_points"] == 8
    assert np.loadtxt(a / "force.csv", delimiter=",", skiprows=1).shape[0] == 8
    r = run(str(full), "--resume", str(a))
    assert r.returncode == 0, r.stderr
    r = run(str(full), "--out", str(b))
    assert r.returncode == 0, r.stderr
    ra, rb = (np.load(f / "branch.npz") for f in (a, b))
    assert json.loads((a / "summary.json").read_text())["status"] == "complete"
    assert ra["scale"].size == rb["scale"].size > 8
    np.testing.assert_allclose(ra["scale"], rb["scale"], rtol=1e-8, atol=0)
    np.testing.assert_allclose(ra["U"], rb["U"], rtol=0, atol=1e-8 * np.abs(rb["U"]).max())
    # refused with one line: a complete folder, another omega, a frf folder
    r = run(str(full), "--resume", str(b))
    assert r.returncode == 2 and "not incomplete" in r.stderr and r.stderr.count("\n") == 1, r.stderr
    run(str(stopped), "--out", str(a))
    r = subprocess.run([sys.executable, "-m", "jointfem", "force", str(full), "--omega", "1.3", "--scale", "0.05",
                        "5", "--quiet", "--resume", str(a)], capture_output=True, text=True)
    assert r.returncode == 2 and "omega_rad_s" in r.stderr and r.stderr.count("\n") == 1, r.stderr
    f = tmp_path / "frf"
    subprocess.run([sys.executable, "-m", "jointfem", "frf", str(stopped), "--out", str(f), "--quiet"],
                   capture_output=True, text=True)
    r = run(str(full), "--resume", str(f))
    assert r.returncode == 2 and "not a force run" in r.stderr and r.stderr.count("\n") == 1, r.stderr


def test_a_continuum_force_folder_exports_its_shape_and_pairs(tmp_path):
    """Issue 50, item 9: ``jointfem export`` of a `jointfem force` folder of the 2D lap joint (penalty
    ROM, H = 1) writes the mesh with the displacement harmonics (shape.npz, now written by force as by
    frf) and the pairs at the largest amplitude; the pairs' values are branch.npz's at that point
    (exactly: the same numbers written twice), and the first harmonic is the ROM's coordinates
    expanded through its basis.  A force folder of an older jointfem (no output layout) is refused in
    one line."""
    import meshio

    from jointfem import cli
    from jointfem.harmonics import Harmonics
    from jointfem.viz import load

    out = tmp_path / "lap"
    assert cli.main(["force", str(ROOT / "demos" / "lap2d.toml"), "--omega", "3000", "--scale", "0.5", "1",
                     "--method", "penalty", "--harmonics", "1", "--samples", "16", "--out", str(out), "--quiet"]) == 0
    b = load(out)
    i = int(np.argmax(np.loadtxt(out / "force.csv", delimiter=",", skiprows=1)[:, 2]))
    assert cli.main(["export", str(out), "--quiet"]) == 0
    pairs = meshio.read(out / "export" / f"pairs_{i}.vtu")
    np.testing.assert_array_equal(pairs.point_data["energy_J"], b["pair_energy_J"][i])
    np.testing.assert_array_equal(pairs.point_data["tangential_amp_m"], b["pair_tangential_amp_m"][i])
    assert pairs.points.shape[0] == b["pair_coords"].shape[0] == 7
    field = meshio.read(out / "export" / f"field_{i}.vtu")
    with np.load(out / "shape.npz") as z:
        q, h = int(b["num_dofs"]), Harmonics(1, 16)
        u1 = z["recovery"] @ b["U"][i][h.cos(1, q)]
        np.testing.assert_allclose(field.point_data["u_1_cos"][z["dof_node"], z["dof_comp"]], u1,
                                   rtol=0, atol=1e-12 * np.abs(u1).max())
    with np.load(out / "branch.npz") as z:  # as an older jointfem wrote a force folder
        old = {k: z[k] for k in ("scale", "U", "states", "H", "N")}
    np.savez(out / "branch.npz", omega=3000.0, **old)
    r = subprocess.run([sys.executable, "-m", "jointfem", "plot", str(out)], capture_output=True, text=True)
    assert r.returncode == 2 and "no output layout" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
