"""MUMPS through its own C interface, for what PETSc 3.18's interface makes costly or does not offer:
many sparse right-hand sides with the solution left distributed (real, ``Cholesky``), and complex
symmetric factorisations with a Schur complement (``BorderedSchur``).

The penalty ROM's static modes are K_lin^-1 G^T Kc: one right-hand side per contact component, two
to six nonzeros each (the DOFs of the pair's two nodes that its direction reads).  PETSc's
MatMatSolve hands MUMPS dense right-hand sides (every front visited in the forward sweep) and, in
parallel, builds and sorts a scatter of the whole distributed solution at every call (perf of a
2-rank run on 100,548 DOFs and 1575 right-hand sides: PETSc's sorting 21 % and page zeroing 31 %
of rank 0's samples; its static solves took longer on 2 ranks than on 1).  Its sparse path
(MatMatTransposeSolve, which petsc4py 3.18 does not wrap) takes every column in one call and
scatters them all (23 s on 2 ranks against 5 s on 1, measured before).  Called directly, MUMPS
takes the sparse right-hand sides on the host (ICNTL(20) = 1: O(pairs) data, so its forward sweep
visits only the fronts above the interface) and leaves the solution distributed (ICNTL(21) = 1),
which is then sent to the rows each rank owns in PETSc's layout.

The exact condensation's harmonics need complex MUMPS, which Debian's real PETSc does not offer, and
MUMPS's Schur complement, which gives the receptance on the gaps C Z^-1 C^T from the factorisation
of the bordered matrix [[Z, C^T], [C, 0]] without the n x r solutions (``BorderedSchur``).

The structures DMUMPS_STRUC_C and ZMUMPS_STRUC_C are read from the installed headers (dmumps_c.h,
zmumps_c.h: Debian's libmumps-dev, which PETSc's development package brings) by cffi, so they match
the installed library's version; the version MUMPS writes into them at initialisation must be the
header's.
``unavailable()`` says why this path cannot be used (jointfem.linalg then keeps PETSc's path).
Part of the linear-algebra layer: only jointfem.linalg calls it.
"""
from __future__ import annotations

import ctypes.util
import functools
import re
from pathlib import Path

import numpy as np
import scipy.sparse as sp

HEADER_DIRS = (Path("/usr/include"), Path("/usr/include/mumps"), Path("/usr/local/include"))
JOB_INIT, JOB_END, JOB_ANALYSE, JOB_FACTOR, JOB_ANALYSE_FACTOR, JOB_SOLVE = -1, -2, 1, 2, 4, 3


class MumpsError(RuntimeError):
    """MUMPS reported an error (its INFOG(1) < 0)."""


class MumpsUnavailable(MumpsError):
    """MUMPS cannot be called directly here (no header, no library, or a structure that does not
    match the library's)."""


ARITHMETICS = {"d": ("double", "double"), "z": ("mumps_double_complex", "double")}  # (entry type, real type)


@functools.lru_cache(maxsize=2)
def _interface(arith: str = "d"):
    """(ffi, lib, MUMPS_INT as a numpy dtype and as a C type, the header's MUMPS_VERSION or None)
    for ``arith``mumps_c ("d": real, "z": complex double), or a string saying why there is none."""
    try:
        import cffi
    except ImportError:
        return "cffi is not installed"
    name = f"{arith}mumps_c.h"
    header = next((d / name for d in HEADER_DIRS if (d / name).is_file()), None)
    if header is None:
        return f"{name} not found (Debian package libmumps-dev) in " + ", ".join(map(str, HEADER_DIRS))
    text = header.read_text()
    A = arith.upper()
    found = re.search(rf"typedef\s+struct\s*\{{(.*?)\}}\s*{A}MUMPS_STRUC_C\s*;", text, re.S)
    maxlen = re.search(r"#\s*define\s+MUMPS_VERSION_MAX_LEN\s+(\d+)", text)
    version = re.search(r'#\s*define\s+MUMPS_VERSION\s+"([^"]+)"', text)
    if found is None or maxlen is None:
        return f"{header}: {A}MUMPS_STRUC_C or MUMPS_VERSION_MAX_LEN not found"
    intdef = header.parent / "mumps_int_def.h"
    int64 = intdef.is_file() and re.search(r"^\s*#\s*define\s+MUMPS_INTSIZE64", intdef.read_text(), re.M)
    body = re.sub(r"/\*.*?\*/", "", found.group(1), flags=re.S)
    if "#" in body:
        return f"{header}: preprocessor lines inside {A}MUMPS_STRUC_C, not parsed"
    cint = "int64_t" if int64 else "int"
    entry, real = ARITHMETICS[arith]
    for macro, ctype in (("MUMPS_VERSION_MAX_LEN", maxlen.group(1)), ("MUMPS_INT8", "int64_t"),
                         ("MUMPS_INT", cint), (f"{A}MUMPS_COMPLEX", entry), (f"{A}MUMPS_REAL", real)):
        body = re.sub(rf"\b{macro}\b", ctype, body)
    library = ctypes.util.find_library(f"{arith}mumps")
    if library is None:
        return f"lib{arith}mumps not found"
    ffi = cffi.FFI()
    try:
        ffi.cdef("typedef struct {double r, i;} mumps_double_complex;\n"
                 f"typedef struct {{{body}}} MUMPS_STRUC_C;\nvoid {arith}mumps_c(MUMPS_STRUC_C *);")
        lib = ffi.dlopen(library)
    except Exception as exc:  # cffi's parser or the loader: say what, keep PETSc's path
        return f"{header} with {library}: {exc}"
    return ffi, lib.dmumps_c if arith == "d" else lib.zmumps_c, (np.int64 if int64 else np.int32), cint, \
        version.group(1) if version else None


def unavailable(arith: str = "d") -> str | None:
    """None if MUMPS (real: "d", complex: "z") can be called directly here, else the reason."""
    found = _interface(arith)
    return found if isinstance(found, str) else None


class _Instance:
    """One MUMPS instance (JOB = -1 .. -2) of arithmetic ``arith`` over ``comm``: the structure with
    room to spare behind it (a library whose structure were larger than the header's could not write
    past it) and the version check that the layouts agree."""

    def __init__(self, arith: str, comm, *, sym: int, what: str):
        found = _interface(arith)
        if isinstance(found, str):
            raise MumpsUnavailable(f"{what}: MUMPS cannot be called directly: {found}")
        self._ffi, self._call_c, self._int, self._cint, version = found
        self.what, self.comm = what, comm
        ffi = self._ffi
        self._buf = ffi.new("char[]", ffi.sizeof("MUMPS_STRUC_C") + 65536)
        self._id = ffi.cast("MUMPS_STRUC_C *", self._buf)
        self._id.comm_fortran = comm.py2f()
        self._id.par, self._id.sym = 1, sym  # the host works too
        self._call(JOB_INIT, "initialisation")
        got = ffi.string(self._id.version_number).decode(errors="replace").strip()
        if version is not None and got != version:
            raise MumpsUnavailable(f"{what}: the MUMPS library reports version {got!r} in the structure read from "
                                   f"its header (version {version!r}): the layouts differ, not called directly")
        for k, v in ((1, -1), (2, -1), (3, -1), (4, 0)):  # silent
            self._id.icntl[k - 1] = v

    def _ptr(self, a: np.ndarray):
        if a.dtype.kind == "c":
            return self._ffi.from_buffer("mumps_double_complex[]", a)
        return self._ffi.from_buffer(("double" if a.dtype == float else self._cint) + "[]", a)

    def _call(self, job: int, stage: str) -> None:
        self._id.job = job
        self._call_c(self._id)
        info = int(self._id.infog[0])
        if info < 0:
            hint = " (the matrix is singular or not positive definite: a substructure without supports?)" \
                if info in (-10, -40) else ""
            raise MumpsError(f"{self.what}: MUMPS {stage} failed, INFOG(1) = {info}, INFOG(2) = "
                             f"{int(self._id.infog[1])}{hint}")

    def destroy(self) -> None:
        """Release MUMPS's memory (collective)."""
        if self._id is not None:
            self._id.irn_loc = self._id.jcn_loc = self._id.a_loc = self._ffi.NULL
            self._call(JOB_END, "release")
            self._id = None


class Cholesky(_Instance):
    """The LDL^T factorisation of a symmetric positive definite distributed PETSc matrix by MUMPS
    (its upper triangle handed over as each rank's rows: ICNTL(18) = 3; SYM = 2, the pivoting
    PETSc's Cholesky through MUMPS uses too), for sparse right-hand sides (``solve_sparse``) and for
    one dense one at a time (``solve_dense``: SLEPc's shift-invert, jointfem.linalg.eigen_rows).
    Collective over ``comm`` (mpi4py); call ``destroy()`` on every rank.  ``audit(kind, shape)`` is
    told what crosses the ranks."""

    def __init__(self, A, comm, *, what: str, audit=None):
        super().__init__("d", comm, sym=2, what=what)  # symmetric (LDL^T with pivoting)
        self.audit = audit
        self._dense = None  # solve_dense's buffers and route, made at its first call
        self.n = A.getSize()[0]
        self.r0, self.r1 = A.getOwnershipRange()
        indptr, cols, vals = A.getValuesCSR()
        rows = np.repeat(np.arange(self.r0, self.r1), np.diff(indptr))
        upper = cols >= rows
        self._keep = [np.ascontiguousarray(rows[upper] + 1, dtype=self._int),
                      np.ascontiguousarray(cols[upper] + 1, dtype=self._int),
                      np.ascontiguousarray(vals[upper], dtype=float)]
        self._id.icntl[17] = 3  # ICNTL(18) = 3: distributed assembled input
        self._id.n = self.n
        self._id.nnz_loc = self._keep[0].size
        self._id.irn_loc = self._ptr(self._keep[0])
        self._id.jcn_loc = self._ptr(self._keep[1])
        self._id.a_loc = self._ptr(self._keep[2])
        self._call(JOB_ANALYSE_FACTOR, "analysis and factorisation")

    def solve_dense(self, b: np.ndarray, out: np.ndarray) -> None:
        """A^-1 b into ``out``, both this rank's rows (n_local,): the right-hand side distributed as
        PETSc holds it (ICNTL(20) = 10), the solution distributed (ICNTL(21) = 1) and sent to the
        rows' owners."""
        idd = self._id
        if self._dense is None:
            lsol = int(idd.info[22])
            self._dense = {"rows": np.arange(self.r0 + 1, self.r1 + 1, dtype=self._int),
                           "rhs": np.zeros(self.r1 - self.r0), "sol": np.empty(lsol),
                           "isol": np.empty(lsol, dtype=self._int), "route": None}
        d = self._dense
        d["rhs"][:] = b
        idd.icntl[19], idd.icntl[20] = 10, 1
        idd.nrhs, idd.lrhs = 1, self.n
        idd.nloc_rhs, idd.lrhs_loc = self.r1 - self.r0, max(1, self.r1 - self.r0)
        idd.irhs_loc, idd.rhs_loc = self._ptr(d["rows"]), self._ptr(d["rhs"])
        idd.lsol_loc = d["sol"].size
        idd.sol_loc, idd.isol_loc = self._ptr(d["sol"]), self._ptr(d["isol"])
        self._call(JOB_SOLVE, "solve of one dense right-hand side")
        if d["route"] is None:
            d["route"] = _Route(self.comm, d["isol"] - 1, self.r0, self.r1, 1, self.audit)
        d["route"].deliver(d["sol"].reshape(1, -1), out.reshape(1, -1))
        idd.irhs_loc = idd.rhs_loc = idd.sol_loc = idd.isol_loc = self._ffi.NULL

    def solve_sparse(self, B_local: sp.spmatrix, out: np.ndarray, *, chunk: int) -> None:
        """A^-1 B into ``out`` (this rank's rows, n_local x m), B given as this rank's rows
        (sparse, n_local x m).  B's nonzeros go to the host (what crosses: nnz(B) entries); each
        block of ``chunk`` columns is solved with its solution distributed as MUMPS maps it, then
        sent to the ranks that own the rows."""
        comm, ffi, idd, audit = self.comm, self._ffi, self._id, self.audit
        B = sp.coo_matrix(B_local)
        m = B.shape[1]
        parts = [(B.row + self.r0, B.col, B.data)]
        if comm.size > 1:
            parts = comm.gather(parts[0], root=0)
        if comm.rank == 0:  # the right-hand sides by columns (compressed column storage, 1-based)
            rows, cols, vals = (np.concatenate(x) for x in zip(*parts))
            if audit and comm.size > 1:
                audit("gather", (rows.size, 3))
            Bc = sp.csc_matrix((vals, (rows, cols)), shape=(self.n, m))
            Bc.sum_duplicates()
            Bc.sort_indices()
        lsol = int(idd.info[22])  # INFO(23): the solution entries this rank holds
        sol = np.empty(lsol * min(chunk, m))
        isol = np.empty(lsol, dtype=self._int)
        idd.icntl[19], idd.icntl[20] = 1, 1  # ICNTL(20) = 1: sparse right-hand sides; ICNTL(21) = 1
        idd.lsol_loc = lsol
        idd.sol_loc, idd.isol_loc = self._ptr(sol), self._ptr(isol)
        idd.lrhs = self.n
        route = None
        for c in range(0, m, chunk):
            e = min(c + chunk, m)
            if comm.rank == 0:
                blk = Bc[:, c:e]
                keep = (np.ascontiguousarray(blk.indptr + 1, dtype=self._int),
                        np.ascontiguousarray(blk.indices + 1, dtype=self._int), np.ascontiguousarray(blk.data))
                idd.irhs_ptr, idd.irhs_sparse, idd.rhs_sparse = (self._ptr(a) for a in keep)
                idd.nz_rhs = keep[2].size
            idd.nrhs = e - c
            self._call(JOB_SOLVE, f"solve of right-hand sides {c} to {e - 1}")
            if route is None:
                route = _Route(comm, isol - 1, self.r0, self.r1, min(chunk, m), audit)
            into = out[:, c:e].T  # (k, n_local): C-contiguous where ``out`` is in Fortran order
            target = into if into.flags.c_contiguous else np.empty(into.shape)
            route.deliver(sol[:lsol * (e - c)].reshape(e - c, lsol), target)
            if target is not into:
                into[...] = target
        if comm.rank == 0:
            idd.irhs_ptr = idd.irhs_sparse = idd.rhs_sparse = ffi.NULL
        idd.sol_loc = idd.isol_loc = ffi.NULL



class BorderedSchur(_Instance):
    """Complex symmetric Z(c) = sum_j c_j A_j (the A_j real, symmetric, sparse, n x n, given whole on
    every rank; each rank hands MUMPS the upper triangle of its block of rows) bordered by C (r x n):
    the augmented matrix [[Z, C^T], [C, 0]], whose Schur complement on its last r variables MUMPS
    forms during the factorisation (ICNTL(19) = 1, returned on the host): -C Z^-1 C^T.  The analysis
    (ordering and symbolic factorisation, on the union of the A_j's patterns) is done once;
    ``factor(c)`` factorises again for new coefficients (JOB = 2) and returns R = C Z^-1 C^T on every
    rank; ``solve(b)`` gives Z^-1 b on the host (the internal problem, ICNTL(26) = 0), None elsewhere.
    What crosses the ranks: MUMPS's own traffic, the r x r complement (broadcast) and whatever
    the caller broadcasts.  Collective over ``comm``; call ``destroy()`` on every rank."""

    def __init__(self, mats, C, comm, *, what: str):
        super().__init__("z", comm, sym=2, what=what)  # complex symmetric (not Hermitian): LDL^T
        n, r = mats[0].shape[0], C.shape[0]
        self.n, self.r = n, r
        lo, hi = n * comm.rank // comm.size, n * (comm.rank + 1) // comm.size
        parts = []
        for A in mats:
            Ab = sp.csr_matrix(A)[lo:hi].tocoo()
            rows = Ab.row.astype(np.int64) + lo
            up = Ab.col >= rows
            parts.append((rows[up] * n + Ab.col[up], Ab.data[up]))
        union = np.unique(np.concatenate([k for k, _ in parts]))
        self._coef = np.zeros((len(mats), union.size))  # each A_j's entries on the union's pattern
        for j, (keys, vals) in enumerate(parts):
            np.add.at(self._coef[j], np.searchsorted(union, keys), vals)
        Cc = sp.coo_matrix(C)
        mine = (Cc.col >= lo) & (Cc.col < hi)  # the border's entries (j, n + i), j < n + i: row j's owner
        self._m = union.size
        self._keep = [np.ascontiguousarray(np.concatenate([union // n, Cc.col[mine]]) + 1, dtype=self._int),
                      np.ascontiguousarray(np.concatenate([union % n, n + Cc.row[mine]]) + 1, dtype=self._int),
                      np.zeros(union.size + int(mine.sum()), dtype=complex)]
        self._keep[2][self._m:] = Cc.data[mine]
        idd = self._id
        idd.icntl[13] = 40  # ICNTL(14): 40 % more working space than the analysis estimates
        idd.icntl[17], idd.icntl[18] = 3, 1  # distributed assembled input; Schur complement on the host
        idd.n = n + r
        idd.nnz_loc = self._keep[0].size
        idd.irn_loc, idd.jcn_loc, idd.a_loc = (self._ptr(a) for a in self._keep)
        if comm.rank == 0:
            self._schur_vars = np.arange(n + 1, n + r + 1, dtype=self._int)
            self._schur = np.empty(r * r, dtype=complex)
            idd.size_schur = r
            idd.listvar_schur, idd.schur = self._ptr(self._schur_vars), self._ptr(self._schur)
        self._call(JOB_ANALYSE, "analysis")
        self.coefficients = None  # those of the current factorisation

    def factor(self, coefficients) -> np.ndarray:
        """Factorise Z = sum_j c_j A_j and return R = C Z^-1 C^T (r x r complex, every rank)."""
        c = np.asarray(coefficients, dtype=complex)
        self._keep[2][:self._m] = c @ self._coef
        self.coefficients = None
        # no null-pivot detection (ICNTL(24) = 0): it flagged the bolted plate of tests/test_preload.py,
        # which the condensation handles; jointfem.hbm.condensed forms the static harmonic by
        # jointfem.linalg.Factorized, whose pivot check refuses a body without supports
        self._call(JOB_FACTOR, "factorisation")
        self.coefficients = tuple(c)
        R = None
        if self.comm.rank == 0:
            # the lower triangle of this row-major view: "by rows, the lower triangular part" for a
            # symmetric matrix (ICNTL(19) = 1); the rest of the array is not defined (MUMPS 5.5 leaves
            # zeros there for small complements and work data for larger ones: 77138 nonzeros above
            # the diagonal at r = 650, tests/test_exact_schur.py)
            S = np.tril(self._schur.reshape(self.r, self.r))
            R = -(S + np.tril(S, -1).T)
        if self.comm.size > 1:
            R = self.comm.bcast(R, root=0)
        if not np.isfinite(R).all():  # on every rank alike, after the broadcast
            raise MumpsError(f"{self.what}: MUMPS returned a Schur complement with non-finite entries")
        return R

    @property
    def factor_bytes(self) -> int:
        """The last factorisation's memory over every rank (INFOG(22), MB), in bytes."""
        return int(self._id.infog[21]) * 2**20

    def solve(self, b: np.ndarray | None) -> np.ndarray | None:
        """Z^-1 b for b (n,) or (n, k) given on the host (ignored elsewhere): the solution on the host,
        None on the other ranks."""
        idd = self._id
        idd.icntl[19], idd.icntl[20], idd.icntl[25] = 0, 0, 0  # dense centralised right-hand sides and solution
        host = self.comm.rank == 0
        if host:
            b = np.asarray(b)
            one = b.ndim == 1
            B = b.reshape(self.n, -1)
            buf = np.zeros((B.shape[1], self.n + self.r), dtype=complex)  # Fortran order (n + r) x k
            buf[:, :self.n] = B.T
            idd.rhs, idd.lrhs, idd.nrhs = self._ptr(buf), self.n + self.r, B.shape[1]
        self._call(JOB_SOLVE, "solve")
        if not host:
            return None
        idd.rhs = self._ffi.NULL
        x = buf[:, :self.n].T
        return np.ascontiguousarray(x[:, 0]) if one else np.array(x)

    def destroy(self) -> None:
        if self._id is not None and self.comm.rank == 0:
            self._id.listvar_schur = self._id.schur = self._ffi.NULL
        super().destroy()


class _Route:
    """Moves blocks of MUMPS's distributed solution (one row per right-hand side, the entries in
    MUMPS's order ``held``, 0-based global rows) to the rows this rank owns in PETSc's layout,
    straight into the caller's array, through send and receive buffers allocated once (fresh
    memory is slow to touch on this kind of machine: a new 100 MB temporary per block cost more
    than the move itself)."""

    def __init__(self, comm, held: np.ndarray, r0: int, r1: int, chunk: int, audit):
        self.comm = comm
        if comm.size == 1:
            self.order = None
            self.land = np.empty(held.size, dtype=np.int64)
            self.land[held - r0] = np.arange(held.size)
            return
        ends = np.array(comm.allgather(r1))
        owner = np.searchsorted(ends, held, side="right")
        self.order = np.argsort(owner, kind="stable")  # by destination rank
        self.send = np.bincount(owner, minlength=comm.size)
        self.recv = np.array(comm.alltoall(self.send.tolist()))
        got = np.empty(int(self.recv.sum()), dtype=np.int64)
        comm.Alltoallv([np.ascontiguousarray(held[self.order], dtype=np.int64), self.send], [got, self.recv])
        if audit:
            audit("redistribute", (got.size, chunk))
        self.sstart = np.concatenate([[0], np.cumsum(self.send)])
        self.rstart = np.concatenate([[0], np.cumsum(self.recv)])
        self.land = got - r0  # where each received entry goes, in the order of the sources
        self.sendbuf = np.empty(held.size * chunk)
        self.recvbuf = np.empty(got.size * chunk)

    def deliver(self, solved: np.ndarray, into: np.ndarray) -> None:
        """``solved`` (k, entries held here) into ``into`` (k, n_local), a C-contiguous view (the
        transpose of a Fortran-order block of columns)."""
        k = solved.shape[0]
        if self.order is None:
            np.take(solved, self.land, axis=1, out=into, mode="clip")  # clip: no buffered copy
            return
        # to each destination d a (k, count_d) block, from each source s a (k, count_s) block
        for d in range(self.comm.size):
            a, b = self.sstart[d], self.sstart[d + 1]
            np.take(solved, self.order[a:b], axis=1, out=self.sendbuf[a * k:b * k].reshape(k, b - a), mode="clip")
        total_s, total_r = int(self.sstart[-1]), int(self.rstart[-1])
        self.comm.Alltoallv([self.sendbuf[:total_s * k], self.send * k], [self.recvbuf[:total_r * k], self.recv * k])
        for src in range(self.comm.size):
            a, b = self.rstart[src], self.rstart[src + 1]
            into[:, self.land[a:b]] = self.recvbuf[a * k:b * k].reshape(k, b - a)
