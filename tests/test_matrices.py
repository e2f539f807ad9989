"""kind = "matrices": a model brought as K, M, D files with DOF-pair contacts (issue 18)."""
from __future__ import annotations

import re

import numpy as np
import pytest
import scipy.io as sio
import scipy.sparse as sp

from jointfem.analysis.frf import compute_frf
from jointfem.app import override_harmonics, sweep_options
from jointfem.scene import SceneError, create_structure, load_scene
from conftest import ROOT

MATRICES_SCENE = """
kind = "matrices"
[solver]
omega_range = [0.8, 2.4]
harmonics = 5
samples = 128

[matrices]
K = "{K}"
M = "{M}"
D = "{D}"
{variables}
dof_names = ["m.x", "m.z"]

[[jenkins]]
tangential = [["m.x", "ground"]]
normal = ["m.z", "ground"]
kt = 1.0
kn = 1.0
mu = 0.5
N0 = 1.0

[[force]]
dof = "m.x"
amplitude = 0.3
[[force]]
dof = "m.z"
amplitude = 0.8

[output]
dofs = ["m.x", "m.z"]
"""


def _lumped(tmp_path):
    block = re.findall(r"```toml\n(.*?)```", (ROOT / "docs" / "scenes.md").read_text(), re.S)[2]
    p = tmp_path / "xz.toml"
    p.write_text(block)
    return override_harmonics(load_scene(p), 5, 128)


@pytest.mark.parametrize("fmt", ["mtx", "npz", "mat"])
def test_matrices_kind_reproduces_a_lumped_scene_exactly(tmp_path, fmt):
    """docs/scenes.md's two-DOF scene (x with a Jenkins pair, z its normal), exported as K, M, D in
    each format and read back as kind = "matrices": the same branch to round-off."""
    lumped = _lumped(tmp_path)
    s = create_structure(lumped)
    names = {}
    for key, A in (("K", s.K), ("M", s.M), ("D", s.D)):
        f = tmp_path / f"{key.lower()}.{fmt}"
        if fmt == "mtx":
            sio.mmwrite(str(f), sp.csr_matrix(A))
        elif fmt == "npz":
            sp.save_npz(f, sp.csr_matrix(A))
        else:
            sio.savemat(str(f), {f"{key}r": sp.csr_matrix(A)})
        names[key] = f.name
    variables = 'variables = { K = "Kr", M = "Mr", D = "Dr" }' if fmt == "mat" else ""
    p = tmp_path / "ext.toml"
    p.write_text(MATRICES_SCENE.format(variables=variables, **names))
    ext = load_scene(p)
    a = compute_frf(s, sweep_options(lumped, stability="off"))
    b = compute_frf(create_structure(ext), sweep_options(ext, stability="off"))
    assert (a.states == 1).any() and (a.states == 2).any()  # slip and separation: the pairs are exercised
    assert a.omega.size == b.omega.size
    np.testing.assert_allclose(b.omega, a.omega, rtol=1e-12)
    np.testing.assert_allclose(b.U, a.U, rtol=0, atol=1e-12 * np.abs(a.U).max())


def test_bad_matrix_files_are_one_line(tmp_path):
    sio.mmwrite(str(tmp_path / "k.mtx"), sp.csr_matrix(np.array([[2.0, -1.0], [-1.0, 2.0]])))
    sio.mmwrite(str(tmp_path / "rect.mtx"), sp.csr_matrix(np.ones((2, 3))))
    sio.mmwrite(str(tmp_path / "asym.mtx"), sp.csr_matrix(np.array([[1.0, 0.5], [0.0, 1.0]])))
    # issue 50, item 5: a negative-definite K, and an indefinite one with a positive diagonal
    sio.mmwrite(str(tmp_path / "negk.mtx"), sp.csr_matrix(np.array([[-2.0, 1.0], [1.0, -2.0]])))
    sio.mmwrite(str(tmp_path / "indef.mtx"), sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 1.0]])))
    base = MATRICES_SCENE.format(K="k.mtx", M="k.mtx", D="k.mtx", variables="")
    for old, new, words in (('K = "k.mtx"', 'K = "nope.mtx"', r"matrices.K = 'nope.mtx'.*cannot be read"),
                            ('M = "k.mtx"', 'M = "rect.mtx"', r"matrices.M = 'rect.mtx'.*not square"),
                            ('K = "k.mtx"', 'K = "asym.mtx"', r"matrices.K = 'asym.mtx'.*not symmetric"),
                            ('K = "k.mtx"', 'K = "negk.mtx"', r"matrices.K = 'negk.mtx'.*negative diagonal entry"),
                            ('K = "k.mtx"', 'K = "indef.mtx"', r"matrices.K = 'indef.mtx'.*smallest eigenvalue is -1"),
                            ('normal = ["m.z", "ground"]', 'normal = ["m.y", "ground"]', r"jenkins\[0\].normal")):
        p = tmp_path / "bad.toml"
        p.write_text(base.replace(old, new))
        with pytest.raises(SceneError, match=words):
            load_scene(p)


def test_stiffness_and_mass_not_semidefinite_are_refused_at_any_size(tmp_path):
    """Issue 50, item 5: a K with a positive diagonal but a negative eigenvalue was accepted above
    3000 DOFs (only its diagonal was checked there), and an indefinite M with a positive diagonal
    at any size.  A free-free chain of 3200 DOFs (springs of 1 to 1e6 N/m: K singular, one zero
    eigenvalue, which round-off may leave slightly negative) is accepted.  The same chain with
    1e7 [[1, 2], [2, 1]] added on two distant DOFs a, b keeps a positive diagonal, but x = e_a - e_b
    gives x^T K x = K_aa + K_bb - 2e7 <= 4e6 - 2e7 < 0: an eigenvalue below -8e6, against a largest
    of about 3e7, far beyond the 1e-6 of round-off; it is refused with the count of such
    eigenvalues, as is a mass matrix [[1, 2], [2, 1]] (eigenvalue -1) of the two-DOF scene."""
    n = 3200
    k = 10 ** np.random.default_rng(0).uniform(0, 6, n - 1)
    K = sp.diags([np.r_[k, 0] + np.r_[0, k], -k, -k], [0, 1, -1]).tocsr()
    a, b = 1000, 2000
    block = sp.csr_matrix(([1e7, 2e7, 2e7, 1e7], ([a, a, b, b], [a, b, a, b])), shape=(n, n))
    sp.save_npz(tmp_path / "k.npz", K)
    sp.save_npz(tmp_path / "kneg.npz", (K + block).tocsr())
    sp.save_npz(tmp_path / "m.npz", sp.identity(n, format="csr"))
    chain = MATRICES_SCENE.format(K="k.npz", M="m.npz", D="m.npz", variables="").replace(
        'dof_names = ["m.x", "m.z"]', f"dof_names = {['m.x', 'm.z'] + [str(i) for i in range(2, n)]}")
    p = tmp_path / "chain.toml"
    p.write_text(chain)
    assert load_scene(p).model.K.shape == (n, n)
    p.write_text(chain.replace('K = "k.npz"', 'K = "kneg.npz"'))
    with pytest.raises(SceneError, match=r"chain.toml: matrices.K = 'kneg.npz': is not positive semi-definite: "
                                         r"1 eigenvalue below -1e-06 times the largest \(3.03\d*e\+07\)$") as exc:
        load_scene(p)
    assert "\n" not in str(exc.value)
    sio.mmwrite(str(tmp_path / "k2.mtx"), sp.csr_matrix(np.array([[2.0, -1.0], [-1.0, 2.0]])))
    sio.mmwrite(str(tmp_path / "m2.mtx"), sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 1.0]])))
    p.write_text(MATRICES_SCENE.format(K="k2.mtx", M="m2.mtx", D="k2.mtx", variables=""))
    with pytest.raises(SceneError, match=r"matrices.M = 'm2.mtx': is not positive semi-definite: its smallest "
                                         r"eigenvalue is -1"):
        load_scene(p)
