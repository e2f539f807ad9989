"""Stability of periodic solutions by Hill's method (Floquet exponents from the HBM Jacobian).

A perturbation e^{s t} v(omega t) of a periodic solution, with v expanded on the same harmonics,
satisfies the quadratic eigenvalue problem

    (J + s Delta1 + s^2 Delta2) v = 0,

J the HBM Jacobian at the solution (with the AFT's contact Jacobian: the contact law linearised
about the steady period, the usual approximation for hysteretic elements) and Delta1, Delta2 from
the problem (Problem.hill_operators).  It is solved in the first-order form
[[0, I], [-J, -Delta1]] z = s [[I, 0], [0, Delta2]] z (dense; massless coordinates give infinite
eigenvalues, which are dropped).  Every Floquet exponent appears 2H+1 times, shifted by i k omega.
The usual selection (Lazarus and Thomas 2010; NLvib and tmdsimpy) takes the ``Problem.num_dynamic()``
finite eigenvalues with the smallest |Im s|.  The verdict here takes the largest real part over
every eigenvalue inside the strip |Im s| <= omega / 2 (``floquet_exponents`` still offers the usual
ordering): each exponent of the periodic solution has a copy there, and one with Im s = omega / 2
two, which the count of ``num_dynamic`` can drop (it did on a 20-mass Jenkins chain, where that pair
led); an eigenvalue of the truncated Hill matrix that the |Im s| ordering selects outside the strip
has no copy inside (measured on the beam at H = 5: 173 + 1438i 1/s at omega = 1702.6 rad/s, with no
copy at 173 - 265i) and is an artefact of the truncation.  The solution is stable when the largest
real part is below STABILITY_RTOL omega: a fold puts a real exponent through zero.

The dense eigenproblem costs (2 n (2H+1))^3: 3 s for the beam's 1320 unknowns (H = 5), minutes at
H = 21.  Above ``DENSE_LIMIT`` first-order unknowns, only the exponents nearest a real shift
sigma = omega / 2 are computed, by shift-invert Arnoldi (ARPACK through scipy) on the same
first-order pencil, with one factorisation of J + sigma Delta1 + sigma^2 Delta2 (sparse or dense, as
J is).  That is enough for the verdict: every copy s + i k omega of an exponent has its real part,
and a copy lies in the strip |Im s| <= omega / 2, so an exponent with -0.059 omega <= Re s <=
1.059 omega has a copy within RADIUS = 0.75 omega of sigma; the count asked for grows until the
farthest one returned lies beyond that radius (``exponents_near``).  The shift lies right of the
imaginary axis because what decides stability lies there: a shift near zero with a radius of
1.2 omega (covering |Re s| < omega) also had to take the copies of every damped high mode up to
about 18 omega (on the beam at H = 35, 54 eigenvalues and a Krylov space of 171 vectors a point),
whose real parts lie far to the left.  A point whose exponents all lie left of -0.059 omega is
stable, and its leading exponent is the largest of those found nearest sigma (at least FIRST).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..hbm.problem import Evaluation, Problem
from ..linalg import sparse_lu

STABILITY_RTOL = 1e-7  # stable when max Re s <= STABILITY_RTOL * omega (Hill's truncation and round-off)
# first-order unknowns up to which every exponent is computed densely.  Above it the Arnoldi path
# is both faster and more accurate on stiff problems: on the 2D lap joint's penalty ROM (H = 3,
# 140-238 unknowns) 0.013 against 0.14 s a point, and where the two differ (by up to 1.6e-3 omega,
# at unstable points) the smallest singular value of J + s d1 + s^2 d2 over its largest is 1e-17 at
# Arnoldi's exponent and 1e-10 at the dense one: the dense eigenvalues of the first-order matrix
# carry round-off of its norm, which the penalty stiffness makes large
DENSE_LIMIT = 200
SHIFT = 0.5  # sigma / omega (right of the axis, where a lost stability is; J itself is singular at a fold)
RADIUS = 0.75  # omega: around sigma, every exponent with -0.059 omega <= Re s <= 1.059 omega has a copy
ARNOLDI_TOL = 1e-9  # ARPACK's relative tolerance on mu = 1 / (s - sigma) (arnoldi_near)
NCV_FACTOR = 2.5  # ARPACK's Krylov space over the count of eigenvalues asked (arnoldi_near)
FIRST = 24  # eigenvalues Arnoldi asks for first at a branch's first point (arnoldi_near)
HILL, HILL_MEMORY = "hill", "hill-memory"  # a point's exponents without, or with, the contact laws' memory
MEMORY_CANDIDATES = 2  # Hill's exponents (largest real parts) from which the memory's are followed (with_memory)
MEMORY_TOL = 1e-7  # omega: the last Newton step (on the slip benchmark the roots then lie 2.2e-12 omega from 1e-13's)
MEMORY_SAME = 1e-6  # omega: a Newton this near a root already found is going there
MEMORY_ITER = 12  # Newton steps (4 to 6 from Hill's exponent where it converges)
MEMORY_REACH = 1.0  # omega: Hill's exponents with |Re s| beyond it are left as they are
MEMORY_NONE = 1e-13  # of max |J|: a correction this small is none (no law remembers anything)


def floquet_exponents(J, d1, d2, num: int) -> np.ndarray:
    """The ``num`` Floquet exponents (1/s) of Hill's problem (J + s d1 + s^2 d2) v = 0.

    Unknowns on which neither d1 nor d2 acts (the penalty ROM's internal variables, which carry
    neither mass nor damping) only give infinite eigenvalues: they are condensed out statically
    first (Schur complement of J), which leaves the same finite exponents.  With the remaining d2
    invertible the first-order form is a standard eigenproblem, else a generalised one."""
    J, d1, d2 = (np.asarray(a.toarray() if sp.issparse(a) else a, dtype=float) for a in (J, d1, d2))
    static = ~((d1 != 0).any(axis=0) | (d1 != 0).any(axis=1) | (d2 != 0).any(axis=0) | (d2 != 0).any(axis=1))
    if static.any():
        d, st = np.flatnonzero(~static), np.flatnonzero(static)
        J = J[np.ix_(d, d)] - J[np.ix_(d, st)] @ np.linalg.solve(J[np.ix_(st, st)], J[np.ix_(st, d)])
        d1, d2 = d1[np.ix_(d, d)], d2[np.ix_(d, d)]
    n = J.shape[0]
    I, Z = np.eye(n), np.zeros((n, n))
    try:  # d2 = I (x) M: symmetric, and positive definite once the static unknowns are out
        c = sla.cho_factor(d2)
        s = np.linalg.eigvals(np.block([[Z, I], [-sla.cho_solve(c, J), -sla.cho_solve(c, d1)]]))
    except np.linalg.LinAlgError:  # a massless but damped coordinate: the generalised problem
        s = sla.eigvals(np.block([[Z, I], [-J, -d1]]), np.block([[I, Z], [Z, d2]]))
    s = s[np.isfinite(s)]
    return s[np.argsort(np.abs(s.imag), kind="stable")][:num]


def max_real_part(problem: Problem, x: np.ndarray, lam: float, evaluation: Evaluation, *,
                  dense: bool | None = None) -> float | None:
    """The largest real part of the Floquet exponents (1/s) of the point x at omega = lam, or None
    (``leading_exponent``'s real part)."""
    s = leading_exponent(problem, x, lam, evaluation, dense=dense)
    return None if s is None else s.real


def leading_exponent(problem: Problem, x: np.ndarray, lam: float, evaluation: Evaluation, *,
                     dense: bool | None = None, memory: bool = True) -> complex | None:
    """The Floquet exponent (1/s) with the largest real part of the point x at omega = lam, in the
    strip |Im s| <= omega / 2 (real: a fold's kind of loss of stability; a complex pair: a
    Neimark-Sacker or period-doubling kind), or None where the problem offers no Hill matrices or
    says why its exponents are not the physical ones.  ``evaluation``: the problem's at (x, lam),
    with its Jacobian.  ``dense``: every exponent by the dense eigenproblem, or (False) those near
    zero by shift-invert Arnoldi; by default dense up to DENSE_LIMIT first-order unknowns.
    ``memory``: with the contact laws' memory where the problem knows it (``with_memory``), or
    (False) Hill's matrix as it is.  Along a branch, ``ExponentTracker`` gives the same exponents
    for less."""
    return _leading(problem, x, lam, evaluation, dense, FIRST, memory)[0]


def _leading(problem, x, lam, evaluation, dense, first, memory=True):
    """(leading exponent or None, eigenvalues Arnoldi found within its radius or None, the method:
    HILL or HILL_MEMORY)."""
    if problem.no_stability is not None:
        return None, None, HILL
    hill = problem.hill_matrices(x, lam, evaluation)
    if hill is None:
        return None, None, HILL
    J, d1, d2, num = hill
    needed = None
    if dense if dense is not None else 2 * J.shape[0] <= DENSE_LIMIT:
        # every exponent inside the strip, as the Arnoldi path takes them: an exponent with
        # Im s = omega / 2 has two copies there, and the ``num`` smallest |Im s| can drop both
        # (measured on a 20-mass Jenkins chain: 42 of 440 inside the strip, the two dropped with the
        # largest real part, -0.0100 against -0.0107 1/s); with none inside, the ``num`` smallest
        s_all = floquet_exponents(J, d1, d2, 2 * J.shape[0])
        inside = s_all[np.abs(s_all.imag) <= 0.5 * abs(lam) * (1 + 1e-9)]
        s = inside if inside.size else s_all[:num]
    else:
        s, needed = arnoldi_near(J, d1, d2, lam, first=first)
    method = HILL
    correction = problem.floquet_correction(x, lam, evaluation) if memory else None
    if correction is not None:
        refined = with_memory(J, d1, d2, correction, s, lam)
        if refined is not None:
            s, method = refined, HILL_MEMORY
    k = int(np.argmax(s.real))
    return complex(s[k].real, abs(s[k].imag)), needed, method  # of a complex pair, the one with Im s > 0


def with_memory(J, d1, d2, correction, s_hill: np.ndarray, omega: float) -> np.ndarray | None:
    """The exponents of Hill's problem with the contact laws' memory, T(s) v = 0 with
    T(s) = J + s d1 + s^2 d2 + dJ(s) (``Problem.floquet_correction``), each by Newton from one of
    the MEMORY_CANDIDATES exponents of ``s_hill`` (Hill's, in the strip) with the largest real
    parts, mapped into the strip; or None where the memory changes nothing (every correction zero),
    is not known (``correction`` answers None), or the Newton from Hill's leading exponent fails
    (then Hill's own exponents stand, and the point says so).  A later start whose Newton fails has no root near it with the memory (on the SDOF
    oscillator, Newton on log det T from there lands on the leading root): it is dropped.

    Newton on the bordered system T(s) x = 0, e^H x = 1 (Ruhe's nonlinear inverse iteration):
    u = T(s)^-1 T'(s) x, s <- s - e^H x / e^H u, x <- u / e^H u, one LU a step, x and e started at
    Hill's right and left eigenvectors (an inverse iteration on Hill's matrix at its exponent), so
    that the first step is the first-order perturbation.  A start that comes within MEMORY_SAME
    omega of a root already found stops there.  On the SDOF and 2-DOF Jenkins oscillators the roots
    are the exponents of an event-driven monodromy matrix (docs/benchmarks_slip_stability.md)."""
    sparse = sp.issparse(J)
    if sparse:  # a full-order model: complex sparse LU (SuperLU)
        Jd, D1, D2 = (sp.csc_matrix(a) for a in (J, d1, d2))

        def factor(A):
            try:
                lu = sparse_lu(A)
            except RuntimeError as exc:  # SuperLU: "Factor is exactly singular"
                raise np.linalg.LinAlgError(str(exc)) from exc
            return lambda v, trans="N": lu.solve(v, trans=trans)
    else:
        Jd, D1, D2 = (np.asarray(a.toarray() if sp.issparse(a) else a, dtype=float) for a in (J, d1, d2))

        def factor(A):
            lu = sla.lu_factor(A, check_finite=False)
            return lambda v, trans="N": sla.lu_solve(lu, v, trans={"N": 0, "H": 2}[trans], check_finite=False)
    scale = max(abs(Jd).max(), 1e-300)
    reach = MEMORY_REACH * abs(omega)
    if s_hill.real.max() > reach:
        return None  # a growth of e^(2 pi) a period or more: no verdict the memory can change
    order = np.argsort(-s_hill.real, kind="stable")
    starts: list[complex] = []
    for z in s_hill[order]:  # one of each complex pair, none damped by more than the reach
        if len(starts) >= MEMORY_CANDIDATES:
            break
        z = complex(z.real, abs(z.imag))
        if z.real >= -reach and all(abs(z - y) > 1e-9 * abs(omega) for y in starts):
            starts.append(z)
    if not starts:
        return None
    rng = np.random.default_rng(0)  # a fixed start vector: the same exponents on every run
    b = rng.standard_normal(Jd.shape[0]) + 1j * rng.standard_normal(Jd.shape[0])
    half = 0.5 * abs(omega)

    def fold(z: complex) -> complex:
        return complex(z.real, abs((z.imag + half) % abs(omega) - half))

    def newton(z: complex, dJ, slope, found: list[complex]) -> complex | None:
        # Hill's eigenvector at its exponent: one inverse iteration on Hill's matrix there (moved
        # off the exponent by round-off's size, so that the factors stay finite)
        for off in (1e-12, 1e-9):  # SuperLU may find the matrix at the exponent exactly singular
            z1 = z * (1.0 + off) + off * abs(omega)
            try:
                solve = factor(Jd + z1 * D1 + z1 * z1 * D2)
            except np.linalg.LinAlgError:
                continue
            x = solve(b)
            left = solve(b, "H")
            if np.all(np.isfinite(x)) and np.all(np.isfinite(left)):
                break
        else:
            return None
        e = left.conj() / (left.conj() @ x)  # e^H x = 1
        for _ in range(MEMORY_ITER):
            try:
                u = factor(Jd + z * D1 + z * z * D2 + dJ)((D1 + 2.0 * z * D2 + slope) @ x)
            except np.linalg.LinAlgError:
                return None
            step = -1.0 / (e @ u)
            if not np.isfinite(step):
                return None
            z += step
            x = -u * step
            if abs(step) <= MEMORY_TOL * abs(omega) or any(abs(fold(z) - r) <= MEMORY_SAME * abs(omega)
                                                           for r in found):
                return fold(z)  # converged, or on its way to a root already found
            if abs(z.real) > 4.0 * reach:
                return None
            dJ, slope = correction(z)
        return None

    at_start = correction(starts[0])
    if at_start is None:  # a law whose memory is not written
        return None
    dJ, slope = at_start
    if abs(dJ).max() <= MEMORY_NONE * scale:
        return None
    first = newton(starts[0], dJ, slope, [])
    if first is None:
        return None
    out = [first]
    for start in starts[1:]:  # a start with no root near it (Newton fails) is one the memory removed
        root = newton(start, *correction(start), out)
        if root is not None:
            out.append(root)
    return np.array(out)


def exponents_near(J, d1, d2, omega: float, *, radius: float | None = None, first: int = 24) -> np.ndarray:
    """The Floquet exponents (1/s) of (J + s d1 + s^2 d2) v = 0 with |Im s| <= omega / 2 among those
    nearest sigma = SHIFT omega, by shift-invert Arnoldi on the first-order pencil (``arnoldi_near``)."""
    return arnoldi_near(J, d1, d2, omega, radius=radius, first=first)[0]


def arnoldi_near(J, d1, d2, omega: float, *, radius: float | None = None,
                 first: int = 24) -> tuple[np.ndarray, int]:
    """``exponents_near`` and how many eigenvalues lay within ``radius`` omega of sigma (what the next
    point of a branch will ask for, ``ExponentTracker``), by shift-invert Arnoldi on

        A z = s B z,  A = [[0, I], [-J, -d1]],  B = [[I, 0], [0, d2]],  z = (v, s v),

    whose operator (A - sigma B)^{-1} B needs one factorisation of Q = J + sigma d1 + sigma^2 d2:
    (A - sigma B)(x, y) = (a, b) gives x = -Q^{-1} (b + (d1 + sigma d2) a), y = a + sigma x.
    Its eigenvalues are mu = 1 / (s - sigma); unknowns without mass or damping give mu = 0 and are
    never returned.  ``first`` eigenvalues are asked for, then twice as many, until the farthest
    returned lies beyond ``radius`` omega of sigma (or every finite one is returned): every exponent
    with a copy nearer than that is then among them, each of its copies having the same real part.

    ARPACK's tolerance is relative to |mu|, so an exponent's error is about ARNOLDI_TOL |s - sigma|,
    below 1e-9 omega inside the radius: 100 times under STABILITY_RTOL.  Its Krylov space holds
    NCV_FACTOR times the eigenvalues asked for (scipy's default is 2).  On 40 points of the beam
    demo's branch, 32 asked at once with this tolerance and space gave the same largest real parts
    (to 5e-12 omega) in 2.7 times less time than 24 then 48 asked, tolerance 1e-12, twice the count."""
    n = J.shape[0]
    radius = RADIUS if radius is None else radius
    sigma = SHIFT * abs(omega)
    sparse = sp.issparse(J)
    d1 = d1.tocsr() if sp.issparse(d1) else sp.csr_matrix(d1)
    d2 = d2.tocsr() if sp.issparse(d2) else sp.csr_matrix(d2)
    if sparse:
        lu = sparse_lu(J + sigma * d1 + sigma**2 * d2)
        solve = lu.solve
    else:
        Q = np.asarray(J, dtype=float) + (sigma * d1 + sigma**2 * d2).toarray()
        lu = sla.lu_factor(Q, check_finite=False)
        solve = lambda b: sla.lu_solve(lu, b, check_finite=False)  # noqa: E731
    shifted = (d1 + sigma * d2).tocsr()

    def op(z):
        z = np.asarray(z).ravel()
        a, b = z[:n], d2 @ z[n:]
        x = -solve(b + shifted @ a)
        return np.concatenate([x, a + sigma * x])

    # unknowns with neither mass nor damping only give mu = 0: the operator's rank bounds the count
    dynamic = int(np.count_nonzero(np.diff(d1.indptr) | np.diff(d2.indptr)))
    most = max(1, min(2 * n - 2, 2 * dynamic))
    k = max(1, min(first, most))
    rng = np.random.default_rng(0)  # a fixed start vector: the same exponents on every run
    v0 = rng.standard_normal(2 * n)
    while True:
        mu = spla.eigs(spla.LinearOperator((2 * n, 2 * n), matvec=op, dtype=float), k=k, which="LM",
                       v0=v0, return_eigenvectors=False, ncv=min(2 * n, max(int(NCV_FACTOR * k) + 1, 40)),
                       tol=ARNOLDI_TOL)
        mu = mu[np.abs(mu) > 1e-300]
        s = sigma + 1.0 / mu
        if k >= most or np.abs(s - sigma).max() > radius * abs(omega):
            break
        k = min(2 * k, most)
    return in_strip(s, omega), int(np.count_nonzero(np.abs(s - sigma) <= radius * abs(omega)))


class ExponentTracker:
    """``leading_exponent`` point after point along a branch.  The count of eigenvalues Arnoldi asks
    for starts from what the previous point needed (a quarter more, at least 8 more), so a branch
    mostly pays for one Arnoldi run a point instead of a run that asks too few and one that asks
    twice as many: on the beam demo (1320 unknowns) each point needs 22-26.  Dense or Arnoldi is
    decided once, on the largest Hill problem the branch can have (``Problem.hill_size``): the
    penalty ROM's size changes along a branch, and the two paths differ by round-off that must not
    show as a change of stability.  An eigensolve that fails (ARPACK without convergence, a singular
    factor) gives None for the point and is counted in ``failures``: the sweep keeps its points."""

    def __init__(self, problem: Problem, *, memory: bool = True):
        self.problem = problem
        self.memory = memory
        self.first = FIRST
        self.dense = 2 * problem.hill_size <= DENSE_LIMIT
        self.failures: list[tuple[float, str]] = []  # (omega, what failed)

    def __call__(self, x: np.ndarray, lam: float, evaluation: Evaluation) -> tuple[complex | None, str]:
        try:
            s, needed, method = _leading(self.problem, x, lam, evaluation, self.dense, self.first, self.memory)
        except (spla.ArpackNoConvergence, spla.ArpackError, RuntimeError, np.linalg.LinAlgError) as exc:
            self.failures.append((float(lam), f"{type(exc).__name__}: {exc}"))
            return None, HILL
        if needed is not None:
            self.first = max(FIRST, needed + max(8, needed // 4))
        return s, method


def in_strip(s: np.ndarray, omega: float) -> np.ndarray:
    """The exponents with |Im s| <= omega / 2, or all of them where none is: with too few harmonics
    for a mode far above omega (an SDOF at omega = 0.5 rad/s with H = 1: its copies 1 + k omega,
    |k| <= H, never reach the strip) the strip holds no copy, and the |Im s| ordering decides."""
    inside = s[np.abs(s.imag) <= 0.5 * abs(omega) * (1 + 1e-9)]
    return inside if inside.size else s


def is_stable(max_real: float, omega: float) -> bool:
    return max_real <= STABILITY_RTOL * abs(omega)
