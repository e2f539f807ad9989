"""The distributed offline stage (issue 17): K, M and the static modes stay in row blocks on the
ranks, only reduced data crosses, and the penalty ROM equals the replicated one."""
import copy
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jointfem import linalg
from jointfem.analysis.frf import solve_at
from jointfem.fem.continuum import ContinuumError, create_continuum
from jointfem.harmonics import Harmonics
from jointfem.rom.common import RomOptions
from jointfem.rom.penalty import PenaltyROM
from jointfem.scene import load_scene, parse_scene
from test_continuum import _mpirun, same_curve

ROOT = Path(__file__).resolve().parents[1]
OMEGAS = [1690.0, 1700.0, 1710.0, 1720.0]  # rad/s: around the stuck 2nd bending mode (1707.0 on the 10 mm mesh)


def lap_spec(size: float, force: float, **keys):
    """demos/lap3d.toml at element size ``size`` m and ``force`` N (no mesh file written)."""
    data = copy.deepcopy(load_scene(ROOT / "demos" / "lap3d.toml").data)
    data["mesh"].pop("file", None)
    data["mesh"]["size"] = size
    data["force"]["amplitude"] = force
    for key, value in keys.items():
        table, k = key.split("__")
        data[table][k] = value
    return parse_scene(data, "lap3d_distributed.toml").model


def _reference(spec):
    """The replicated penalty ROM (every rank holds K, M and the basis): frequencies, the linear
    response at the outputs, and the nonlinear points at OMEGAS (H = 3, N = 128)."""
    rom = PenaltyROM(create_continuum(spec), RomOptions(modes=10))
    w = np.array(OMEGAS)
    linear = {nm: rom.structure.linear_response(w) @ row for nm, row in rom.structure.outputs.items()}
    h = Harmonics(3, 128)
    nonlinear = {str(om): solve_at(rom, om, h) for om in OMEGAS}
    return rom, linear, nonlinear


@pytest.mark.slow
def test_two_ranks_gather_no_model_sized_array_and_equal_serial(tmp_path):
    """`mpirun -n 2`: every array the distributed offline stage gathers or reduces across the
    ranks is of the size of the interface (J contact components by q ROM coordinates) or smaller,
    never of the model's n DOFs; the one n-sized exchange is the static modes' move from the rows
    MUMPS holds to the rows PETSc gives each rank (jointfem.mumps), in which no rank receives more
    than its own rows (what PETSc's MatMatSolve did inside PETSc before).  The replicated path's
    audit does show n-sized gathers (so the audit can fail).  The ROM equals the replicated serial
    one to 1e-8: natural frequencies, the linear response at the outputs, and nonlinear stick-slip
    points (3 N, H = 3) with their active sets."""
    size, force = 0.01, 3.0  # 7686 matrix rows (7560 free DOFs), 49 pairs, 147 components
    spec = lap_spec(size, force)
    rom, linear, nonlinear = _reference(spec)
    out = tmp_path / "distributed.json"
    subprocess.run(_mpirun() + [sys.executable, str(ROOT / "tests" / "distributed_run.py"), str(out), str(size),
                                str(force), ",".join(map(str, OMEGAS))], check=True, cwd=ROOT, timeout=600,
                   env=dict(os.environ))
    res = json.loads(out.read_text())
    n, J, q = res["n"], rom.num_comp, rom.K.shape[0]
    assert res["ranks"] == 2 and res["free_dofs"] == rom.full_size == 7560 and n == 7686
    assert 0 < res["rows"][1] - res["rows"][0] < n  # this rank held only part of the rows
    # the audit: what crossed, by kind and shape.  Reductions and gathers of reduced data: the
    # largest is the gap rows of the basis, J x q
    audit = [(kind, tuple(s)) for kind, s in res["audit"]]
    assert {kind for kind, _ in audit} == {"allreduce", "allgather", "gather", "redistribute"}
    reduced = [s for kind, s in audit if kind in ("allreduce", "allgather")]
    assert max(max(s) for s in reduced if s) <= max(J, q) < n / 40
    # the static modes' right-hand sides reach MUMPS's host as their nonzeros: a component of a 3D
    # pair reads at most the 3 + 3 DOFs of its two nodes
    sent = [s for kind, s in audit if kind == "gather"]
    assert len(sent) == 1 and 2 * J <= sent[0][0] <= 6 * J
    # and their solution goes from where MUMPS holds it to the ranks that own its rows: no rank
    # receives more than its own rows (rank 0's record; what rank 1 receives is the rest)
    own = res["rows"][1] - res["rows"][0]
    moved = [s for kind, s in audit if kind == "redistribute"]
    assert moved and all(s[0] <= own < n for s in moved)
    old = [tuple(s) for _, s in res["replicated_audit"]]
    assert any(s and max(s) >= n for s in old)  # K, M and the modes gathered whole
    # the results, against the serial replicated ROM
    np.testing.assert_allclose(res["frequencies"], rom.natural_frequencies(10), rtol=1e-8)
    for name, X in linear.items():
        Xd = np.array(res["linear"][name][0]) + 1j * np.array(res["linear"][name][1])
        assert np.abs(Xd - X).max() <= 1e-8 * np.abs(X).max(), name
    slipping = 0
    for om, sol in nonlinear.items():
        got = res["nonlinear"][om]
        assert got["active"] == int(np.sum(sol.record.active)), om
        slipping += got["active"] > 0
        for name, a in sol.amplitudes.items():
            assert got["amplitudes"][name] == pytest.approx(a, rel=1e-8), (om, name)
    # stick-slip and separation, not the linear model (serially measured: 0, 106, 147 and 28 of the
    # 147 components active at these omegas)
    assert slipping >= 3


@pytest.mark.parametrize("name", ["lap3d", "lap2d"])
def test_one_rank_equals_the_replicated_rom(name):
    """Serially, the distributed code path builds the same ROM (frequencies to 1e-8, output FRF to
    1e-8; measured 1e-10 and 1e-9) from the PETSc matrices as the replicated one from the gathered
    scipy matrices, and its reduced matrices cross nothing model-sized."""
    from jointfem.fem.distributed import create_distributed

    if name == "lap3d":
        spec = lap_spec(0.015, 1.0)
    else:  # the 2D demo as it is (720 free DOFs, 7 pairs)
        data = copy.deepcopy(load_scene(ROOT / "demos" / "lap2d.toml").data)
        data["mesh"].pop("file", None)
        spec = parse_scene(data, "lap2d_distributed.toml").model
    ref = PenaltyROM(create_continuum(spec), RomOptions(modes=8))
    with linalg.gather_audit() as audit:
        model = create_distributed(spec)
        rom = PenaltyROM(None, RomOptions(modes=8), distributed=model)
    assert rom.size == ref.size and rom.num_comp == ref.num_comp and rom.full_size == ref.full_size
    assert rom.info["offline"] == "distributed" and rom.basis is None
    assert all(max(s, default=0) < model.n / 10 for _, s in audit)
    np.testing.assert_allclose(rom.natural_frequencies(8), ref.natural_frequencies(8), rtol=1e-8)
    w = np.linspace(1400.0, 1900.0, 11)
    for out, row in ref.structure.outputs.items():
        X = ref.structure.linear_response(w) @ row
        Xd = rom.structure.linear_response(w) @ rom.structure.outputs[out]
        assert np.abs(Xd - X).max() <= 1e-8 * np.abs(X).max(), out
    # the pairs in the same order, at the same places, with the same laws
    np.testing.assert_allclose(rom.pair_coords, ref.pair_coords, atol=1e-12)
    np.testing.assert_allclose(rom.groups[0].group.pairs.stiffness, ref.groups[0].group.pairs.stiffness, rtol=1e-12)
    with pytest.raises(Exception, match="row blocks"):
        rom.reconstruct(np.zeros(rom.K.shape[0]))
    model.destroy()


@pytest.mark.parametrize("change,match", [
    ({"preload": "static"}, "static contact solve"),
    ({"supports": ((0.0, 0.0, 0.0),)}, "support"),
    ({"geometry": "brb"}, "brb"),
])
def test_what_the_distributed_stage_does_not_take_is_refused_by_name(change, match):
    """Before any mesh is built: the static preload, gaps, supports and the BRB still need the
    replicated model, and the error says which key."""
    from dataclasses import replace

    from jointfem.fem.distributed import create_distributed

    with pytest.raises(ContinuumError, match=match) as exc:
        create_distributed(replace(lap_spec(0.03, 1.0), **change))
    assert "lap3d_distributed.toml" in str(exc.value)


@pytest.mark.slow
def test_cli_offline_distributed_on_two_ranks_equals_serial(tmp_path):
    """`mpirun -n 2 jointfem frf demos/lap3d.toml --method penalty --offline distributed`: the FRF of
    the serial replicated run (the same first point to 1e-8; every point on the serial curve to
    1e-6 of the peak, as tests/test_continuum.py compares MPI runs), pictures drawn, no deformed
    shape written (its basis is not gathered), the summary says which offline stage ran."""
    args = [sys.executable, "-m", "jointfem", "frf", str(ROOT / "demos" / "lap3d.toml"), "--method", "penalty",
            "--modes", "10", "--quiet", "--out"]
    subprocess.run(args + [str(tmp_path / "serial")], check=True, cwd=ROOT, timeout=600)
    subprocess.run(_mpirun() + args[:-1] + ["--offline", "distributed", "--plots", "--out", str(tmp_path / "mpi")],
                   check=True, cwd=ROOT, timeout=600, env=dict(os.environ))
    same_curve(tmp_path / "serial", tmp_path / "mpi")
    summary = json.loads((tmp_path / "mpi" / "summary.json").read_text())
    assert summary["mpi_ranks"] == 2 and summary["rom"]["offline"] == "distributed"
    assert summary["model"] == json.loads((tmp_path / "serial" / "summary.json").read_text())["model"]
    assert (tmp_path / "serial" / "shape.npz").exists() and not (tmp_path / "mpi" / "shape.npz").exists()
    assert len(list((tmp_path / "mpi").glob("interface_*.png"))) == 1


@pytest.mark.parametrize("method,scene,match", [("cb", "lap3d", "--method cb needs the replicated"),
                                                ("penalty", "beam2d", "for continuum scenes")])
def test_offline_distributed_is_refused_where_it_does_not_apply(method, scene, match):
    from jointfem.app import solve_scene
    from jointfem.scene import SceneError

    with pytest.raises(SceneError, match=match) as exc:
        solve_scene(load_scene(ROOT / "demos" / f"{scene}.toml"), method=method,
                    rom_options=RomOptions(offline="distributed"))
    assert f"{scene}.toml: --offline = 'distributed'" in str(exc.value)
