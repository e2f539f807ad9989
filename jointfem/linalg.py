"""Sparse/dense linear algebra for the offline stage: scipy, or PETSc/SLEPc with MUMPS.

Only this module (with jointfem.mumps, which it calls for MUMPS's own C interface), the mesh and
the fem modules may touch an eigen- or linear-solver package directly.  Matrices arrive as scipy
(replicated on every MPI rank); above ``SPARSE_PETSC`` DOFs, when petsc4py and slepc4py import,
the eigenvalue problems (SLEPc Krylov-Schur, shift-invert, MUMPS) and the factorisations (PETSc
KSP + MUMPS LU) run distributed over ``MPI.COMM_WORLD``: each rank hands PETSc its block of rows
and gets the full result back, so the caller never knows.  ``JOINTFEM_LINALG=scipy`` forces
the scipy backend (ARPACK shift-invert and SuperLU), for comparisons.

The distributed offline stage (the end of this module: RowBlocks, gram, eigen_rows, direct_factor,
solve_rows) works on the PETSc matrices themselves (jointfem.fem.distributed) and keeps every
tall matrix in the rows each rank owns: only reduced data crosses the ranks (gather_audit records
what does).
"""
from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

DENSE_LIMIT = 2500  # dense eigh below this many DOFs: exact and fast enough
SPARSE_PETSC = 2500  # PETSc/SLEPc above this many DOFs (when available)


def backend(n: int) -> str:
    """'dense', 'scipy' or 'petsc' for a problem of n DOFs."""
    if n <= DENSE_LIMIT:
        return "dense"
    choice = os.environ.get("JOINTFEM_LINALG", "petsc")
    if choice == "petsc" and n > SPARSE_PETSC and _petsc() is not None:
        return "petsc"
    return "scipy"


def _petsc():
    try:
        from petsc4py import PETSc
        from slepc4py import SLEPc  # noqa: F401
    except ImportError:  # pragma: no cover - the Debian stack has both
        return None
    return PETSc


def _comm():
    from petsc4py import PETSc

    return PETSc.COMM_WORLD


def _rows(n: int):
    comm = _comm()
    size, rank = comm.getSize(), comm.getRank()
    bounds = np.linspace(0, n, size + 1).round().astype(int)
    return int(bounds[rank]), int(bounds[rank + 1])


def _to_petsc(A):
    """A replicated scipy matrix as a distributed PETSc AIJ (each rank inserts its rows)."""
    from petsc4py import PETSc

    A = sp.csr_matrix(A)
    n = A.shape[0]
    r0, r1 = _rows(n)
    blk = A[r0:r1]
    blk.sort_indices()
    M = PETSc.Mat().createAIJ(size=((r1 - r0, n), (r1 - r0, n)), csr=(blk.indptr.astype(PETSc.IntType),
                              blk.indices.astype(PETSc.IntType), blk.data), comm=_comm())
    M.assemble()
    return M


def allgather_rows(comm, a: np.ndarray) -> np.ndarray:
    """The concatenation over the ranks of ``comm`` (mpi4py) of each rank's array along axis 0, on
    every rank, by buffer (Allgatherv), not by pickle."""
    a = np.ascontiguousarray(a)
    if comm.size == 1:
        return a.copy()
    rows = np.array(comm.allgather(a.shape[0]))
    _audit("allgather", (int(rows.sum()),) + a.shape[1:])
    per_row = int(np.prod(a.shape[1:], dtype=np.int64))
    out = np.empty((rows.sum(),) + a.shape[1:], dtype=a.dtype)
    from mpi4py import MPI

    comm.Allgatherv(a, [out, rows * per_row, None, MPI._typedict[a.dtype.char]])
    return out


def _gather_vec(v) -> np.ndarray:
    """The whole of a distributed PETSc vector, on every rank."""
    from petsc4py import PETSc

    _audit("gather_vec", (v.getSize(),))
    scatter, full = PETSc.Scatter.toAll(v)
    scatter.scatter(v, full, addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
    out = full.getArray().copy()
    scatter.destroy()
    full.destroy()
    return out


def _use_mumps(ksp, *, symmetric: bool):
    """A direct solve by MUMPS (Cholesky or LU) for this KSP."""
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("cholesky" if symmetric else "lu")
    pc.setFactorSolverType("mumps")
    return ksp


def _mumps_ksp(A, *, symmetric: bool):
    from petsc4py import PETSc

    ksp = PETSc.KSP().create(_comm())
    ksp.setOperators(A)
    return _use_mumps(ksp, symmetric=symmetric)


class _FactorPC:
    """A PETSc preconditioner (type python) that applies A^-1 by a factorisation already made
    (jointfem.mumps.Cholesky): SLEPc's shift-invert at 0 then needs no factorisation of its own."""

    def __init__(self, factor):
        self.factor = factor

    def apply(self, pc, x, y):
        out = np.empty(x.getLocalSize())
        self.factor.solve_dense(x.getArray(readonly=True), out)
        y.setArray(out)


def _eps_solve(A, B, num: int, what: str, sigma: float, factor=None):
    """SLEPc's Krylov-Schur with shift-invert (MUMPS) on the distributed pencil (A, B): the solver and
    the indices of its ``num`` lowest converged eigenpairs, with their eigenvalues.  ``factor``: a
    factorisation of A (jointfem.mumps.Cholesky) that shift-invert at sigma = 0 uses instead of
    factorising A again."""
    from slepc4py import SLEPc

    eps = SLEPc.EPS().create(_comm())
    eps.setOperators(A, B)
    eps.setProblemType(SLEPc.EPS.ProblemType.GHEP)
    eps.setDimensions(num, max(2 * num + 10, num + 20))
    eps.setTolerances(1e-12, 500)
    eps.setWhichEigenpairs(SLEPc.EPS.Which.TARGET_MAGNITUDE)
    eps.setTarget(sigma)
    st = eps.getST()
    st.setType("sinvert")
    st.setShift(sigma)
    if factor is None:
        _use_mumps(st.getKSP(), symmetric=True)
    else:
        if sigma != 0.0:
            raise ValueError(f"{what}: a factorisation of A serves the shift 0 only, not {sigma}")
        ksp = st.getKSP()
        ksp.setType("preonly")
        ksp.getPC().setType("python")
        ksp.getPC().setPythonContext(_FactorPC(factor))
    eps.solve()
    nconv = eps.getConverged()
    if nconv < num:
        raise LinAlgError(f"{what}: SLEPc converged {nconv} of {num} eigenpairs")
    w2 = np.array([eps.getEigenvalue(i).real for i in range(nconv)])
    order = np.argsort(w2)[:num]
    return eps, order, w2[order]


def _eigen_petsc(K, M, num: int, what: str, sigma: float):
    A, B = _to_petsc(K), _to_petsc(M)
    eps, order, w2 = _eps_solve(A, B, num, what, sigma)
    # only the num lowest of the converged pairs are gathered to every rank
    vr = A.createVecRight()
    vecs = []
    for i in order:
        eps.getEigenvector(int(i), vr)
        vecs.append(_gather_vec(vr))
    for obj in (eps, A, B, vr):
        obj.destroy()
    return w2, np.column_stack(vecs)


class LinAlgError(RuntimeError):
    """An offline solve failed (singular matrix, unconverged eigenvalues)."""


# BLAS's threads while a branch is followed.  Measured (benchmarks/blas_threads.py, one process, 2
# cores, 2026-12-07): the lap2d penalty ROM's sweep (140-238 unknowns, dense) took 2.5 times as long
# with OpenBLAS at 2 threads as at 1 (78-84 s against 31-33 s), and the last bits its threads change
# sent it down another path (1014 points against 1064); the beam demo at full order (1320 unknowns)
# was 0.96 as long with 2 and the same to the bit.  A branch's points must not depend on the
# machine's core count (OpenBLAS starts one thread a core), so sweeps run BLAS on one thread unless
# JOINTFEM_BLAS_THREADS asks for more (then the points are the same only at that count).
BLAS_THREADS_ENV = "JOINTFEM_BLAS_THREADS"


def sweep_blas_threads() -> int:
    """The BLAS thread count of a sweep: JOINTFEM_BLAS_THREADS, 1 by default."""
    text = os.environ.get(BLAS_THREADS_ENV, "").strip()
    if not text:
        return 1
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise LinAlgError(f"environment variable {BLAS_THREADS_ENV}={text!r}: give a whole number of threads >= 1")
    return n


@contextlib.contextmanager
def sweep_blas():
    """BLAS (OpenBLAS, MKL, ... through threadpoolctl) at sweep_blas_threads() threads within."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=sweep_blas_threads(), user_api="blas"):
        yield


def with_sweep_blas(fn):
    """``fn`` run under sweep_blas (the analyses' entry points: a branch's points the same on any machine)."""
    import functools

    @functools.wraps(fn)
    def run(*args, **kwargs):
        with sweep_blas():
            return fn(*args, **kwargs)

    return run


def eigen(K, M, num: int, *, what: str = "model", sigma: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The ``num`` lowest eigenpairs of K phi = w^2 M phi, mass-normalised.

    Returns (w2 ascending, Phi of shape (n, num)).  Raises LinAlgError if fewer exist.
    sigma: the shift of the sparse shift-invert solvers, rad^2/s^2 (negative for a structure
    with rigid-body modes, whose K is singular).
    """
    n = K.shape[0]
    if num < 1:
        return np.zeros(0), np.zeros((n, 0))
    if num > n:
        raise LinAlgError(f"{what}: {num} modes asked, but it has only {n} DOFs")
    if n <= DENSE_LIMIT or num >= n - 1:
        Kd = K.toarray() if sp.issparse(K) else np.asarray(K)
        Md = M.toarray() if sp.issparse(M) else np.asarray(M)
        # The inverse problem M phi = (1/w2) K phi resolves the lowest modes to machine precision
        # relative to themselves (the direct one only relative to the stiffest mode: 1e-7 on the
        # beam) and admits a singular M (MacNeal's reduced mass).  Rigid-body modes make K singular:
        # then the direct problem.
        try:
            mu, V = sla.eigh(Md, Kd, subset_by_index=[n - num, n - 1])
            mu, V = mu[::-1], V[:, ::-1]
            if mu[-1] <= 0:
                raise LinAlgError(f"{what}: only {int(np.sum(mu > 0))} finite eigenvalues, {num} asked")
            w2, Phi = 1.0 / mu, V
        except np.linalg.LinAlgError:
            try:
                w2, Phi = sla.eigh(Kd, Md, subset_by_index=[0, num - 1])
            except np.linalg.LinAlgError as exc:
                raise LinAlgError(f"{what}: neither K nor M is positive definite") from exc
    elif backend(n) == "petsc":
        w2, Phi = _eigen_petsc(K, M, num, what, sigma)
    else:
        w2, Phi = spla.eigsh(sp.csc_matrix(K), k=num, M=sp.csc_matrix(M), sigma=sigma, which="LM")
        order = np.argsort(w2)
        w2, Phi = w2[order], Phi[:, order]
    # mass-normalise (eigh already does; eigsh nearly) and fix the sign for reproducibility
    Mphi = M @ Phi
    Phi = Phi / np.sqrt(np.einsum("ij,ij->j", Phi, Mphi))
    sign = np.sign(Phi[np.argmax(np.abs(Phi), axis=0), np.arange(Phi.shape[1])])
    return w2, Phi * sign


def all_modes_inverse(K, M, *, what: str = "model") -> tuple[np.ndarray, np.ndarray]:
    """Every eigenpair of the inverse problem M v = mu K v (dense LAPACK): (mu descending, V) with
    V^T K V = I and V^T M V = diag(mu), mu = 1/w^2.  K must be positive definite (no rigid-body
    modes).  The inverse form resolves the lowest modes (the largest mu) to machine precision
    relative to themselves, and the stiffest ones (mu near 0) only absolutely, which is what
    (K - sigma M)^-1 = V diag(1 / (1 - sigma mu)) V^T needs at any finite sigma.  O(n^3) time and
    3 n^2 doubles of memory: for the exact condensation up to some ten thousand DOFs."""
    Kd = K.toarray() if sp.issparse(K) else np.array(K, float)
    Md = M.toarray() if sp.issparse(M) else np.array(M, float)
    dm = np.diag(Md)
    scale = float(np.max(np.diag(Kd) / np.where(dm > 0, dm, np.inf)))  # before eigh overwrites them
    try:
        mu, V = sla.eigh(Md, Kd, overwrite_a=True, overwrite_b=True, check_finite=False)
    except np.linalg.LinAlgError as exc:
        raise LinAlgError(f"{what}: K is not positive definite (rigid-body modes?)") from exc
    # A K singular to round-off (a free substructure) may still pass the Cholesky factorisation:
    # its rigid-body modes then come out with w^2 of 8.5e-18 to 2.7e-17 of the elements' largest
    # K_ii / M_ii (measured: the 2D lap joint with B free), where the clamped one's lowest is 7.6e-9
    # and the quick BRB's, its halves on soft supports without the joint's springs (0.1 Hz), 8.9e-14
    if mu[-1] <= 0 or 1.0 / mu[-1] < 1e-15 * scale:
        raise LinAlgError(f"{what}: K is singular to round-off (rigid-body modes: the lowest w^2 is "
                          f"{1.0 / mu[-1] if mu[-1] > 0 else float('inf'):.3g}, against {scale:.3g} of the elements)")
    return mu[::-1].copy(), np.ascontiguousarray(V[:, ::-1])


def finite_frequencies(K, M, num: int, *, what: str = "model", at_most: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The ``num`` lowest natural frequencies (rad/s) of a small pencil that need not be definite:
    a saddle-point model with a singular M (the dual Craig-Bampton's multipliers and gaps).  The
    finite eigenvalues of K phi = w^2 M phi by the dense QZ algorithm; infinite ones (massless
    coordinates) are dropped, and real negative ones (w^2 < 0: the spurious modes of an indefinite
    reduction) are returned apart.  Returns (frequencies, the negative w^2 ascending).  Raises
    LinAlgError where fewer than ``num`` real positive ones exist (``at_most``: returns those), or
    where one of them is complex beyond round-off."""
    Kd = K.toarray() if sp.issparse(K) else np.asarray(K, float)
    Md = M.toarray() if sp.issparse(M) else np.asarray(M, float)
    ab = sla.eig(Kd, Md, right=False, homogeneous_eigvals=True)
    alpha, beta = ab[0], ab[1]
    finite = np.abs(beta) > 1e-12 * np.abs(alpha)
    w2 = alpha[finite] / beta[finite]
    real = np.abs(w2.imag) <= 1e-8 * np.abs(w2)
    negative = np.sort(w2.real[real & (w2.real < 0)])
    positive = np.sort(w2.real[real & (w2.real > 0)])
    complex_ = w2[~real]
    if positive.size < num and not at_most:
        raise LinAlgError(f"{what}: only {positive.size} real positive eigenvalues, {num} asked")
    num = min(num, positive.size)
    if num and complex_.size and np.abs(complex_).min() < positive[num - 1]:
        raise LinAlgError(f"{what}: a complex eigenvalue w^2 = {complex_[np.argmin(np.abs(complex_))]:.6g} lies "
                          f"among the lowest {num}: no natural frequency")
    return np.sqrt(positive[:num]), negative


def sparse_lu(A):
    """SuperLU's factors of a sparse A, ordered on the pattern of A + A^T (minimum degree): the
    matrices factorised here are structurally symmetric (stiffness and mass, a harmonic balance
    Jacobian with its harmonics' coupling, contact blocks and bordering row and column), and the
    column ordering SuperLU takes by default (COLAMD) filled the factors of the 2D lap joint's
    full-order Jacobian 4.4 to 29 times as much (5041 unknowns: 1.2e6 and 8.2e6 against 2.8e5
    nonzeros), and its factorisations took 10 times as long (docs/benchmarks_lu_ordering.md)."""
    return spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A")


def eigenvalues_below(A, bound: float) -> int | None:
    """How many eigenvalues of the sparse symmetric A are below ``bound``: the negative pivots of
    A - bound I = L D L^T (Sylvester's law of inertia).  SuperLU gives that factorisation when it
    orders rows and columns alike and pivots on the diagonal only (diag_pivot_thresh = 0); where it
    had to leave the diagonal (a zero pivot), the bound is moved by half its size and tried again;
    None if no try gave that factorisation."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as sla

    n = A.shape[0]
    for shift in (bound, 1.5 * bound, 2.0 * bound):
        lu = sla.splu(sp.csc_matrix(A - shift * sp.identity(n)), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                      options={"SymmetricMode": True})
        if np.array_equal(lu.perm_r, lu.perm_c):
            return int(np.count_nonzero(lu.U.diagonal() < 0))
    return None


class Factorized:
    """A sparse LU of a square matrix, with a clear error when it is singular.

    Above SPARSE_PETSC rows and for a real matrix: MUMPS through PETSc, distributed.
    """

    def __new__(cls, A, *, what: str = "matrix"):
        if cls is Factorized and sp.issparse(A) and backend(A.shape[0]) == "petsc":
            if not np.iscomplexobj(A.data):
                return super().__new__(_MumpsFactorized)
            # complex (the exact condensation's harmonics): Debian's PETSc is real, so MUMPS factorises
            # the real 2n block form.  On one rank SuperLU's complex LU is faster (7560 DOFs, 147
            # right-hand sides: 0.36 s against 0.92 s), so MUMPS is used when it can distribute.
            if _comm().getSize() > 1 or os.environ.get("JOINTFEM_MUMPS_COMPLEX") == "1":
                return super().__new__(_MumpsComplex)
        return super().__new__(cls)

    def __init__(self, A, *, what: str = "matrix"):
        self.what = what
        A = sp.csc_matrix(A)
        try:
            self._lu = sparse_lu(A)
        except RuntimeError as exc:
            raise LinAlgError(f"{what} is singular ({exc}): a substructure without supports "
                              f"(rigid-body modes) cannot be factorised") from exc
        d = np.abs(self._lu.U.diagonal())
        if d.size and d.min() <= 1e-13 * d.max():
            raise LinAlgError(f"{what} is numerically singular (pivot ratio {d.min() / d.max():.1e}): "
                              f"a substructure without supports (rigid-body modes)?")

    def solve(self, B: np.ndarray) -> np.ndarray:
        B = B.toarray() if sp.issparse(B) else np.asarray(B)
        return self._lu.solve(B if np.iscomplexobj(B) else B.astype(float))


class _MumpsFactorized(Factorized):
    """MUMPS LU of a replicated scipy matrix over COMM_WORLD (see Factorized)."""

    def __init__(self, A, *, what: str = "matrix"):
        from petsc4py import PETSc

        self.what = what
        self.n = A.shape[0]
        self._A = _to_petsc(A)
        self._ksp = _mumps_ksp(self._A, symmetric=False)
        try:
            self._ksp.setUp()
        except PETSc.Error as exc:
            raise LinAlgError(f"{what} could not be factorised by MUMPS (error {exc.ierr}): singular? "
                              f"a substructure without supports (rigid-body modes) cannot be factorised") from exc
        self._x, self._b = self._A.createVecs()

    def solve(self, B: np.ndarray) -> np.ndarray:
        B = B.toarray() if sp.issparse(B) else np.asarray(B, dtype=float)
        one = B.ndim == 1
        B = B.reshape(self.n, -1)
        r0, r1 = self._b.getOwnershipRange()
        if B.shape[1] > 1:
            X = self._mat_solve(B, r0, r1)
        else:
            self._b.setArray(B[r0:r1, 0])
            self._ksp.solve(self._b, self._x)
            if self._ksp.getConvergedReason() < 0:
                raise LinAlgError(f"{self.what}: MUMPS solve failed (reason {self._ksp.getConvergedReason()})")
            X = _gather_vec(self._x)[:, None]
        if not np.all(np.isfinite(X)):
            raise LinAlgError(f"{self.what} is singular: the MUMPS solution is not finite "
                              f"(a substructure without supports?)")
        return X[:, 0] if one else X

    def _mat_solve(self, B: np.ndarray, r0: int, r1: int) -> np.ndarray:
        """All columns at once (MatMatSolve with dense right-hand sides): one MUMPS call, not one per column."""
        from petsc4py import PETSc

        m = B.shape[1]
        comm = _comm()
        Bp = PETSc.Mat().createDense(size=((r1 - r0, self.n), (PETSc.DECIDE, m)), comm=comm)
        Bp.setUp()
        Bp.getDenseArray()[:] = B[r0:r1]
        Bp.assemble()
        Xp = Bp.duplicate()
        self._ksp.getPC().getFactorMatrix().matSolve(Bp, Xp)
        local = Xp.getDenseArray().copy()
        Bp.destroy()
        Xp.destroy()
        if comm.getSize() == 1:
            return local
        return allgather_rows(comm.tompi4py(), local)  # by buffer, not pickled


class _MumpsComplex(Factorized):
    """MUMPS LU of a complex matrix through PETSc's real build: the real block form
    [[Ar, -Ai], [Ai, Ar]] [xr; xi] = [br; bi] of (Ar + i Ai)(xr + i xi) = br + i bi."""

    def __init__(self, A, *, what: str = "matrix"):
        A = sp.csr_matrix(A)
        self.n = A.shape[0]
        Ar, Ai = sp.csr_matrix(A.real), sp.csr_matrix(A.imag)
        self._real = _MumpsFactorized(sp.bmat([[Ar, -Ai], [Ai, Ar]], format="csr"), what=what)
        self.what = what

    def solve(self, B: np.ndarray) -> np.ndarray:
        B = B.toarray() if sp.issparse(B) else np.asarray(B)
        one = B.ndim == 1
        B = B.reshape(self.n, -1).astype(complex)
        X = self._real.solve(np.vstack([B.real, B.imag]))
        X = X[:self.n] + 1j * X[self.n:]
        return X[:, 0] if one else X


def bordered_unavailable() -> str | None:
    """None if BorderedFactor can be used here, else the reason (JOINTFEM_MUMPS=petsc, or complex
    MUMPS not callable directly)."""
    if os.environ.get("JOINTFEM_MUMPS") == "petsc":
        return "JOINTFEM_MUMPS=petsc"
    from . import mumps

    return mumps.unavailable("z")


# BorderedFactors whose MUMPS instance is alive, oldest first: at most LIVE_MAX instances and about
# LIVE_BYTES of factors are kept (an evicted one analyses again at its next use).  Eviction happens
# inside collective calls, in the same order on every rank, so it is safe under MPI, which a
# finaliser run by the garbage collector would not be.
_LIVE: list = []
LIVE_MAX = 32
LIVE_BYTES = 8 * 2**30


class BorderedFactor:
    """Z(c) = sum_j c_j A_j, complex symmetric (the A_j real, symmetric, sparse and the same on
    every rank), factorised by complex MUMPS with its receptance on the rows of C (r x n) formed in
    the factorisation as a Schur complement (jointfem.mumps.BorderedSchur): R = C Z^-1 C^T without
    the n x r solutions.  One symbolic analysis for every factorisation: a branch's harmonics
    refactorise with new coefficients only.  Distributed over COMM_WORLD (each rank assembles its
    block of rows), collective; the results are on every rank."""

    def __init__(self, mats, C, *, what: str):
        self.mats, self.C, self.what = list(mats), sp.csr_matrix(C), what
        self._f = None
        self._bytes = 0

    def _instance(self):
        from . import mumps

        if self._f is None:
            while len(_LIVE) >= LIVE_MAX or (_LIVE and sum(x._bytes for x in _LIVE) > LIVE_BYTES):
                _LIVE[0]._release()
            try:
                self._f = mumps.BorderedSchur(self.mats, self.C, _comm().tompi4py(), what=self.what)
            except mumps.MumpsError as exc:
                raise LinAlgError(str(exc)) from exc
            _LIVE.append(self)
        return self._f

    def _release(self) -> None:
        if self._f is not None:
            self._f.destroy()
            self._f = None
            _LIVE.remove(self)

    @property
    def coefficients(self):
        return None if self._f is None else self._f.coefficients

    def factor(self, coefficients) -> np.ndarray:
        """Factorise Z(c); R = C Z^-1 C^T (r x r complex)."""
        from . import mumps

        f = self._instance()
        try:
            R = f.factor(coefficients)
        except mumps.MumpsError as exc:
            raise LinAlgError(f"{exc} (a singular dynamic stiffness? an undamped resonance hit exactly, or a body "
                              "held by nothing)") from exc
        self._bytes = f.factor_bytes
        return R

    def ensure(self, coefficients) -> None:
        """Factorise Z(c) unless the current factorisation is that one."""
        if self.coefficients != tuple(np.asarray(coefficients, dtype=complex)):
            self.factor(coefficients)

    def solve_chain(self, b, maps) -> np.ndarray:
        """x_1 = Z^-1 b, x_{i+1} = Z^-1 maps[i-1](x_i), ..., and maps[-1](x_last), on every rank:
        the maps run on the host only (what crosses the ranks is their last result)."""
        from . import mumps

        f = self._instance()
        host = f.comm.rank == 0
        x = None
        try:
            for i, m in enumerate(maps):
                x = f.solve(b if host else None)
                b = m(x) if host else None
        except mumps.MumpsError as exc:
            raise LinAlgError(str(exc)) from exc
        return f.comm.bcast(b, root=0) if f.comm.size > 1 else b


def pod(V: np.ndarray, M, num: int, against: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The ``num`` dominant POD vectors of the snapshots V in the M inner product, after removing
    their M-projection on ``against``.  Returns (vectors M-orthonormal, singular values, all)."""
    if against is not None and against.size:
        V = V - against @ (against.T @ (M @ V))
    C = V.T @ (M @ V)
    C = 0.5 * (C + C.T)
    s, W = np.linalg.eigh(C)
    order = np.argsort(s)[::-1]
    s, W = np.clip(s[order], 0.0, None), W[:, order]
    num = min(num, int(np.sum(s > 1e-12 * s[0])) if s.size and s[0] > 0 else 0)
    return (V @ W[:, :num]) / np.sqrt(s[:num]), np.sqrt(s)


# --- the distributed offline stage (issue 17): tall matrices as row blocks -----------------------
# K, M and K_lin stay the PETSc matrices dolfinx assembled; eigenvectors and static modes stay in the
# rows each rank owns (RowBlocks); only reduced data (q x q, J x q, single rows) crosses the ranks,
# through allreduce below.  gather_audit() records every array this module moves between ranks, so
# that a test can check the claim.

_AUDIT: list | None = None
CHUNK = 256  # columns per block of the projections (bounds the extra memory)
# columns per MUMPS solve of the static modes: 64 measured fastest of 16 to 1575 (100,548 DOFs, 1575
# right-hand sides, one rank: 10.6-14.8 s at 64, 15-17 s at 256, 25 s all at once; timing noise
# about +-30 %)
SOLVE_CHUNK = 64
# columns per direct MUMPS solve with sparse right-hand sides (jointfem.mumps): at most DIRECT_CHUNK,
# and fewer where one of its three buffers (solution, send, receive: n_local x columns) would pass
# DIRECT_BLOCK_BYTES (a 525k-DOF model on 2 ranks: 128 columns); MUMPS blocks them itself (ICNTL(27))
DIRECT_CHUNK = 256
DIRECT_BLOCK_BYTES = 2**28


def _audit(kind: str, shape: tuple) -> None:
    if _AUDIT is not None:
        _AUDIT.append((kind, tuple(int(s) for s in shape)))


@contextlib.contextmanager
def gather_audit():
    """Record (kind, shape) of every array gathered or reduced across the ranks by this module
    (allgather_rows, the PETSc gathers of whole vectors, allreduce) while the block runs."""
    global _AUDIT
    previous, _AUDIT = _AUDIT, []
    try:
        yield _AUDIT
    finally:
        _AUDIT = previous


def allreduce(comm, a: np.ndarray, *, op: str = "sum") -> np.ndarray:
    """The sum (or max) over the ranks of ``comm`` (mpi4py; None: serial) of a small array, by buffer."""
    a = np.ascontiguousarray(a, dtype=float)
    _audit("allreduce", a.shape)
    if comm is None or comm.size == 1:
        return a.copy()
    from mpi4py import MPI

    out = np.empty_like(a)
    comm.Allreduce(a, out, op=MPI.SUM if op == "sum" else MPI.MAX)
    return out


@dataclass
class RowBlocks:
    """A tall matrix (n, q): on each rank of ``comm`` its rows ``offset`` to ``offset`` + len(local)
    (comm None: the whole matrix here, offset 0).  Products that reduce the n rows go through
    allreduce; the rows themselves never leave their rank."""

    local: np.ndarray  # (n_local, q)
    n: int
    offset: int = 0
    comm: object = None  # mpi4py communicator

    @property
    def num_cols(self) -> int:
        return self.local.shape[1]

    def rows(self, index: np.ndarray) -> np.ndarray:
        """Rows ``index`` (global) of the matrix, (len(index), q), on every rank."""
        index = np.asarray(index, dtype=np.int64)
        out = np.zeros((index.size, self.num_cols))
        mine = (index >= self.offset) & (index < self.offset + self.local.shape[0])
        out[mine] = self.local[index[mine] - self.offset]
        return out if self.comm is None else allreduce(self.comm, out)

    def col_max(self, q: int) -> np.ndarray:
        """max_i |T_ij| over the rows, for the first q columns."""
        loc = np.abs(self.local[:, :q]).max(axis=0) if self.local.shape[0] else np.zeros(q)
        return loc if self.comm is None else allreduce(self.comm, loc, op="max")

    def max_abs_product(self, X: np.ndarray, q: int) -> float:
        """max |X T[:, :q]^T| over every entry, X (s, q); by blocks of rows."""
        top = 0.0
        for r in range(0, self.local.shape[0], 20000):
            top = max(top, float(np.abs(X @ self.local[r:r + 20000, :q].T).max()))
        return top if self.comm is None else float(allreduce(self.comm, np.array([top]), op="max")[0])


def _dense(local: np.ndarray, n: int):
    """A distributed PETSc dense matrix holding this rank's rows ``local`` of an (n, q) matrix."""
    from petsc4py import PETSc

    A = PETSc.Mat().createDense(size=((local.shape[0], n), (PETSc.DECIDE, local.shape[1])), comm=_comm())
    A.setUp()
    A.getDenseArray()[:] = local
    A.assemble()
    return A


def gram(A, T: RowBlocks, *, chunk: int = CHUNK, cols: int | None = None) -> np.ndarray:
    """T^T A T (q, q) of a symmetric distributed PETSc matrix A, by column blocks of A T (never the
    whole A T), each block against the columns before it only (the upper triangle: half the
    products), reduced over the ranks.  ``cols``: only the first ``cols`` columns of T."""
    q = T.num_cols if cols is None else cols
    out = np.zeros((q, q))
    for c in range(0, q, chunk):
        e = min(c + chunk, q)
        Tc = _dense(T.local[:, c:e], T.n)
        ATc = A.matMult(Tc)
        out[:e, c:e] = T.local[:, :e].T @ ATc.getDenseArray()
        Tc.destroy()
        ATc.destroy()
    out = allreduce(T.comm, out)
    return np.triu(out) + np.triu(out, 1).T


def eigen_rows(A, B, num: int, *, what: str, sigma: float = 0.0, comm=None,
               factor=None) -> tuple[np.ndarray, RowBlocks]:
    """eigen() of a distributed PETSc pencil, the modes left in row blocks: (w2 ascending, Phi)
    mass-normalised, each signed so that its entry of largest magnitude is positive (the first
    such row where several tie), as eigen() does.  ``factor``: A already factorised
    (direct_factor), for sigma = 0."""
    eps, order, w2 = _eps_solve(A, B, num, what, sigma, factor)
    vr, Bv = A.createVecs()
    r0, r1 = vr.getOwnershipRange()
    n = vr.getSize()
    Phi = np.zeros((r1 - r0, num))
    for k, i in enumerate(order):
        eps.getEigenvector(int(i), vr)
        B.mult(vr, Bv)
        Phi[:, k] = vr.getArray() / np.sqrt(vr.dot(Bv))
    for obj in (eps, vr, Bv):
        obj.destroy()
    # the sign: the largest |entry| of each mode, over the ranks (value, then the lowest row on a tie)
    big = np.abs(Phi).max(axis=0) if r1 > r0 else np.zeros(num)
    top = big if comm is None else allreduce(comm, big, op="max")
    first = np.full(num, float(n))
    for k in range(num):
        hit = np.flatnonzero(np.abs(Phi[:, k]) == top[k])
        if hit.size:
            first[k] = r0 + hit[0]
    first = first if comm is None else -allreduce(comm, -first, op="max")
    sign = np.zeros(num)
    for k in range(num):
        if r0 <= first[k] < r1:
            sign[k] = np.sign(Phi[int(first[k]) - r0, k])
    sign = sign if comm is None else allreduce(comm, sign)
    return w2, RowBlocks(Phi * sign, n, r0, comm)


def direct_factor(A, *, what: str, required: bool = False):
    """A symmetric positive definite distributed PETSc matrix factorised by MUMPS called directly
    (jointfem.mumps.Cholesky, for solve_rows' sparse right-hand sides and eigen_rows at sigma = 0),
    or None where that path is not taken: JOINTFEM_MUMPS=petsc, or jointfem.mumps unavailable here
    (then LinAlgError if ``required``).  The caller destroys it."""
    from . import mumps

    reason = mumps.unavailable()
    if reason is not None or (not required and os.environ.get("JOINTFEM_MUMPS") == "petsc"):
        if required:
            raise LinAlgError(f"{what}: MUMPS cannot be called directly: {reason}")
        return None
    try:
        return mumps.Cholesky(A, A.getComm().tompi4py(), what=what, audit=_audit)
    except mumps.MumpsUnavailable as exc:
        if required:
            raise LinAlgError(str(exc)) from exc
        return None
    except mumps.MumpsError as exc:
        raise LinAlgError(str(exc)) from exc


def solve_rows(A, B, *, what: str, comm=None, symmetric: bool = True, chunk: int = SOLVE_CHUNK,
               out: np.ndarray | None = None, direct: bool | None = None, factor=None) -> RowBlocks:
    """A^-1 B for a distributed PETSc matrix A and this rank's rows B (n_local, m) of the right-hand
    sides (dense or scipy sparse); the solution stays in the same rows, written into ``out`` if
    given (column blocks are contiguous if ``out`` is in Fortran order).

    Sparse B of a symmetric positive definite A: MUMPS called directly (jointfem.mumps: sparse
    right-hand sides on the host, the solution distributed, up to ``DIRECT_CHUNK`` columns per solve),
    by ``factor`` if given (direct_factor(A)), else by a factorisation made and released here.
    Otherwise (dense B, ``direct`` False, JOINTFEM_MUMPS=petsc, or jointfem.mumps unavailable
    where ``direct`` was left to this function): one MUMPS factorisation through PETSc, then
    MatMatSolve with distributed dense right-hand sides by blocks of ``chunk`` columns, each
    densified only while it is solved."""
    from petsc4py import PETSc

    from . import mumps

    n = A.getSize()[0]
    r0, r1 = A.getOwnershipRange()
    X = np.zeros(B.shape, order="F") if out is None else out
    fits = sp.issparse(B) and symmetric
    if (direct or factor is not None) and not fits:
        raise LinAlgError(f"{what}: a direct MUMPS solve needs sparse right-hand sides of a symmetric matrix")
    own = None
    if factor is None and fits and direct is not False:
        factor = own = direct_factor(A, what=what, required=bool(direct))
    if factor is not None:
        try:
            rows = int(np.diff(A.getOwnershipRanges()).max())  # the same on every rank
            factor.solve_sparse(B, X, chunk=int(np.clip(DIRECT_BLOCK_BYTES // (8 * max(rows, 1)), 16, DIRECT_CHUNK)))
        except mumps.MumpsError as exc:
            raise LinAlgError(str(exc)) from exc
        finally:
            if own is not None:
                own.destroy()
    else:  # PETSc's interface (also where the direct path was chosen by default but is unavailable)
        ksp = _mumps_ksp(A, symmetric=symmetric)
        try:
            ksp.setUp()
        except PETSc.Error as exc:
            raise LinAlgError(f"{what} could not be factorised by MUMPS (error {exc.ierr}): singular? a substructure "
                              f"without supports (rigid-body modes) cannot be factorised") from exc
        factor = ksp.getPC().getFactorMatrix()
        B = sp.csc_matrix(B) if sp.issparse(B) else B
        for c in range(0, B.shape[1], chunk):
            blk = B[:, c:c + chunk]
            Bc = _dense(np.ascontiguousarray(blk.toarray() if sp.issparse(blk) else blk), n)
            Xc = Bc.duplicate()
            factor.matSolve(Bc, Xc)
            X[:, c:c + chunk] = Xc.getDenseArray()
            Bc.destroy()
            Xc.destroy()
        ksp.destroy()
    bad = np.array([0.0 if np.all(np.isfinite(X)) else 1.0])
    if (bad if comm is None else allreduce(comm, bad))[0] > 0:
        raise LinAlgError(f"{what} is singular: the MUMPS solution is not finite (a substructure without supports?)")
    return RowBlocks(X, n, r0, comm)
