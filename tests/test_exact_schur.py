"""The exact condensation's Schur path (CondensedProblem(sparse="schur")): complex MUMPS forms the
receptance on the gaps R_k = C Z_k^-1 C^T as the Schur complement of [[Z_k, C^T], [C, 0]], one
symbolic analysis per harmonic for the whole branch, and every product with Z_k^-1 C^T (dS/domega,
dS/dxi, the recovery of the full field) as two solves with the kept factors.

References: dense linear algebra (jointfem.mumps.BorderedSchur), the sparse-LU path (SuperLU and r
solves per harmonic: an independent factorisation and formula), full order (the condensation is
exact), and one rank against two; its Jacobian against central differences is
tests/test_continuum.py's test_exact_condensation_jacobian_fd.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

pytest.importorskip("dolfinx")

from jointfem import linalg, mumps  # noqa: E402
from jointfem.analysis.frf import create_problem  # noqa: E402
from jointfem.continuation.arclength import NewtonOptions, solve_newton  # noqa: E402
from jointfem.harmonics import Harmonics  # noqa: E402
from jointfem.hbm.condensed import CondensedProblem  # noqa: E402
from jointfem.rom import ExactModel  # noqa: E402
from jointfem.scene import create_structure, load_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
W = 1700.0  # rad/s: the 2D lap joint sticks and separates here at 3 N (test_continuum)

pytestmark = pytest.mark.skipif(mumps.unavailable("z") is not None, reason="complex MUMPS not callable directly")


def _lap2d():
    return create_structure(load_scene(ROOT / "demos" / "lap2d.toml"))


def _matrices(n: int = 300, r: int = 7):
    """A sparse symmetric K, a diagonal M, a Rayleigh-plus D and a border C of r rows."""
    rng = np.random.default_rng(1)
    A = sp.random(n, n, density=0.02, random_state=2)
    K = sp.csr_matrix(A + A.T + 10 * sp.eye(n))
    M = sp.diags(rng.random(n) + 1).tocsr()
    D = sp.csr_matrix(0.01 * K + 0.1 * M)
    C = sp.random(r, n, density=0.05, random_state=3).tocsr()
    return K, M, D, C


def test_bordered_schur_equals_dense_algebra_for_every_coefficient_set():
    """One analysis, three factorisations: R = C Z^-1 C^T from the Schur complement and Z^-1 b from
    the internal solve equal dense linear algebra to 1e-12 relative (Z's condition number is about
    1e2 here), for one and for two right-hand sides."""
    K, M, D, C = _matrices()
    f = mumps.BorderedSchur([K, M, D], C, comm(), what="test")
    rng = np.random.default_rng(5)
    try:
        for w in (0.3, 1.0, 2.5):
            c = (1.0, -w * w, 1j * w)
            Z = (K - w * w * M + 1j * w * D).toarray()
            R = f.factor(c)
            ref = C @ np.linalg.solve(Z, C.T.toarray())
            assert f.coefficients == tuple(np.asarray(c, dtype=complex))
            assert np.abs(R - ref).max() <= 1e-12 * np.abs(ref).max(), w
            assert np.array_equal(R, R.T)  # the triangle MUMPS returns, mirrored
            b = rng.standard_normal((K.shape[0], 2)) + 1j * rng.standard_normal((K.shape[0], 2))
            x = f.solve(b)
            assert np.abs(x - np.linalg.solve(Z, b)).max() <= 1e-12 * np.abs(x).max()
            x1 = f.solve(b[:, 0])
            assert x1.shape == (K.shape[0],) and np.abs(x1 - x[:, 0]).max() <= 1e-14 * np.abs(x).max()
    finally:
        f.destroy()


def test_a_large_complement_is_read_from_its_lower_triangle_only():
    """r = 650 gaps of a 3D grid Laplacian: MUMPS leaves work data above the diagonal of the
    complement it returns (measured: 77138 nonzeros there), so only the lower triangle may be read;
    R then equals SuperLU's C Z^-1 C^T to 1e-12 of its largest entry.  (Read whole, the BRB's gap
    receptance was off by 1e9 of it.)"""
    import scipy.sparse.linalg as spla

    k = 18
    one = sp.diags([-np.ones(k - 1), 2 * np.ones(k), -np.ones(k - 1)], [-1, 0, 1])
    K = sp.csr_matrix(sp.kronsum(sp.kronsum(one, one), one) + 1e-2 * sp.eye(k**3))
    n, r = k**3, 650
    rng = np.random.default_rng(0)
    a, b = rng.choice(n, r), rng.choice(n, r)
    C = sp.csr_matrix((np.r_[np.ones(r), -np.ones(r)], (np.r_[np.arange(r), np.arange(r)], np.r_[a, b])),
                      shape=(r, n))
    M = sp.eye(n).tocsr()
    f = mumps.BorderedSchur([K, M], C, comm(), what="test")
    try:
        R = f.factor((1.0, -0.1 + 0.01j))
        raw = f._schur.reshape(r, r)
        assert np.count_nonzero(np.triu(raw, 1)) > 0  # the case this test is for: not a clean upper part
        Z = sp.csc_matrix(K - (0.1 - 0.01j) * M)
        ref = C @ spla.splu(Z).solve(C.T.toarray().astype(complex))
        assert np.abs(R - ref).max() <= 1e-12 * np.abs(ref).max()
    finally:
        f.destroy()


def comm():
    from mpi4py import MPI

    return MPI.COMM_WORLD


def test_a_rigid_body_mode_the_gaps_do_not_see():
    """A free-free chain of unit springs at the static harmonic has a rigid-body mode; a gap between
    nodes 3 and 7 does not move with it, and its receptance is the four springs in series: 4 m/N to
    1e-12 (the factorisation is not refused for a null pivot, as a body held by its contacts alone
    needs, tests/test_preload.py), and the same at a dynamic coefficient set against dense algebra."""
    n = 50
    K = sp.diags([-np.ones(n - 1), np.r_[1, 2 * np.ones(n - 2), 1], -np.ones(n - 1)], [-1, 0, 1]).tocsr()
    M = sp.eye(n).tocsr()
    C = sp.csr_matrix(([1.0, -1.0], ([0, 0], [3, 7])), shape=(1, n))
    f = linalg.BorderedFactor([K, M, M], C, what="free chain")
    assert abs(f.factor((1.0, 0.0, 0.0))[0, 0] - 4.0) <= 1e-12 * 4.0
    c = (1.0, -0.5, 0.01j)
    ref = C @ np.linalg.solve((K - 0.5 * M + 0.01j * M).toarray(), C.T.toarray())
    assert abs(f.factor(c)[0, 0] - ref[0, 0]) <= 1e-12 * abs(ref[0, 0])


def _operators_as_arrays(op):
    out = {}
    for name in ("S", "dS", "dSxi", "ylin", "dylin", "T"):
        x = getattr(op, name)
        out[name] = x if x is None or isinstance(x, np.ndarray) else x.matmat(np.eye(x.shape[1]))
    return out


def test_schur_path_operators_equal_the_lu_path():
    """On the 2D lap joint, the Schur path's operators equal the sparse-LU path's at three points,
    with the EPMC's xi at one: S to 1e-8, its derivatives, the linear response and the recovery to
    1e-7 (the tolerances of the modal path's test: both paths carry the round-off of S = R^-1 of a
    receptance whose condition number reaches 1e8; measured S 1e-10, the rest up to 7e-9)."""
    s = _lap2d()
    h = Harmonics(2, 128)
    sc, lu = CondensedProblem(s, h, modal=False), CondensedProblem(s, h, modal=False, sparse="lu")
    assert sc.branch_info() == {"condensation": "schur"} and lu.branch_info() == {"condensation": "lu"}
    for w, xi, orders in ((1650.0, 0.0, ()), (1711.3, 0.4, (1,)), (3000.0, 0.0, ())):
        for k, (a, b) in enumerate(zip(sc._operators(w, xi, orders), lu._operators(w, xi, orders))):
            a, b = _operators_as_arrays(a), _operators_as_arrays(b)
            for name, tol in (("S", 1e-8), ("dS", 1e-7), ("dSxi", 1e-7), ("ylin", 1e-7), ("dylin", 1e-7), ("T", 1e-7)):
                x, y = a[name], b[name]
                if y is None:
                    assert x is None
                    continue
                assert np.abs(x - y).max() <= tol * max(np.abs(y).max(), 1e-300), (w, k, name)


def _newton(pb, w=W):
    def fun(U, lam):
        ev = pb.evaluate(U, lam)
        return ev.R, ev.J, ev.dR_dlam
    return solve_newton(fun, pb.initial_guess(w), w, x_scale=pb.scales(1550.0, 1800.0).x, r_scale=3.0,
                        options=NewtonOptions(tol=1e-12, max_iter=60))[0]


def test_schur_path_solution_and_full_field_equal_full_order():
    """Newton at fixed omega on the full 2D lap joint and on its Schur-path condensation: the same
    gaps and outputs to 1e-8 (as the LU and modal paths, test_continuum), and the full field the
    condensation recovers from its factors equals full order's to 1e-8."""
    s = _lap2d()
    h = Harmonics(3, 512)
    full, ex = create_problem(s, h), create_problem(ExactModel(s, modal=False), h)
    assert ex.branch_info() == {"condensation": "schur"}
    U, Y = _newton(full), _newton(ex)
    states = full.record(U, W, full.evaluate(U, W, jacobian=False)).states
    assert (states == 2).any() and (states == 0).any()  # separates and sticks
    Yf = (U.reshape(h.num_hc, -1) @ ex.C.T).ravel()
    assert np.abs(Y - Yf).max() <= 1e-8 * np.abs(Yf).max()
    Ue = ex.full_coefficients(Y, W)
    assert np.abs(Ue - U).max() <= 1e-8 * np.abs(U).max()


def test_an_operator_outlives_its_factorisation(monkeypatch):
    """The operators cached for one omega stay right after the same harmonic was factorised at
    another omega (the stuck response of initial_guess does that) and after their MUMPS instances
    were evicted by another problem's (LIVE_MAX = 2, three harmonics each): they factorise (and
    analyse) again, and give the same products to round-off."""
    s = _lap2d()
    h = Harmonics(2, 128)
    ex = CondensedProblem(s, h, modal=False)
    v = np.random.default_rng(0).standard_normal(ex.r)
    ops = ex._operators(1650.0)
    first = [op.dS @ v for op in ops[1:]]
    ex.initial_guess(1800.0)  # harmonic 1 factorised at 1800 rad/s
    assert ex._factor(1).coefficients != ex._coefficients(1, 1650.0, None)
    again = [op.dS @ v for op in ops[1:]]
    monkeypatch.setattr(linalg, "LIVE_MAX", 2)
    other = CondensedProblem(s, h, modal=False)
    other._operators(1800.0)  # another problem's three instances, two alive at a time: ex's are evicted
    assert all(f._f is None for f in ex._schur.values())
    assert sum(f._f is not None for f in other._schur.values()) == 2
    evicted = [op.dS @ v for op in ops[1:]]
    for a, b, c in zip(first, again, evicted):
        assert np.abs(b - a).max() <= 1e-12 * np.abs(a).max()
        assert np.abs(c - a).max() <= 1e-12 * np.abs(a).max()


def test_schur_path_backbone_equals_full_order():
    """The EPMC on the Schur path (xi in the dynamic stiffness, dS/dxi as an operator, the full field
    recovered through the factors for the energy and modal mass) gives full order's backbone of
    test_nma's chain: omega and zeta to 1e-8 and 1e-7 (as the modal path there)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from test_nma import exact_chain

    from jointfem.analysis.nma import NmaOptions, compute_backbone

    s = exact_chain()
    at = (0.05, 0.5, 2.0)
    opts = NmaOptions(amplitude_start=1e-2, amplitude_end=3.0, output="b.x", harmonics=Harmonics(3, 128), at=at)
    full = compute_backbone(s, opts)
    model = ExactModel(s, modal=False, sparse="schur")
    assert model.info["condensation"] == "schur"
    ex = compute_backbone(model, opts)
    assert ex.info["status"] == "complete"
    for a in at:
        f, e = full.info["at"][a], ex.info["at"][a]
        assert abs(e["omega_rad_s"] / f["omega_rad_s"] - 1) < 1e-8 and abs(e["zeta"] / f["zeta"] - 1) < 1e-7, a
        assert abs(e["energy_J"] / f["energy_J"] - 1) < 1e-7 and abs(e["modal_mass_kg"] / f["modal_mass_kg"] - 1) < 1e-8


def test_two_ranks_equal_one(tmp_path):
    """`mpirun -n 2`: the Schur path's factorisations distributed over both ranks (each hands MUMPS
    its block of rows) give the one-rank Newton solution and full field at 1700 rad/s to 1e-9
    relative (both converge to 1e-12; the factorisations differ in their pivot order only)."""
    from test_continuum import _mpirun

    out = tmp_path / "two.npz"
    subprocess.run(_mpirun() + [sys.executable, str(ROOT / "tests" / "exact_schur_run.py"), str(out)], check=True,
                   cwd=ROOT, timeout=600, env=dict(os.environ))
    two = np.load(out)
    assert int(two["ranks"]) == 2 and str(two["path"]) == "schur"
    s = _lap2d()
    h = Harmonics(3, 256)
    ex = create_problem(ExactModel(s, modal=False), h)
    Y = _newton(ex)
    U = ex.full_coefficients(Y, W)
    assert np.abs(two["Y"] - Y).max() <= 1e-9 * np.abs(Y).max()
    assert np.abs(two["U"] - U).max() <= 1e-9 * np.abs(U).max()


def test_an_unknown_sparse_path_is_refused_by_name():
    """CondensedProblem(sparse=...) takes "schur", "lu" or None; anything else is refused, naming it."""
    s = _lap2d()
    with pytest.raises(ValueError, match=r"sparse = 'qr', expected 'schur', 'lu' or None"):
        CondensedProblem(s, Harmonics(1, 8), modal=False, sparse="qr")
