"""Generic pseudo-arclength continuation of R(x, lam) = 0.  Knows nothing about vibration.

The caller supplies scales: the continuation works on y = x / x_scale,
mu = lam / lam_scale and r = R / r_scale, so that one step length ``ds``
means the same on every unknown.  A step is: tangent predictor, then Newton
corrector on R = 0 and t . (y - y_pred) = 0 (Keller's hyperplane).  The step
grows after easy corrections, halves after failed ones, and stays in
[ds_min, ds_max]; a step whose tangent turns by more than ``max_turn`` is
rejected unless it is already shorter than ``turn_ds_floor`` (no silent jumps
over folds or onto other branches; true corners of a nonsmooth branch pass).
"""
from __future__ import annotations

import logging
import time
import warnings
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

log = logging.getLogger(__name__)


class ConvergenceError(RuntimeError):
    """Newton failed: carries the iteration count, the last residual norm and lam."""

    def __init__(self, message: str, *, iterations: int, residual: float, lam: float):
        super().__init__(message)
        self.iterations = iterations
        self.residual = residual
        self.lam = lam


class _OutOfTime(Exception):
    """The branch's time limit passed during a step (not a RuntimeError: no step may catch it)."""


class ContinuationError(RuntimeError):
    """Continuation cannot go on (step at its minimum, a budget reached, the branch out of bounds).

    ``points``: the points converged before it stopped (a caller may keep them)."""

    def __init__(self, message: str, *, points: list | None = None, interrupted: bool = False):
        super().__init__(message)
        self.points = list(points or [])
        self.interrupted = interrupted  # stopped by Ctrl-C (SIGINT)


class Adaptive:
    """Hooks of a problem whose equations, and whose unknowns, change along the branch (the penalty
    ROM's active set).

    x always has the same length (the problem's coefficients); ``unknowns()`` says which of them
    are solved now (an index array, or None: all).  The others are zero: the problem's equations
    hold them there, and Newton does not see them (its system has len(unknowns()) rows).
    ``before_step(x, lam)`` runs before each predictor at the last accepted point; True means it
    changed the problem (and perhaps its unknowns: a coefficient that leaves them is zeroed).
    ``after_converge(x, lam)`` runs on each converged corrector; True means the point broke a
    condition of the problem, which has been changed, and the step is redone from the last
    accepted point with the same length.
    """

    max_redo: int = 50

    def unknowns(self) -> np.ndarray | None:  # pragma: no cover - interface
        return None

    def before_step(self, x, lam) -> bool:  # pragma: no cover - interface
        return False

    def after_converge(self, x, lam) -> bool:  # pragma: no cover - interface
        return False

    def restore(self, state) -> None:  # pragma: no cover - interface
        """Put the problem back in a state it recorded at a converged point (for solves after the
        branch, e.g. locating a peak between recorded points)."""

    def state_of(self, x):  # pragma: no cover - interface
        """The state in which every coefficient of x that is not zero is an unknown (for a solve
        from a point of a branch whose state was not kept: a guess, a resumed run)."""
        return None


@dataclass(frozen=True)
class NewtonOptions:
    tol: float = 1e-10  # on max|R| / r_scale
    max_iter: int = 40
    kink_tol: float = 1e-8  # a Newton stalled on a kink of the sampled law is accepted below this,
    stall_iter: int = 8  # after this many iterations without halving its best residual (_damped_newton)
    max_backtrack: int = 6  # step halvings of the line search
    relaxed_kink_tol: float = 1e-6  # kink_tol once the step has shrunk below ContinuationOptions.relax_ds


@dataclass(frozen=True)
class ContinuationOptions:
    ds0: float = 0.02
    ds_min: float = 1e-6
    ds_max: float = 0.1
    grow: float = 1.5
    target_iter: int = 4  # grow the step if the corrector needed at most this many iterations
    # a guard on memory more than on time (time_limit is the budget): 20000 points hold every sweep of
    # issue 14's list (the beam at H = 15, N = 4096: 13308 points)
    max_points: int = 20000
    max_turn_deg: float = 45.0
    turn_ds_floor: float = 1e-4  # steps shorter than this are not refused for turning
    target_turn_deg: float = 8.0  # the step shrinks when the tangent turns more than this
    relax_ds: float = 1e-5  # below this step a corrector stalled on a kink is accepted up to relaxed_kink_tol
    max_jump: float = 3.0  # a corrector that lands farther than this many steps from the last point fails
    max_reversal_deg: float = 30.0  # a step whose tangent turns by more than 180 - this is always refused
    # a step that changes x by more than this times max(|x|, |x_new|) is refused, however short (None: no
    # such rule; a forced response never passes through zero, so a step that flips its sign has jumped)
    max_rel_change: float | None = None
    lam_bounds: tuple[float, float] | None = None  # the branch must stay inside (else ContinuationError)
    # corner steps: a step refused at most this long, across which the orientation of the branch
    # flips (a fold on a kink of the sampled law), is tried again along the tangent of the piece
    # beyond the first flip, located to corner_bisections halvings of the step
    corner_steps: bool = True
    corner_ds: float = 1e-4  # as turn_ds_floor: a step this short does not cut a smooth fold (< 1e-4 of the scales)
    corner_bisections: int = 8
    # a corrector converges in at most 5 iterations on the beam and lap joints (measured); one that
    # has not in this many is cycling between the pieces of a kink, and the step is refused sooner
    corrector_max_iter: int = 15
    # steps over kinks at fixed lam: a step refused at most corner_ds long is tried again as Newton at
    # fixed lam = lam + ds t_lam from the predictor, where the branch goes on in lam (see across())
    kink_lam_steps: bool = True
    # kink-aware steps: the secant is the tangent at a point whose corrector stalled on a kink, and a
    # tangent's turn beyond max_turn_deg that stays as large when the step halves is a corner, accepted
    secant_on_kinks: bool = True
    # a step whose new point lies within this times its length of the branch already traced, walked the
    # other way, is refused, however short (None: no such rule): a corner step can turn back onto the
    # way it came (issue 14: the 3D lap joint's penalty ROM at 1712.87 rad/s), which no local rule sees
    retrace_tol: float | None = 0.1
    time_limit: float | None = None  # s: the branch stops with a ContinuationError (points kept) past this
    # a sharp corner (the last resort before a stop) may be probed from the last point converged to
    # the tolerance this many points back, over points accepted only at the relaxed kink tolerance
    max_relaxed_back: int = 50
    # leaps (the last resort before a stop, see leap()): Newton at fixed lam + corner_ds 2^k (towards
    # lam_end), k < leap_tries, at most max_leaps times on a branch (0: never)
    leap_tries: int = 6
    max_leaps: int = 20
    newton: NewtonOptions = field(default_factory=NewtonOptions)


def sparse_lu(A):
    """SuperLU's factors ordered on the pattern of A + A^T, as jointfem.linalg.sparse_lu (which says
    why; this layer imports nothing of jointfem)."""
    return spla.splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A")


def linear_solve(A, b):
    """A x = b for a dense or sparse A (SuperLU)."""
    if sp.issparse(A):
        return sparse_lu(A).solve(b)
    return np.linalg.solve(A, b)


def bordered(J, c, t):
    """The matrix [[J, c], [t^T, 0]] (sparse if J is)."""
    if sp.issparse(J):
        return sp.bmat([[J, sp.csr_matrix(c[:, None])], [sp.csr_matrix(t[None, :-1]), sp.csr_matrix([[t[-1]]])]],
                       format="csc")
    n = J.shape[0]
    A = np.empty((n + 1, n + 1))
    A[:n, :n] = J
    A[:n, n] = c
    A[n] = t
    return A


def _scaled(fun, space: "_Space", lam_scale, r_scale):
    """Wrap fun(x, lam) -> (R, J, dR/dlam), which takes every coefficient, into the scaled unknowns
    of ``space``."""
    def g(y, mu):
        R, J, dl = fun(space.full(y), mu * lam_scale)
        if R.shape[0] != np.size(y):
            raise ValueError(f"the problem returned {R.shape[0]} residuals for {np.size(y)} unknowns: "
                             "an adaptive problem's unknowns (Adaptive.unknowns) were not passed")
        if J is not None:
            J, dl = _scaled_jacobian(J, dl, space, lam_scale, r_scale)
        return R / r_scale, J, dl

    return g


def _scaled_jacobian(J, dl, space: "_Space", lam_scale, r_scale):
    """dR/dx and dR/dlam in the scaled variables of ``space``."""
    J = (J @ sp.diags(space.scale)) / r_scale if sp.issparse(J) else J * space.scale / r_scale
    return J, dl * lam_scale / r_scale


class _Space:
    """The unknowns solved among the coefficients x (n,): ``select`` (index array; None: all), in
    the scaled variables y = x[select] / x_scale[select]; the other coefficients are zero."""

    def __init__(self, x_scale: np.ndarray, select: np.ndarray | None):
        self.x_scale = x_scale
        self.select = np.arange(x_scale.size) if select is None else np.asarray(select)
        self.scale = x_scale[self.select]

    def full(self, y: np.ndarray) -> np.ndarray:
        """The coefficients x of scaled unknowns y."""
        x = np.zeros(self.x_scale.size)
        x[self.select] = y * self.scale
        return x

    def sub(self, x: np.ndarray) -> np.ndarray:
        """The scaled unknowns of coefficients x."""
        return x[self.select] / self.scale

    def carry(self, v: np.ndarray, other: "_Space") -> np.ndarray:
        """A scaled vector of ``other``'s unknowns in this space's (a coordinate scaled the same
        in both): a coefficient new to this space gets 0, one that left is dropped."""
        w = np.zeros(self.x_scale.size)
        w[other.select] = v
        return w[self.select]


def _roundoff(A, z):
    """Per row, the round-off of evaluating A z: 32 eps sum_j |A_ij z_j|.  A residual below it is
    converged whatever the tolerance (a stiff ROM coordinate, 2e15 N/m, puts this above 1e-10)."""
    Az = (abs(A) @ np.abs(z)) if sp.issparse(A) else np.abs(A) @ np.abs(z)
    return 32.0 * np.finfo(float).eps * np.asarray(Az).ravel()


def _damped_newton(F, z0, opts: "NewtonOptions", what: str, lam_of):
    """Newton with backtracking on ||r||_2.  F(z) -> (r, A).

    Returns (z, iterations, max|r|); raises ConvergenceError.  The residual of a sampled
    Jenkins law is only piecewise smooth: at a kink, one-sided Jacobians make Newton cycle,
    which the backtracking breaks.  If a root sits on a kink, Newton may stall above ``tol``;
    it is then accepted only below ``kink_tol`` and after ``stall_iter`` iterations without
    halving the best residual, and the achieved residual is returned for the record.
    """
    z = z0
    r, A = F(z)
    res = float(np.max(np.abs(r))) if r.size else 0.0
    best_res, best_z, best_it = res, z, 0
    for it in range(opts.max_iter + 1):
        if not np.isfinite(res):
            break
        if res <= opts.tol or (r.size and np.all(np.abs(r) <= _roundoff(A, z))):
            return z, it, res
        if res < 0.5 * best_res:
            best_res, best_z, best_it = res, z, it
        elif res < best_res:
            best_res, best_z = res, z
        if it - best_it >= opts.stall_iter and best_res <= opts.kink_tol:
            return best_z, it, best_res
        if it - best_it >= 2 * opts.stall_iter:
            break  # no halving of the residual for this long: give up early (the step will shrink)
        if it == opts.max_iter:
            break
        dz = linear_solve(A, -r)
        if not np.all(np.isfinite(dz)):
            break
        norm0 = np.linalg.norm(r)
        alpha, best = 1.0, None
        for _ in range(opts.max_backtrack + 1):
            zt = z + alpha * dz
            rt, At = F(zt)
            nt = np.linalg.norm(rt)
            if best is None or nt < best[0]:
                best = (nt, zt, rt, At)
            if nt <= (1.0 - 1e-4 * alpha) * norm0:
                break
            alpha *= 0.5
        _, z, r, A = best
        res = float(np.max(np.abs(r)))
    raise ConvergenceError(
        f"{what} did not converge at lam = {lam_of(z):.9g} after {opts.max_iter} iterations: "
        f"last scaled residual max|R|/r_scale = {res:.3e} (tol {opts.tol:.1e})",
        iterations=opts.max_iter, residual=res, lam=lam_of(z))


def solve_newton(fun: Callable, x0: np.ndarray, lam: float, *, x_scale, r_scale: float,
                 options: NewtonOptions = NewtonOptions(), select: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Solve R(x, lam) = 0 at fixed lam.  Returns (x, iterations); raises ConvergenceError.
    ``select``: the coefficients of x solved (Adaptive.unknowns; None: all), the others zero."""
    space = _Space(np.broadcast_to(np.asarray(x_scale, float), np.shape(x0)).copy(), select)
    g = _scaled(fun, space, 1.0, r_scale)

    def F(y):
        R, J, _ = g(y, lam)
        return R, J

    y, it, _ = _damped_newton(F, space.sub(x0), options, "Newton", lambda z: lam)
    return space.full(y), it


def solve_adaptive(fun: Callable, x0: np.ndarray, lam: float, *, adapt: "Adaptive | None", x_scale, r_scale: float,
                   options: NewtonOptions = NewtonOptions()) -> tuple[np.ndarray, int]:
    """solve_newton in the unknowns of an adaptive problem, solved again each time its
    ``after_converge`` changes it (the penalty ROM's active set grows), as the continuation's start
    point is.  Returns (x, iterations); raises ContinuationError if it keeps changing."""
    select = None if adapt is None else adapt.unknowns()
    x, it = solve_newton(fun, x0, lam, x_scale=x_scale, r_scale=r_scale, options=options, select=select)
    for _ in range(adapt.max_redo if adapt is not None else 1):
        if adapt is None or not adapt.after_converge(x, lam):
            return x, it
        x, more = solve_newton(fun, x, lam, x_scale=x_scale, r_scale=r_scale, options=options,
                               select=adapt.unknowns())
        it += more
    raise ContinuationError(f"the problem kept changing at lam = {lam:.9g} ({adapt.max_redo} solves)")


def correct(fun: Callable, x_p: np.ndarray, lam_p: float, direction: tuple[np.ndarray, float], *, x_scale,
            lam_scale: float, r_scale: float, options: NewtonOptions = NewtonOptions(),
            select: np.ndarray | None = None, start: tuple[np.ndarray, float] | None = None):
    """Solve R(x, lam) = 0 on the hyperplane through (x_p, lam_p) normal to ``direction`` = (dx, dlam)
    (in the scaled variables of the continuation), as the corrector of a step does.
    ``select``: the coefficients of x solved (Adaptive.unknowns; None: all), the others zero.
    ``start``: Newton's first iterate (x, lam), if not (x_p, lam_p).

    Returns (x, lam, iterations, achieved max|R|/r_scale); raises ConvergenceError.  This meets
    the branch where it crosses the hyperplane, whether it is a graph over lam there or folds.
    """
    space = _Space(np.broadcast_to(np.asarray(x_scale, float), np.shape(x_p)).copy(), select)
    g = _scaled(fun, space, lam_scale, r_scale)
    t = np.append(space.sub(np.asarray(direction[0], float)), direction[1] / lam_scale)
    t = t / np.linalg.norm(t)
    z0 = None if start is None else np.append(space.sub(np.asarray(start[0], float)), start[1] / lam_scale)
    y, mu, it, res = _corrector(g, space.sub(x_p), lam_p / lam_scale, t, options, lam_scale, z0)
    return space.full(y), mu * lam_scale, it, res


def hyperplane_derivative(fun: Callable, x: np.ndarray, lam: float, direction: tuple[np.ndarray, float], *,
                          x_scale, lam_scale: float, select: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """(dx/dt, dlam/dt) of the point that ``correct`` finds on the hyperplane through
    (x_p, lam_p) + t (dx, dlam), normal to ``direction`` = (dx, dlam), at its solution (x, lam):
    the branch's tangent there, scaled so that its projection on the (scaled) direction is the
    direction's length.  One Jacobian and one solve of the bordered system [[J, dR/dlam], [d^T]];
    on a nonsmooth branch, the derivative of the smooth piece through (x, lam)."""
    space = _Space(np.broadcast_to(np.asarray(x_scale, float), np.shape(x)).copy(), select)
    d = np.append(space.sub(np.asarray(direction[0], float)), direction[1] / lam_scale)
    # at (x, lam) as given: a problem that keeps its last evaluation has the corrector's last one
    _, J, dl = fun(x, lam)
    J, dl = _scaled_jacobian(J, dl, space, lam_scale, 1.0)
    w = linear_solve(bordered(J, dl, d), np.append(np.zeros(J.shape[0]), d @ d))
    return space.full(w[:-1]), float(w[-1] * lam_scale)


RETRACE = "the step goes back along the branch"  # the start of a step's failure by the retrace rule


def _retraced(points: list, x_scale: np.ndarray, lam_scale: float, z_last: np.ndarray, z_new: np.ndarray,
              tol: float) -> int | None:
    """The index j of the first segment (points j, j+1) of the branch traced so far that the step from
    z_last to z_new walks back along: z_new lies within ``tol`` times the step's length of it, and the
    step and the segment are more than 120 deg apart.  None if there is none.

    z = (x / x_scale, lam / lam_scale) over every coefficient, solved now or not (an adaptive problem's
    unknowns change along the branch, its coefficients do not).  A branch never comes back onto
    itself: a smooth fold's two legs part at the rate they are walked, and a corner's (a fold on a
    kink, turning by at most 180 - max_reversal_deg) at half that rate or more (a sharp corner's, the
    last resort, at sin(180 deg - turn): 0.21 at 168 deg), so a tolerance of a tenth of the step tells
    them from a retrace, whose points lie on the old polyline to its chords'
    error (1e-6 to 1e-5 of the scales against steps of 1e-4 to 1e-3 on the 3D lap joint)."""
    n = len(points)
    step = z_new - z_last
    length = float(np.linalg.norm(step))
    if n < 2 or length == 0.0:
        return None
    eps = tol * length
    mu = np.fromiter((p.lam for p in points), float, n) / lam_scale
    lo, hi = np.minimum(mu[:-1], mu[1:]) - eps, np.maximum(mu[:-1], mu[1:]) + eps
    cand = np.flatnonzero((lo <= z_new[-1]) & (z_new[-1] <= hi))
    if cand.size == 0:
        return None
    P0 = np.array([np.append(points[i].x / x_scale, mu[i]) for i in cand])
    seg = np.array([np.append(points[i + 1].x / x_scale, mu[i + 1]) for i in cand]) - P0
    L2 = np.maximum(np.einsum("ij,ij->i", seg, seg), 1e-300)
    t = np.clip(np.einsum("ij,ij->i", z_new - P0, seg) / L2, 0.0, 1.0)
    dist = np.linalg.norm(P0 + t[:, None] * seg - z_new, axis=1)
    cos = (seg @ step) / (np.sqrt(L2) * length)
    hit = np.flatnonzero((dist <= eps) & (cos < -0.5))
    return int(cand[hit[0]]) if hit.size else None


@dataclass
class ContinuationPoint:
    x: np.ndarray
    lam: float
    iterations: int
    ds: float
    extra: object = None
    residual: float = 0.0  # achieved max|R|/r_scale
    ds_next: float = 0.0  # the step the continuation takes from this point (to resume it exactly)


def _corrector(g, y_p, mu_p, t, opts: NewtonOptions, lam_scale: float = 1.0, z0: np.ndarray | None = None):
    """Newton on [R(y, mu); t.(z - z_p)] = 0 from z0 (None: z_p).  Returns (y, mu, iterations,
    achieved max|r|) or raises."""
    z_p = np.append(y_p, mu_p)

    def F(z):
        R, J, dl = g(z[:-1], z[-1])
        return np.append(R, t @ (z - z_p)), bordered(J, dl, t)

    z, it, res = _damped_newton(F, z_p.copy() if z0 is None else z0, opts, "corrector", lambda z: z[-1] * lam_scale)
    return z[:-1], z[-1], it, res


def _parity(perm) -> int:
    """+1 or -1: the sign of a permutation (given as an index array), by its cycles."""
    perm = np.asarray(perm)
    seen = np.zeros(perm.size, bool)
    sign = 1
    for i in range(perm.size):
        if not seen[i]:
            j, length = i, 0
            while not seen[j]:
                seen[j] = True
                j = perm[j]
                length += 1
            sign *= -1 if length % 2 == 0 else 1
    return sign


def _solve_with_sign(A, b):
    """x = A^-1 b and the sign of det A, from the same LU factors."""
    if sp.issparse(A):
        lu = sparse_lu(A)
        d = lu.U.diagonal()
        return lu.solve(b), int(np.prod(np.sign(d))) * _parity(lu.perm_r) * _parity(lu.perm_c)
    lu, piv = sla.lu_factor(A)
    swaps = np.count_nonzero(piv != np.arange(piv.size))
    return sla.lu_solve((lu, piv), b), int(np.prod(np.sign(np.diag(lu)))) * (-1) ** swaps


def _tangent(J, dl, t_prev):
    """The unit tangent (oriented along t_prev) and the sign of det [[J, dl], [t_prev^T]]: the
    orientation of the branch, constant along it between bifurcation points, so a corrector that
    lands on another branch of the same shape shows as a change of sign."""
    t, sign = _solve_with_sign(bordered(J, dl, t_prev), np.append(np.zeros(J.shape[0]), 1.0))
    return t / np.linalg.norm(t), sign


def continue_branch(fun: Callable, x0: np.ndarray, lam0: float, lam_end: float, *, x_scale, lam_scale: float,
                    r_scale: float, options: ContinuationOptions = ContinuationOptions(),
                    callback: Callable[[ContinuationPoint], None] | None = None,
                    extra: Callable[[np.ndarray, float], object] | None = None,
                    adapt: Adaptive | None = None, stats: dict | None = None,
                    resume: tuple[np.ndarray, float] | None = None,
                    traced: list[ContinuationPoint] = ()) -> list[ContinuationPoint]:
    """Follow R(x, lam) = 0 from (x0, lam0) until lam passes lam_end (either direction).

    fun(x, lam) -> (R, dR/dx, dR/dlam).  x0 is an initial guess at lam0 (refined by Newton).
    ``extra(x, lam)`` is stored with each point; ``callback(point)`` is called per accepted point.
    ``adapt``: hooks of a problem that changes along the branch (see Adaptive).
    ``stats``: a dict filled (also when it stops) with the counts of refused steps, corners
    passed and steps redone because the problem changed.
    ``resume``: (direction, ds) to continue a branch that stopped at (x0, lam0): the direction
    (dx, dlam) it was heading in there (the secant of its last step will do: it orients the
    tangent) and the step it would have taken (ContinuationPoint.ds_next), so that the branch goes
    on as if it had not stopped.  ``traced``: the points of that branch before (x0, lam0), which
    the retrace rule (ContinuationOptions.retrace_tol) sees as part of the branch.
    """
    opts = options
    x_scale = np.broadcast_to(np.asarray(x_scale, float), np.shape(x0)).copy()

    def unknowns():
        return None if adapt is None else adapt.unknowns()

    x, it0 = solve_adaptive(fun, x0, lam0, adapt=adapt, x_scale=x_scale, r_scale=r_scale, options=opts.newton)
    # the unknowns solved now; every step works in them (scaled), every point is kept in x
    space = _Space(x_scale, unknowns())
    g_space = _scaled(fun, space, lam_scale, r_scale)

    def g_plain(y_, mu_):
        return g_space(y_, mu_)

    def rebase(y_old, t_old):
        """The problem changed (Adaptive): its unknowns now, and the last point and the tangent
        carried into them (a coefficient that joins starts at zero, where it was held: the last
        point is still a solution; one that leaves was zeroed by the problem)."""
        nonlocal space, g_space
        old, space = space, _Space(x_scale, unknowns())
        g_space = _scaled(fun, space, lam_scale, r_scale)
        if space.select.size == old.select.size and np.array_equal(space.select, old.select):
            return y_old, t_old
        t_new = np.append(space.carry(t_old[:-1], old), t_old[-1])
        return space.carry(y_old, old), t_new / np.linalg.norm(t_new)

    g = g_plain
    t_start = time.monotonic()
    y, mu = space.sub(x), lam0 / lam_scale
    mu_end = lam_end / lam_scale
    direction = np.sign(mu_end - mu)
    if direction == 0:
        raise ValueError("lam_end equals lam0: nothing to continue")
    R, J, dl = g(y, mu)
    points = [ContinuationPoint(x, lam0, it0, 0.0, extra(x, lam0) if extra else None,
                                residual=float(np.max(np.abs(R))))]
    if callback:
        callback(points[-1])
    if resume is None:
        e_lam = np.zeros(y.size + 1)
        e_lam[-1] = direction
        t, _ = _tangent(J, dl, e_lam)
        if t[-1] * direction < 0:
            t = -t
        ds = opts.ds0
    else:
        heading = np.append(space.sub(np.asarray(resume[0][0], float)), resume[0][1] / lam_scale)
        t, _ = _tangent(J, dl, heading / np.linalg.norm(heading))
        ds = float(np.clip(resume[1], opts.ds_min, opts.ds_max))
    t, orient = _tangent(J, dl, t)
    points[-1].ds_next = ds
    cos_max = np.cos(np.deg2rad(opts.max_turn_deg))
    cos_rev = -np.cos(np.deg2rad(opts.max_reversal_deg))
    redo = 0
    counts = stats if stats is not None else {}
    counts.update(refused_steps=0, corners_passed=0, sharp_corners=0, kinks_crossed=0, redone_steps=0,
                  retraces_refused=0, leaps=0)

    def stop(why: str):
        return ContinuationError(f"continuation stopped at lam = {mu * lam_scale:.9g} before reaching "
                                 f"{lam_end:.9g}, after {len(traced) + len(points)} points and "
                                 f"{counts['refused_steps']} refused steps: {why}", points=points)

    turned = []  # the tangent's turns (deg) of the steps refused for it at this point

    def attempt(d, ds, base=None):
        """One step of length ds along the unit direction d from ``base`` (default: the last point
        (y, mu)).  Returns (y_new, mu_new, iterations, residual, t_new, orient_new, changed, failure)."""
        z_p = (np.append(y, mu) if base is None else base) + ds * d
        # A root on a kink of the sampled law (a sample changing state) can stall Newton just
        # above kink_tol however short the step: accept it at a looser, recorded residual.
        nopts = replace(opts.newton, max_iter=min(opts.newton.max_iter, opts.corrector_max_iter))
        if ds <= opts.relax_ds:
            nopts = replace(nopts, kink_tol=max(opts.newton.kink_tol, opts.newton.relaxed_kink_tol))
        try:
            y_new, mu_new, it, res = _corrector(g, z_p[:-1], z_p[-1], d, nopts, lam_scale)
            jump = float(np.linalg.norm(np.append(y_new - y, mu_new - mu)))
            if jump > opts.max_jump * ds and ds > opts.turn_ds_floor:
                # the hyperplane met the branch far from the predictor: another part of it, refused
                # before the problem may adapt to it (an adaptive problem changed by a point it then
                # refuses need not have the last point as a solution: the penalty ROM's active set
                # grown at such a point left the 3D lap joint at 5 N unable to step on, issue 14)
                return (None, None, it, res, None, None, False,
                        f"corrector landed {jump / ds:.1f} step lengths away")
            if adapt is not None and (why := retraces(y_new, mu_new)) is not None:
                # likewise a point back on the branch traced: the problem must not adapt to it (the
                # penalty ROM's active set grown at such a point turned every later step back along
                # the branch, at 1732.95 rad/s on the 9-pair lap joint under another BLAS kernel)
                return None, None, it, res, None, None, False, why
            changed = adapt is not None and adapt.after_converge(space.full(y_new), mu_new * lam_scale)
            if changed:
                # the problem changed: the tangent at the last accepted point, then the same step again
                log.debug("step redone at lam=%.6g: the problem changed", mu_new * lam_scale)
                return y_new, mu_new, it, res, None, None, True, None
            R, J, dl = g(y_new, mu_new)
            t_new, orient_new = _tangent(J, dl, d)
        except (ConvergenceError, np.linalg.LinAlgError, RuntimeError) as exc:
            return None, None, 0, np.inf, None, None, False, str(exc)
        sec = np.append(y_new, mu_new) - (np.append(y, mu) if base is None else base)
        sec = sec / max(np.linalg.norm(sec), 1e-300)
        if opts.secant_on_kinks and res > opts.newton.tol:
            # the corrector stalled on a kink: the root lies on the boundary between pieces of the
            # law, and each piece's tangent points off it; along such a ridge the secant is the
            # branch's direction (and the orientation is that of the piece it came from)
            t_new, orient_new = sec, orient
        # A true corner of the branch (slip onset on a sampled period is one) turns the
        # tangent however short the step; only steps longer than turn_ds_floor are refused.
        failure = None
        cos_turn = float(t_new @ d)
        if orient_new != orient and ds > opts.turn_ds_floor:
            # the corrector met another branch (or passed a bifurcation point): never silently
            failure = "the orientation of the branch (sign of the bordered Jacobian) changed"
        elif cos_turn < cos_max and ds > opts.turn_ds_floor and not (
                base is None and opts.secant_on_kinks and len(turned) >= 2
                and np.rad2deg(np.arccos(np.clip(cos_turn, -1, 1))) >= 0.8 * max(turned[-2:])):
            # (a turn that stays as large over two halvings of the step is a corner of the branch at
            # a kink, not curvature, which would shrink with the step: it is then accepted)
            turned.append(float(np.rad2deg(np.arccos(np.clip(cos_turn, -1, 1)))))
            failure = f"tangent turned by {turned[-1]:.1f} deg"
        elif opts.max_rel_change is not None and (rel := np.linalg.norm(y_new - y) / max(
                np.linalg.norm(y), np.linalg.norm(y_new), 1e-300)) > opts.max_rel_change:
            # however short the step: x flipped sign (a branch through an unbounded resonance,
            # or another branch met by the hyperplane) -- never accepted silently
            failure = f"the solution changed by {rel:.2f} times its size in one step"
        elif cos_turn < cos_rev:
            # however short the step: a tangent that reverses retraces the branch backwards
            failure = f"tangent reversed ({np.rad2deg(np.arccos(np.clip(cos_turn, -1, 1))):.1f} deg)"
        else:
            failure = retraces(y_new, mu_new)
        return y_new, mu_new, it, res, t_new, orient_new, False, failure

    def retraces(y_new, mu_new):
        """Why the point (y_new, mu_new) is refused as a step back along the branch traced so far
        (however short the step), or None."""
        if opts.retrace_tol is None:
            return None
        z_new = np.append(space.full(y_new) / x_scale, mu_new)
        branch = list(traced) + points
        j = _retraced(branch, x_scale, lam_scale, np.append(points[-1].x / x_scale, points[-1].lam / lam_scale),
                      z_new, opts.retrace_tol)
        if j is None:
            return None
        counts["retraces_refused"] += 1
        return f"{RETRACE} traced at lam = {branch[j].lam:.9g} (points {j}-{j + 1} of this branch)"

    def sign_at(z, d):
        """The orientation at z (0 where the bordered matrix is singular) and the Jacobian there."""
        R, J, dl = g(z[:-1], z[-1])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return _solve_with_sign(bordered(J, dl, d), np.append(np.zeros(J.shape[0]), 1.0))[1], J, dl

    def beyond(d, ds):
        """A fold on a kink within ds along d: the orientation of the branch flips between the last
        point and the predictor, and the hyperplane normal to d never meets the branch beyond (it
        turns back).  The first flip is located by bisection to ds / 2^corner_bisections, and
        (base, t2) returned: the point just past it and the tangent of the piece there, oriented to
        keep the orientation of the branch.  None when the orientation does not flip.  (t2 may turn
        back by more than 180 - max_reversal_deg: the caller decides whether to take such a corner.)"""
        z0 = np.append(y, mu)
        try:
            o, J, dl = sign_at(z0 + ds * d, d)
            if o == orient:
                return None
            lo, hi = 0.0, ds
            for _ in range(opts.corner_bisections):
                mid = 0.5 * (lo + hi)
                o_mid, J_mid, dl_mid = sign_at(z0 + mid * d, d)
                if o_mid == orient:
                    lo = mid
                else:
                    hi, J, dl = mid, J_mid, dl_mid
        except (np.linalg.LinAlgError, RuntimeError, ValueError):
            return None
        t2 = None
        # bordered by d, the null vector of [J, dl] is singular where the branch turns by 90 deg:
        # then by a fixed generic vector; the orientation is then read with t2 itself
        for b in (d, np.random.default_rng(0).standard_normal(d.size)):
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    t2, _ = _tangent(J, dl, b / np.linalg.norm(b))
                    t2, o2 = _tangent(J, dl, t2)
            except (np.linalg.LinAlgError, RuntimeError, ValueError):
                continue
            if np.all(np.isfinite(t2)):
                break
            t2 = None
        if t2 is None:
            return None
        if o2 != orient:
            t2 = -t2
        return z0 + hi * d, t2

    def across(d, ds, march=False):
        """A kink that the corrector on the hyperplane normal to d cannot cross, on a branch that goes
        on in lam: one step at fixed lam.

        At the onset of slip or of separation of a pair whose load only just reaches its limit (a
        grazing switch), the slider's motion is continuous but not differentiable in the gaps (its
        slip grows like max(0, overshoot)), for the sampled law and in continuous time alike
        (docs/theory.md, Known limits).  The Jacobian then differs across the kink, the bordered
        determinant may change sign, and Newton on the hyperplane cycles between the pieces for
        every step length, while Newton at fixed lam converges on the far side.  The predictor
        z + ds d is corrected at its lam; the point is accepted within max_jump step lengths of the
        last point, its tangent oriented along the secant (the orientation is read there again).
        Returns attempt()'s tuple, or None where d does not advance lam.

        ``march``: a step of ds in lam from the last point (d = the unit vector of lam), for a branch
        whose own tangent leads back along it (the retrace rule refused every step): the point is
        accepted within max_jump times the distance the tangent there predicts for that change of
        lam (ds / |t_lam|, with |t_lam| taken as at least 0.01), unless it lies on the branch traced,
        and whichever way the piece beyond points (the steps after it are checked as any other).
        Measured on the 3D lap joint: 12.7 and 4.8 step lengths, where |t_lam| is about 0.08."""
        if d[-1] * direction <= 0:
            return None
        z0 = np.append(y, mu)
        z_p = z0 + ds * d
        nopts = replace(opts.newton, max_iter=min(opts.newton.max_iter, opts.corrector_max_iter))

        def F(y_):
            R, J, _ = g(y_, z_p[-1])
            return R, J

        try:
            y_new, it, res = _damped_newton(F, z_p[:-1].copy(), nopts, "corrector at fixed lam",
                                            lambda _: z_p[-1] * lam_scale)
            mu_new = z_p[-1]
            sec = np.append(y_new, mu_new) - z0
            jump = float(np.linalg.norm(sec))
            if jump > opts.max_jump * ds * (1.0 / max(abs(t[-1]), 1e-2) if march else 1.0):
                return None  # (before the problem may adapt to the point, as in attempt())
            changed = adapt is not None and adapt.after_converge(space.full(y_new), mu_new * lam_scale)
            if changed:
                return y_new, mu_new, it, res, None, None, True, None
            R, J, dl = g(y_new, mu_new)
            t_new, orient_new = _tangent(J, dl, sec / max(jump, 1e-300))
        except (ConvergenceError, np.linalg.LinAlgError, RuntimeError):
            return None
        if t_new[-1] * direction <= 0 and not march:  # the piece beyond turns back: a fold on the kink
            return None
        if retraces(y_new, mu_new) is not None:
            return None
        return y_new, mu_new, it, res, t_new, orient_new, False, None

    def g(y_, mu_):  # (the steps' closures below see this binding)
        # the time limit also holds inside a step (one corrector of the exact condensation on the
        # 3D lap joint took 300 s): past it, the evaluation stops the branch
        if opts.time_limit is not None and time.monotonic() - t_start > opts.time_limit:
            raise _OutOfTime
        return g_plain(y_, mu_)

    def sharp_corner(ds):
        """A sharp corner's step (see its use): (points taken back, its length, its direction,
        attempt()'s tuple) with the branch set back to its base, or None with nothing changed."""
        nonlocal y, mu, t, orient
        bases = [0]
        # (the last point converged to the tolerance, at most max_relaxed_back behind, with one before it)
        back = next((b for b in range(1, min(opts.max_relaxed_back, len(points) - 2) + 1)
                     if points[-1 - b].residual <= opts.newton.tol), None)
        if points[-1].residual > opts.newton.tol and back is not None:
            bases.append(back)
        here = (y, mu, t, orient)
        for back in bases:
            if back:
                k = len(points) - 1 - back
                if adapt is not None:
                    adapt.restore(adapt.state_of(points[k].x))
                    rebase(y, t)
                y, mu = space.sub(points[k].x), points[k].lam / lam_scale
                sec = np.append(y - space.sub(points[k - 1].x), mu - points[k - 1].lam / lam_scale)
                R, J, dl = g(y, mu)
                t, _ = _tangent(J, dl, sec / max(np.linalg.norm(sec), 1e-300))
                t, orient = _tangent(J, dl, t)
            for trial in (ds, opts.corner_ds):
                found = beyond(t, trial)
                if found is None or float(found[1] @ t) >= cos_rev:
                    continue
                out = attempt(found[1], trial, found[0])
                if out[7] is None:
                    log.debug("sharp corner passed at lam=%.6g (%d points back): the branch turns by %.1f deg",
                              mu * lam_scale, back, np.rad2deg(np.arccos(np.clip(found[1] @ t, -1, 1))))
                    return back, trial, found[1], out
            if back:  # (set forth again)
                if adapt is not None:
                    adapt.restore(adapt.state_of(points[-1].x))
                    rebase(y, t)
                y, mu, t, orient = here
        return None

    def adapted(y_new, mu_new, it, res, nopts):
        """A point found at fixed mu_new, solved again at that mu in the problem as it adapts to it
        (the last point and its tangent carried along, as a redone step does), or (None, 0, inf)
        where it fails or lands back on the branch traced (the problem is then put back)."""
        nonlocal y, t, orient, space, g_space
        if adapt is None:
            return y_new, it, res
        here = (space, t, orient)
        for _ in range(adapt.max_redo):
            if not adapt.after_converge(space.full(y_new), mu_new * lam_scale):
                return y_new, it, res
            old = space
            y, t = rebase(y, t)
            y_new = space.carry(y_new, old)

            def F(y_):
                R, J, _ = g(y_, mu_new)
                return R, J

            try:
                y_new, more, res = _damped_newton(F, y_new, nopts, "corrector at fixed lam", lambda _: mu_new * lam_scale)
            except (ConvergenceError, np.linalg.LinAlgError, RuntimeError):
                break
            it += more
            if retraces(y_new, mu_new) is not None:
                break
        if space is not here[0]:
            adapt.restore(adapt.state_of(points[-1].x))
            space = _Space(x_scale, unknowns())
            g_space = _scaled(fun, space, lam_scale, r_scale)
            y = space.sub(points[-1].x)
            t = np.append(space.carry(here[1][:-1], here[0]), here[1][-1])
            t = t / np.linalg.norm(t)
        orient = here[2]
        return None, 0, np.inf

    def leap():
        """The last resort where the branch would stop (every step refused down to ds_min): a point of
        the branch beyond a kink that no step on a hyperplane reaches, found by Newton at fixed lam
        = mu + corner_ds 2^k towards lam_end (a branch that folds back beyond is then followed back
        by the steps from there; a leap the other way would take a branch refused as it came, for
        going back along its own points, onto those points' far side).

        Where a fold lies on a kink whose piece beyond turns back by more than 90 deg, the hyperplane
        normal to the tangent meets no solution ahead at any step length, and whether the orientation
        flips at the predictor (which beyond() needs) depends on which side of the kink's surface an
        off-branch predictor falls: a matter of round-off (issue 52: the 9-pair lap joint at 1470.68
        rad/s stalled under one OpenBLAS kernel and passed under another).  A solution at a fixed lam
        near the last point is either the branch traced (refused by the retrace rule) or its
        continuation: the first found (the smallest change of lam) is taken, within max_jump times the
        distance that a branch with |t_lam| >= 0.01 covers for that change of lam; an adaptive
        problem adapts to it first (adapted()).  Returns attempt()'s tuple (never a changed problem) or None."""
        nopts = replace(opts.newton, max_iter=min(opts.newton.max_iter, opts.corrector_max_iter))
        for k in range(opts.leap_tries):
            mu_new = mu + direction * opts.corner_ds * 2.0 ** k

            def F(y_):
                R, J, _ = g(y_, mu_new)
                return R, J

            try:
                y_new, it, res = _damped_newton(F, y.copy(), nopts, "corrector at fixed lam", lambda _: mu_new * lam_scale)
            except (ConvergenceError, np.linalg.LinAlgError, RuntimeError):
                continue
            dmu = abs(mu_new - mu)
            jump = float(np.linalg.norm(np.append(y_new - y, dmu)))
            if not 1e-3 * dmu < jump <= opts.max_jump * dmu / 1e-2 or retraces(y_new, mu_new) is not None:
                continue
            try:
                y_new, it, res = adapted(y_new, mu_new, it, res, nopts)
                if y_new is None:
                    continue
                # (y in the problem as it is now)
                sec = np.append(y_new, mu_new) - np.append(y, mu)
                sec = sec / max(np.linalg.norm(sec), 1e-300)
                R, J, dl = g(y_new, mu_new)
                t_new, _ = _tangent(J, dl, sec)
                t_new, orient_new = _tangent(J, dl, t_new)
            except (np.linalg.LinAlgError, RuntimeError):
                continue
            log.debug("leap at lam=%.9g to lam=%.9g (%.2g step lengths of corner_ds)", mu * lam_scale,
                      mu_new * lam_scale, jump / opts.corner_ds)
            return y_new, mu_new, it, res, t_new, orient_new, False, None  # (attempt()'s tuple)
        return None

    try:
        while (mu - mu_end) * direction < 0:
            if len(points) >= opts.max_points:
                raise stop(f"max_points = {opts.max_points} reached; the last solution is {np.max(np.abs(y)):.3g} "
                           f"times its scale" + ("" if np.max(np.abs(y)) < 100 else " (growing without bound: an "
                                                 "undamped resonance that friction cannot hold?)"))
            if opts.time_limit is not None and time.monotonic() - t_start > opts.time_limit:
                raise stop(f"the time limit of {opts.time_limit:g} s was reached (time_limit)")
            if adapt is not None and redo == 0 and adapt.before_step(space.full(y), mu * lam_scale):
                y, t = rebase(y, t)
                R, J, dl = g(y, mu)
                t, _ = _tangent(J, dl, t)
                t, orient = _tangent(J, dl, t)  # (the orientation of the system it is now)
            d = t
            y_new, mu_new, it, res, t_new, orient_new, changed, failure = attempt(d, ds)
            if failure is not None and opts.corner_steps and ds <= opts.corner_ds:
                # a fold on a corner of the piecewise-smooth branch (a kink of the sampled law) within
                # the step: step along the branch beyond it instead of shrinking towards it
                found = beyond(t, ds)
                if found is not None and float(found[1] @ t) < cos_rev:
                    found = None  # (a sharp corner: only where the branch would stop otherwise, below)
                if found is not None:
                    base, d2 = found
                    out = attempt(d2, ds, base)
                    if out[7] is None:
                        log.debug("corner passed at lam=%.6g: the branch turns by %.1f deg (%s)", mu * lam_scale,
                                  np.rad2deg(np.arccos(np.clip(d2 @ t, -1, 1))), failure)
                        d = d2
                        y_new, mu_new, it, res, t_new, orient_new, changed, failure = out
                        counts["corners_passed"] += not changed
                    else:
                        log.debug("corner step at lam=%.6g (turn %.1f deg) refused: %s", mu * lam_scale,
                                  np.rad2deg(np.arccos(np.clip(d2 @ t, -1, 1))), out[7])
            if failure is not None and opts.kink_lam_steps and ds <= opts.corner_ds:
                out = across(t, ds)
                if out is None and failure.startswith(RETRACE):
                    # the branch's own tangent leads back along it: a step at fixed lam from the last
                    # point towards lam_end, onto the branch beyond the corner (if there is one)
                    e_lam = np.zeros(t.size)
                    e_lam[-1] = direction
                    out = across(e_lam, ds, march=True)
                if out is not None:
                    log.debug("kink crossed at fixed lam=%.9g (%s)", out[1] * lam_scale, failure)
                    d = t
                    y_new, mu_new, it, res, t_new, orient_new, changed, failure = out
                    counts["kinks_crossed"] += not changed
            if (failure is not None and 0.5 * ds < opts.ds_min and opts.corner_steps
                    and opts.retrace_tol is not None):
                # the last resort where the branch would stop: a fold on a kink whose piece beyond turns
                # back by more than the reversal guard allows (a sharp corner: 168 deg on the 3D lap
                # joint at N = 128, issue 14), probed over this step and over corner_ds, from the last
                # point and, if points accepted only at the relaxed kink tolerance follow it, from the
                # last point converged to the tolerance (those points crawl along the kink past the
                # fold, off the branch: measured there).  The piece beyond is the branch going on if
                # the retrace rule (which attempt() applies) tells it from the way it came.  Nothing
                # changes on a branch that goes on without it.
                out = sharp_corner(ds)
                if out is not None:
                    back, trial, d, out = out
                    del points[len(points) - back:]
                    ds = trial
                    y_new, mu_new, it, res, t_new, orient_new, changed, failure = out
                    counts["corners_passed"] += not changed
                    counts["sharp_corners"] += not changed
            if failure is None and changed:
                y, t = rebase(y, t)
                R, J, dl = g(y, mu)
                t, _ = _tangent(J, dl, t)
                t, orient = _tangent(J, dl, t)
                redo += 1
                counts["redone_steps"] += 1
                if redo > Adaptive.max_redo:
                    raise stop(f"the problem kept changing ({redo - 1} redone steps)")
                continue
            if failure is not None:
                counts["refused_steps"] += 1
                ds *= 0.5
                log.debug("step rejected at lam=%.6g (%s); ds -> %.3g", mu * lam_scale, failure, ds)
                if ds < opts.ds_min:
                    # (like a sharp corner, only where the retrace rule can tell the way back)
                    out = (leap() if opts.corner_steps and opts.retrace_tol is not None and opts.leap_tries
                           and counts["leaps"] < opts.max_leaps else None)
                    if out is None:
                        raise stop(f"the step fell below ds_min = {opts.ds_min:.1e}; last failure: {failure}")
                    counts["leaps"] += 1
                    y_new, mu_new, it, res, t_new, orient_new, changed, failure = out
                    d, ds = t_new, opts.corner_ds
                else:
                    continue
            if opts.lam_bounds is not None and not opts.lam_bounds[0] <= mu_new * lam_scale <= opts.lam_bounds[1]:
                raise stop(f"the branch left [{opts.lam_bounds[0]:.6g}, {opts.lam_bounds[1]:.6g}] at lam = "
                           f"{mu_new * lam_scale:.9g}: it turned back at a fold and does not come back to lam_end (lam_bounds)")
            redo = 0
            turned.clear()
            y, mu, t, orient = y_new, mu_new, t_new, orient_new
            x = space.full(y)
            points.append(ContinuationPoint(x, mu * lam_scale, it, ds, extra(x, mu * lam_scale) if extra else None,
                                            residual=res))
            log.debug("point %d at lam=%.9g: ds %.3g, %d iterations, |y| %.6g", len(points) - 1, mu * lam_scale, ds,
                      it, float(np.linalg.norm(y)))
            if callback:
                callback(points[-1])
            # Step control: grow after easy corrections, but keep the tangent turning at most
            # ``target_turn_deg`` per step so that peaks and folds are resolved, not stepped over
            # (measured from the direction stepped along, so a corner passed does not count).
            # A turn is not shrunk below turn_ds_floor: at that length a turn beyond target_turn_deg
            # is a kink, not curvature (a smooth branch would need a radius under 7 turn_ds_floor),
            # and shrinking for it only followed the tangent's chatter between the pieces of
            # neighbouring kinks, down to ds_min (issue 14: the lap joint's separated loop).
            turn = float(np.rad2deg(np.arccos(np.clip(d @ t, -1.0, 1.0))))
            if turn > opts.target_turn_deg and ds > opts.turn_ds_floor:
                ds = max(ds * max(opts.target_turn_deg / turn, 0.25), opts.turn_ds_floor)
            elif it <= opts.target_iter or (opts.secant_on_kinks and res > opts.newton.tol):
                # (a corrector stalled on a kink takes stall_iter iterations whatever the step)
                ds = min(ds * opts.grow, opts.ds_max)
            points[-1].ds_next = ds
    except _OutOfTime:
        raise stop(f"the time limit of {opts.time_limit:g} s was reached (time_limit)") from None
    except KeyboardInterrupt as exc:
        # Ctrl-C (or SIGTERM, SIGHUP, which jointfem's command line raises as it): the points converged
        # so far are kept, as for any other stop
        raise ContinuationError(f"continuation interrupted ({str(exc) or 'Ctrl-C'}) at lam = {points[-1].lam:.9g} "
                                f"after {len(traced) + len(points)} points", points=points, interrupted=True) from None
    log.debug("branch done: %d points, %s", len(points), counts)
    return points
