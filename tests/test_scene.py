"""Scene files: every class of bad input gives one clear line naming file, key and value,
before any computation, and the CLI writes nothing."""
import re
import subprocess
import sys

import pytest

from jointfem.scene import SceneError, create_structure, load_scene
from conftest import ROOT

SDOF = (ROOT / "demos" / "sdof_jenkins.toml").read_text()
BEAM = (ROOT / "demos" / "beam2d.toml").read_text()


def _write(tmp_path, text, name="bad.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


# (scene text, key in the message, value in the message)
BAD = {
    "unknown key": (SDOF.replace("harmonics = 7", "harmonics = 7\nharmonix = 3"), "solver.harmonix", "3"),
    "missing key": (SDOF.replace("m = 1.0\n", ""), "mass[0].m", "required key is missing"),
    "mass <= 0": (SDOF.replace("m = 1.0", "m = 0.0"), "mass[0].m", "0.0"),
    "stiffness <= 0": (SDOF.replace("k = 1.0", "k = -2.0"), "spring[0].k", "-2.0"),
    "kt <= 0": (SDOF.replace("kt = 1.0", "kt = 0"), "jenkins[0].kt", "0"),
    "mu < 0": (SDOF.replace("mu = 1.0", "mu = -0.1"), "jenkins[0].mu", "-0.1"),
    "N0 < 0": (SDOF.replace("N0 = 1.0", "N0 = -1.0"), "jenkins[0].N0", "-1.0"),
    "empty range": (SDOF.replace("[0.5, 2.0]", "[1.0, 1.0]"), "solver.omega_range", "[1.0, 1.0]"),
    "reversed range": (SDOF.replace("[0.5, 2.0]", "[2.0, 0.5]"), "solver.omega_range", "[2.0, 0.5]"),
    "harmonics < 1": (SDOF.replace("harmonics = 7", "harmonics = 0"), "solver.harmonics", "0"),
    "samples < 2H+1": (SDOF.replace("samples = 256", "samples = 14"), "solver.samples", "14"),
    "output dof": (SDOF.replace('dofs = ["m.x"]', 'dofs = ["m.y"]'), "output.dofs", "m.y"),
    "force dof": (SDOF.replace('dof = "m.x"', 'dof = "q.x"'), "force[0].dof", "q.x"),
    "wrong type": (SDOF.replace("c = 0.02", 'c = "soft"'), "damper[0].c", "soft"),
    "beam mu < 0": (BEAM.replace("mu = 0.3", "mu = -0.3"), "joint.mu", "-0.3"),
    "beam N0 < 0": (BEAM.replace("N0 = 20.0", "N0 = -5.0"), "joint.N0", "-5.0"),
    "beam output": (BEAM.replace('"b2.mid.uy"]', '"b3.mid.uy"]'), "output.dofs", "b3.mid.uy"),
    "beam odd elements": (BEAM.replace("elements = 20", "elements = 21"), "beam.elements", "21"),
    "unknown kind": (SDOF.replace('kind = "lumped"', 'kind = "shell"'), "kind", "shell"),
    "jenkins dof": (SDOF.replace('between = ["m", "ground"]', 'between = ["m.y", "ground"]'), "jenkins[0].between", "m.y"),
    "omega_limits inside the range": (SDOF.replace("[0.5, 2.0]", "[0.5, 2.0]\nomega_limits = [0.6, 3.0]"),
                                      "solver.omega_limits", "[0.6, 3.0]"),
    "omega_limits not a pair": (SDOF.replace("[0.5, 2.0]", "[0.5, 2.0]\nomega_limits = 3.0"),
                                "solver.omega_limits", "3.0"),
    "jenkins dof axis": (SDOF.replace('between = ["m", "ground"]\ntangential = ["x"]',
                                      'between = ["m.x", "ground"]\ntangential = ["y"]'),
                         "jenkins[0].between", "['m.x', 'ground']"),
    "stability": (SDOF.replace("harmonics = 7", 'harmonics = 7\nstability = "yes"'), "solver.stability", "yes"),
    "stability_memory": (SDOF.replace("harmonics = 7", 'harmonics = 7\nstability_memory = "yes"'),
                         "solver.stability_memory", "yes"),
    "peak_share": (SDOF.replace("harmonics = 7", 'harmonics = 7\npeak_share = 2'), "solver.peak_share", "2"),
    "peak_share < 0": (SDOF.replace("harmonics = 7", 'harmonics = 7\npeak_share = -0.1'), "solver.peak_share", "-0.1"),
    "reduction method": (SDOF + '\n[reduction]\nmethod = "guyan"\n', "reduction.method", "guyan"),
    "reduction modes < 0": (SDOF + '\n[reduction]\nmodes = -1\n', "reduction.modes", "-1"),
    "reduction tvd_kind": (SDOF + '\n[reduction]\ntvd_kind = "exact"\n', "reduction.tvd_kind", "exact"),
    "reduction unknown key": (SDOF + '\n[reduction]\nmode = 3\n', "reduction.mode", "3"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scene_is_one_clear_line(tmp_path, case):
    text, key, value = BAD[case]
    path = _write(tmp_path, text)
    with pytest.raises(SceneError) as err:
        load_scene(path)
    msg = str(err.value)
    assert "\n" not in msg
    assert str(path) in msg and key in msg and value in msg, msg


def test_toml_syntax_and_missing_file(tmp_path):
    with pytest.raises(SceneError, match="not valid TOML"):
        load_scene(_write(tmp_path, "kind = lumped ="))
    with pytest.raises(SceneError, match="cannot be read"):
        load_scene(tmp_path / "nope.toml")


def test_cli_bad_scene_exits_2_and_writes_nothing(tmp_path):
    path = _write(tmp_path, BAD["mu < 0"][0])
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "jointfem", "frf", str(path), "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "jointfem: error:" in lines[0] and "jenkins[0].mu" in lines[0]
    assert "Traceback" not in r.stderr
    assert not out.exists()
    r = subprocess.run([sys.executable, "-m", "jointfem", "frf", str(ROOT / "demos" / "sdof_jenkins.toml"),
                        "--samples", "10", "--out", str(out)], capture_output=True, text=True)
    assert r.returncode == 2 and "samples" in r.stderr and "Traceback" not in r.stderr
    assert not out.exists()


def test_lumped_scene_never_imports_dolfinx(tmp_path):
    code = (
        "import sys, jointfem\n"
        "from jointfem.scene import load_scene, create_structure\n"
        f"s = create_structure(load_scene({str(ROOT / 'demos' / 'sdof_jenkins.toml')!r}))\n"
        "from jointfem.analysis.frf import compute_frf, SweepOptions\n"
        "from jointfem.harmonics import Harmonics\n"
        "compute_frf(s, SweepOptions(1.2, 1.3, Harmonics(2, 32)))\n"
        "bad = [m for m in ('dolfinx', 'petsc4py', 'slepc4py', 'gmsh', 'mpi4py') if m in sys.modules]\n"
        "assert not bad, bad\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_beam_scene_defaults_and_build():
    scene = load_scene(ROOT / "demos" / "beam2d.toml")
    s = create_structure(scene)
    assert s.num_dofs == 2 * 21 * 3 - 6  # two beams of 20 elements, one clamped node each
    assert s.num_pairs == 3
    assert set(s.outputs) == {"b1.mid.uy", "b2.mid.uy"}


def test_a_binary_file_as_scene_is_one_line(tmp_path):
    png = tmp_path / "frf.png"
    png.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)))
    r = subprocess.run([sys.executable, "-m", "jointfem", "frf", str(png), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "not a text file" in r.stderr, r.stderr


def test_harmonics_beyond_memory_refused_with_the_estimate(tmp_path):
    """--harmonics 100000 asked numpy for 298 GiB before it failed; now one line with the estimate,
    before any allocation (the AFT's transforms alone: 2 N (2H+1) 8 bytes = 1490 GiB)."""
    r = subprocess.run([sys.executable, "-m", "jointfem", "frf", str(ROOT / "demos" / "sdof_jenkins.toml"),
                        "--harmonics", "100000", "--out", str(tmp_path / "o")], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "solver.harmonics = 100000" in r.stderr and "1490.2 GiB" in r.stderr
    assert not (tmp_path / "o").exists()


def test_harmonics_beyond_the_time_limit_refused_with_the_estimate(tmp_path):
    """--harmonics 1000 on the beam ran with no word for minutes: an iteration takes about 2 h there
    (measured 84 s at H = 255, growing like (2H+1)^3.3).  Now one line with the estimate from probes
    at fewer harmonics (1.3e3 s measured at H = 31), before the sweep; nothing written."""
    r = subprocess.run([sys.executable, "-m", "jointfem", "frf", str(ROOT / "demos" / "beam2d.toml"),
                        "--harmonics", "1000", "--set", "solver.time_limit=60", "--out", str(tmp_path / "o")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "solver.harmonics = 1000" in r.stderr and "per Newton iteration" in r.stderr
    assert "solver.time_limit = 60 s" in r.stderr
    assert not (tmp_path / "o").exists()
    # the SDOF oscillator at H = 1000 is cheap (a 2001-unknown dense system: seconds): not refused
    from jointfem import app
    from jointfem.harmonics import Harmonics
    from jointfem.scene import create_structure
    scene = load_scene(ROOT / "demos" / "sdof_jenkins.toml")
    est = app.iteration_estimate(create_structure(scene), Harmonics(1000, 4004), scene.solver.omega_start)
    assert est["probe_H"] < 1000 and 0 < est["seconds"] < 1000
    app.check_time(scene, create_structure(scene), Harmonics(1000, 4004), scene.solver.omega_start)


def test_mesh_file_is_relative_to_the_scene_file(tmp_path):
    text = (ROOT / "demos" / "lap3d.toml").read_text()
    (tmp_path / "sub").mkdir()
    p = tmp_path / "sub" / "lap.toml"
    p.write_text(text)
    assert load_scene(p).model.mesh_file == str(tmp_path / "meshes" / "lap3d.msh")
    assert load_scene(ROOT / "demos" / "lap3d.toml").model.mesh_file == str(ROOT / "meshes" / "lap3d.msh")


def test_mesh_file_that_names_no_msh_file_is_refused_by_name(tmp_path):
    """An empty [mesh] file resolved to the scene's folder and failed later inside meshio."""
    text = (ROOT / "demos" / "lap3d.toml").read_text()
    p = tmp_path / "lap.toml"
    for bad in ("", "meshes/", "lap3d.vtu"):
        p.write_text(text.replace('file = "../meshes/lap3d.msh"', f'file = "{bad}"'))
        with pytest.raises(SceneError, match=rf"lap.toml.*mesh.file.*'{bad}'.*\.msh"):
            load_scene(p)


def test_small_ds_max_needs_no_ds0(tmp_path):
    """ds_max below the default first step (0.02) was refused on ds0, a key the user never set."""
    text = (ROOT / "demos" / "sdof_jenkins.toml").read_text().replace("samples = 256\n", "samples = 256\nds_max = 0.005\n")
    p = tmp_path / "s.toml"
    p.write_text(text)
    s = load_scene(p).solver
    assert s.ds0 == 0.005 and s.ds_max == 0.005
    p.write_text(text.replace("ds_max = 0.005\n", "ds_max = 0.005\nds0 = 0.01\n"))
    with pytest.raises(SceneError, match="ds0 = 0.01"):
        load_scene(p)


def test_set_overrides_any_key_and_validates_again():
    from jointfem.app import override

    base = load_scene(ROOT / "demos" / "sdof_jenkins.toml")
    s = override(base, ["force.amplitude=0.5", "solver.omega_range=[1.0, 1.6]", "jenkins[0].mu=0.8",
                        "solver.direction=down"])
    assert s.model.forces[0].amplitude == 0.5 and (s.solver.omega_min, s.solver.omega_max) == (1.0, 1.6)
    assert s.model.jenkins[0].mu == 0.8 and s.solver.direction == "down"
    assert base.model.forces[0].amplitude == 0.2  # the original scene is untouched
    for bad, words in (("force.amplitud=0.5", "force[0].amplitud = 0.5: unknown key"),
                       ("jenkins[3].mu=0.5", "jenkins.3 is not a table"),
                       ("jenkins[0].mu=-1", "jenkins[0].mu = -1: must be >= 0"),
                       ("force", "--set: force: must be key=value")):
        with pytest.raises(SceneError, match=re.escape(words)):
            override(base, [bad])


def test_a_missing_key_or_table_is_named_without_a_value(tmp_path):
    """A key the scene lacks has no value to show: the line names the key (it said "nma = None",
    as if the user had written None)."""
    from jointfem.app import nma_options

    with pytest.raises(SceneError) as e:
        nma_options(load_scene(ROOT / "demos" / "beam2d.toml"))
    assert str(e.value).startswith(f"{ROOT / 'demos' / 'beam2d.toml'}: [nma]: the scene has no [nma] table")
    assert "None" not in str(e.value)
    path = tmp_path / "s.toml"
    path.write_text((ROOT / "demos" / "sdof_jenkins.toml").read_text().replace("omega_range", "#omega_range"))
    with pytest.raises(SceneError, match=re.escape(f"{path}: solver.omega_range: required key is missing")):
        load_scene(path)


def test_undamped_forced_mode_that_friction_cannot_hold_is_refused(tmp_path):
    """docs/scenes.md's lumped example without its z damper: the forced z mode (sqrt(k_z + kn) = 2
    rad/s, inside [0.8, 2.4]) moves no friction component, so nothing bounds it (the sweep failed on
    a NaN in the slider's shakedown).  Refused before any solve, naming the mode and the DOF.  The
    SDOF oscillator at c = 0, whose mode friction holds, is not."""
    from jointfem.app import check_forced_resonances
    from jointfem.scene import create_structure

    text = (ROOT / "docs" / "scenes.md").read_text()
    block = re.findall(r"```toml\n(.*?)```", text, re.S)[2]
    undamped = re.sub(r"\[\[damper\]\][^\n]*\nbetween = \[\"m.z\", \"ground\"\][^\n]*\nc = 0.05\n", "", block)
    assert undamped != block
    p = tmp_path / "xz.toml"
    p.write_text(undamped)
    scene = load_scene(p)
    with pytest.raises(SceneError, match=r"undamped, forced stuck mode at 2 rad/s .* mostly m.z"):
        check_forced_resonances(scene, create_structure(scene))
    p.write_text(block)
    check_forced_resonances(load_scene(p), create_structure(load_scene(p)))
    sdof = (ROOT / "demos" / "sdof_jenkins.toml").read_text().replace("c = 0.02", "c = 0.0")
    p.write_text(sdof)
    check_forced_resonances(load_scene(p), create_structure(load_scene(p)))


@pytest.mark.parametrize("omega_range", [[2.0, 2.5], [0.8, 1.2]])
def test_undamped_mode_with_an_open_unilateral_spring_is_not_refused(tmp_path, omega_range):
    """m = k = 1 undamped and forced, with a unilateral spring k = 4 open at rest (gap 0.5).  Small
    vibrations about rest resonate at 1 rad/s, and that mode moves the spring's component, which
    engages once the gap closes and detunes it: bounded.  The engaged sqrt(5) = 2.236 rad/s is no
    mode at rest.  The check took the spring engaged (K_lin) and refused [2.0, 2.5] (issue 50, item 3);
    it takes the structure at rest (K_rest) and refuses neither range."""
    from jointfem.app import check_forced_resonances
    from jointfem.scene import create_structure

    p = tmp_path / "gap.toml"
    p.write_text(f"""kind = "lumped"
[solver]
omega_range = {omega_range}
harmonics = 3
samples = 64
[[mass]]
name = "m"
m = 1.0
dofs = ["x"]
[[spring]]
between = ["m.x", "ground"]
k = 1.0
[[unilateral_spring]]
between = ["m.x", "ground"]
k = 4.0
gap = 0.5
[[force]]
dof = "m.x"
amplitude = 0.05
[output]
dofs = ["m.x"]
""")
    scene = load_scene(p)
    check_forced_resonances(scene, create_structure(scene))


def test_jenkins_between_names_dofs_as_a_spring_does(tmp_path):
    """`between = ["m.x", "ground"]` (DOF names, as springs take them) is the same element as
    `between = ["m", "ground"]` with `tangential = ["x"]`: the same stuck stiffness and the same
    nonlinear force."""
    import numpy as np

    from jointfem.harmonics import Harmonics

    dof_style = SDOF.replace('between = ["m", "ground"]\ntangential = ["x"]', 'between = ["m.x", "ground"]')
    assert dof_style != SDOF
    a = create_structure(load_scene(_write(tmp_path, SDOF, "a.toml")))
    b = create_structure(load_scene(_write(tmp_path, dof_style, "b.toml")))
    assert np.array_equal(a.K_lin.toarray(), b.K_lin.toarray())
    h = Harmonics(3, 64)
    G = np.zeros((h.num_hc, 1, 1))
    G[1] = 3.0  # slipping: |kt g| = 3 > mu N0 = 1
    fa, fb = (s.contacts[0].pairs.aft(G, h, jacobian=False).F for s in (a, b))
    assert np.array_equal(fa, fb) and np.abs(fa).max() > 0


def test_omega_limits_reach_the_continuation(tmp_path):
    """[solver] omega_limits is the band a frequency sweep's branch may leave its window into
    (default None: an octave each side, analysis.frf.default_omega_limits); it reaches the sweep's options
    and no other analysis's continuation (a force or amplitude sweep has its own bounds)."""
    from jointfem.app import sweep_options

    assert load_scene(_write(tmp_path, SDOF)).solver.omega_limits is None
    scene = load_scene(_write(tmp_path, SDOF.replace("[0.5, 2.0]", "[0.5, 2.0]\nomega_limits = [0.1, 3.5]")))
    opts = sweep_options(scene)
    assert opts.omega_limits == (0.1, 3.5) and opts.continuation.lam_bounds is None

