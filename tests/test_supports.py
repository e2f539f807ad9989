"""Soft supports ([[support]]): a free-free test article hangs on springs to ground (issue 16).

* the Brake-Reuss beam on two symmetric supports bounces as a rigid body on its springs: its
  bounce frequency is sqrt(sum k_y / m) (closed form), and its mass is rho V;
* a model whose every substructure is clamped or supported may be swept; one that is not is
  refused, naming the substructure;
* one-line scene errors for a support off the surface, a bad stiffness, a patch with no node.
"""
from __future__ import annotations

import numpy as np
import pytest

from jointfem.fem.continuum import ContinuumError
from jointfem.linalg import eigen
from jointfem.scene import SceneError, check_solvable, create_structure, load_scene

SCENE = """
kind = "continuum3d"
[solver]
omega_range = [900.0, 1200.0]
harmonics = 1
[geometry]
shape = "brb"
[mesh]
size = 0.0254
size_normal = 0.0127
[contact]
kt = 1e13
kn = 1e13
mu = 0.2
pressure = 1e6
[[support]]
at = [0.1, 0.0254, 0.0127]
stiffness = [300.0, 1000.0, 300.0]
radius = 0.013
[[support]]
at = [0.62, 0.0254, 0.0127]
stiffness = [300.0, 1000.0, 300.0]
radius = 0.013
"""


def write(tmp_path, text=SCENE):
    p = tmp_path / "brb_supports.toml"
    p.write_text(text)
    return p


def test_rigid_bounce_on_the_supports_is_the_closed_form(tmp_path):
    """The two supports sit symmetrically about the centre of mass (x = 0.36 m), so a vertical
    translation loads no moment and is a mode of the rigid bar on its springs: omega^2 = 2 k_y / m.
    The beam's elastic flexibility lowers it by about (f_bounce / f_1)^2 = (3.7 / 200)^2 = 3e-4
    at most (measured 1e-4); the tolerance is 5e-4.  The six lowest modes are the rigid ones, all
    below 10 Hz; the seventh, the first bending, above 150 Hz."""
    scene = load_scene(write(tmp_path))
    check_solvable(scene)  # free-free, held by the supports
    st = create_structure(scene)
    m = 7857.8 * 0.72 * 0.0254 ** 2
    assert st.M.sum() / 3 == pytest.approx(m, rel=1e-12)  # the consistent mass of a uniform bar
    w2, Phi = eigen(st.K_lin, st.M, 7)
    f = np.sqrt(w2) / (2 * np.pi)
    assert f[5] < 10.0 and f[6] > 150.0
    bounce = np.sqrt(2 * 1000.0 / m) / (2 * np.pi)
    # the bounce mode: the one whose uy is most uniform
    uy = Phi[np.array([n.endswith(".uy") for n in st.dof_names])][:, :6]
    k = int(np.argmax(np.abs(uy.mean(axis=0)) / np.abs(uy).max(axis=0)))
    assert f[k] == pytest.approx(bounce, rel=5e-4)
    assert f[k] < bounce  # flexibility only lowers it


def test_a_substructure_without_support_or_clamp_is_refused(tmp_path):
    text = SCENE.split("[[support]]")[0] + "[[support]]" + SCENE.split("[[support]]")[1]  # the support on A only
    with pytest.raises(SceneError, match=r"substructure B has no supports.*\[\[support\]\]"):
        check_solvable(load_scene(write(tmp_path, text)))


@pytest.mark.parametrize("old, new, key, why", [
    ("at = [0.1, 0.0254, 0.0127]", "at = [0.1, 0.01, 0.0127]", r"support\[0\]\.at", "must lie on an outer face"),
    ("at = [0.1, 0.0254, 0.0127]", "at = [0.1, 0.0254]", r"support\[0\]\.at", "must be a point of 3 coordinates"),
    ("stiffness = [300.0, 1000.0, 300.0]\nradius = 0.013\n[[support]]\nat = [0.62",
     "stiffness = [300.0, -1.0, 300.0]\nradius = 0.013\n[[support]]\nat = [0.62", r"support\[0\]\.stiffness",
     "must be a number or 3 numbers >= 0"),
    ("stiffness = [300.0, 1000.0, 300.0]\nradius = 0.013\n[[support]]\nat = [0.62",
     "stiffness = 0.0\nradius = 0.013\n[[support]]\nat = [0.62", r"support\[0\]\.stiffness", "not all zero"),
    ("radius = 0.013\n[[support]]\nat = [0.62", "radius = -1.0\n[[support]]\nat = [0.62", r"support\[0\]\.radius",
     "must be >= 0"),
    ("radius = 0.013\n[[support]]\nat = [0.62", "radius = 0.013\nspring = 1\n[[support]]\nat = [0.62",
     r"support\[0\]\.spring", "unknown key"),
])
def test_support_scene_errors(tmp_path, old, new, key, why):
    assert old in SCENE
    with pytest.raises(SceneError, match=rf"brb_supports\.toml: {key} = .*{why}"):
        load_scene(write(tmp_path, SCENE.replace(old, new, 1)))


def test_a_patch_that_covers_no_node_is_one_error(tmp_path):
    """A support patch of radius 0.1 mm between the nodes (every 12.7 mm) names the support."""
    text = SCENE.replace("at = [0.1, 0.0254, 0.0127]\nstiffness = [300.0, 1000.0, 300.0]\nradius = 0.013",
                         "at = [0.1, 0.0254, 0.006]\nstiffness = [300.0, 1000.0, 300.0]\nradius = 0.0001")
    with pytest.raises(ContinuumError, match=r"support 0 at \[0\.1, 0\.0254, 0\.006\] m with radius 0\.0001 m "
                                             r"covers no node of its face"):
        create_structure(load_scene(write(tmp_path, text)))
