"""MUMPS called directly (jointfem.mumps) for sparse right-hand sides: against scipy's sparse LU and
PETSc's MatMatSolve on the same matrix, and its errors.  Two ranks: tests/test_distributed.py (the
audit there sees the right-hand sides' nonzeros go to the host and the solution to the rows' owners)."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from jointfem import linalg, mumps


def _spd(n: int) -> sp.csr_matrix:
    """A 2D Laplacian (Dirichlet) plus a small diagonal shift: symmetric positive definite."""
    k = int(np.sqrt(n))
    one = sp.diags([-np.ones(k - 1), 2 * np.ones(k), -np.ones(k - 1)], [-1, 0, 1])
    return sp.csr_matrix(sp.kronsum(one, one) + 1e-3 * sp.eye(k * k))


def _rhs(n: int, m: int, seed: int = 0) -> sp.csr_matrix:
    """m columns of two nonzeros each, like a gap operator's G^T Kc."""
    rng = np.random.default_rng(seed)
    rows = np.concatenate([rng.choice(n, m), rng.choice(n, m)])
    cols = np.concatenate([np.arange(m), np.arange(m)])
    vals = np.concatenate([rng.uniform(1, 2, m), -rng.uniform(1, 2, m)])
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, m))


def test_the_installed_mumps_can_be_called_directly():
    """On this stack the direct path is the one taken (else every other test here would only check
    the fallback): the header parses and the library loads."""
    assert mumps.unavailable() is None


@pytest.mark.parametrize("chunk", [7, 256])
def test_direct_sparse_solve_equals_scipy_and_matmatsolve(chunk, monkeypatch):
    """A^-1 B by the direct path equals scipy's sparse LU and PETSc's MatMatSolve to 1e-12
    relative (the condition number of this A is about 4e3), in blocks that do and do not divide
    the column count."""
    monkeypatch.setattr(linalg, "DIRECT_CHUNK", chunk)
    A = _spd(900)
    B = _rhs(900, 40)
    ref = spla.spsolve(sp.csc_matrix(A), B.toarray())
    Ap = linalg._to_petsc(A)
    direct = linalg.solve_rows(Ap, B, what="test matrix", direct=True).local
    petsc = linalg.solve_rows(Ap, B, what="test matrix", direct=False).local
    scale = np.abs(ref).max()
    assert np.abs(direct - ref).max() <= 1e-12 * scale
    assert np.abs(petsc - ref).max() <= 1e-12 * scale
    assert direct.flags["F_CONTIGUOUS"]  # each block of columns written contiguously


def test_direct_solve_writes_into_the_given_columns():
    """``out`` may be a column block of a wider Fortran-order array (the penalty ROM's basis):
    only those columns are written."""
    A = _spd(400)
    B = _rhs(400, 12, seed=1)
    wide = np.full((400, 15), 7.0, order="F")
    linalg.solve_rows(linalg._to_petsc(A), B, what="test matrix", out=wide[:, 3:], direct=True)
    assert np.all(wide[:, :3] == 7.0)
    np.testing.assert_allclose(wide[:, 3:], spla.spsolve(sp.csc_matrix(A), B.toarray()), rtol=0, atol=1e-12 * 40)


def test_a_singular_matrix_is_refused_with_what_mumps_said():
    """A zero row and column (an unconstrained DOF): MUMPS's own error code in a LinAlgError that
    names the matrix, not a solution full of infinities."""
    A = _spd(400).tolil()
    A[5, :] = 0.0
    A[:, 5] = 0.0
    with pytest.raises(linalg.LinAlgError, match=r"stuck test structure.*INFOG\(1\) = -?\d+"):
        linalg.solve_rows(linalg._to_petsc(sp.csr_matrix(A)), _rhs(400, 4), what="stuck test structure", direct=True)


def test_dense_right_hand_sides_are_not_taken_by_the_direct_path():
    A = linalg._to_petsc(_spd(400))
    with pytest.raises(linalg.LinAlgError, match="sparse right-hand sides"):
        linalg.solve_rows(A, np.ones((400, 2)), what="test matrix", direct=True)
    # and by default they go to MatMatSolve
    X = linalg.solve_rows(A, np.ones((400, 2)), what="test matrix").local
    np.testing.assert_allclose(_spd(400) @ X, np.ones((400, 2)), atol=1e-9)


def test_a_structure_that_does_not_match_the_library_is_not_called(monkeypatch):
    """The version MUMPS writes into the structure read from the header must be the header's: if
    not, the layouts differ, and the direct path is refused (asked for) or left for PETSc's
    MatMatSolve (by default), with the same solution."""
    found = mumps._interface()
    monkeypatch.setattr(mumps, "_interface", lambda arith="d": found[:-1] + ("0.0.0",))
    A = linalg._to_petsc(_spd(400))
    B = _rhs(400, 6, seed=2)
    with pytest.raises(linalg.LinAlgError, match="layouts differ"):
        linalg.solve_rows(A, B, what="test matrix", direct=True)
    X = linalg.solve_rows(A, B, what="test matrix").local
    np.testing.assert_allclose(X, spla.spsolve(sp.csc_matrix(_spd(400)), B.toarray()), rtol=0, atol=1e-12 * 40)


def test_shift_invert_modes_by_the_direct_factor_equal_the_dense_eigensolution():
    """eigen_rows with SLEPc's shift-invert applied by the factorisation the static modes use
    (one factorisation of K_lin for both, as the distributed penalty ROM does) gives the lowest
    eigenpairs of the dense problem: eigenvalues to 1e-10, mass-normalised modes to 1e-8."""
    import scipy.linalg as sla

    K = _spd(400)
    M = sp.diags(np.linspace(1.0, 2.0, 400)).tocsr()
    factor = linalg.direct_factor(linalg._to_petsc(K), what="test matrix", required=True)
    try:
        w2, Phi = linalg.eigen_rows(linalg._to_petsc(K), linalg._to_petsc(M), 6, what="test pencil", factor=factor)
    finally:
        factor.destroy()
    ref_w2, ref = sla.eigh(K.toarray(), M.toarray(), subset_by_index=[0, 5])
    np.testing.assert_allclose(w2, ref_w2, rtol=1e-10)
    for k in range(6):  # each mode up to its sign
        v = Phi.local[:, k] * np.sign(Phi.local[:, k] @ (M @ ref[:, k]))
        assert np.abs(v - ref[:, k]).max() <= 1e-8 * np.abs(ref[:, k]).max()
    with pytest.raises(ValueError, match="shift 0 only"):
        f = linalg.direct_factor(linalg._to_petsc(K), what="test matrix", required=True)
        try:
            linalg.eigen_rows(linalg._to_petsc(K), linalg._to_petsc(M), 2, what="test pencil", sigma=1.0, factor=f)
        finally:
            f.destroy()
