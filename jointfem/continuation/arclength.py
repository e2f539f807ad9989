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


class ContinuationError(RuntimeError):
    """Continuation cannot go on (step at its minimum, or a non-finite value)."""


class Adaptive:
    """Hooks of a problem whose equations change along the branch (the penalty ROM's active set).

    ``before_step(x, lam)`` runs before each predictor at the last accepted point; it may change
    the problem and return a new x there (or None: unchanged).  ``after_converge(x, lam)`` runs
    on each converged corrector; True means the point broke a condition of the problem, which
    has been changed, and the step is redone from the last accepted point with the same length.
    """

    max_redo: int = 50

    def before_step(self, x, lam):  # pragma: no cover - interface
        return None

    def after_converge(self, x, lam) -> bool:  # pragma: no cover - interface
        return False

    def restore(self, state) -> None:  # pragma: no cover - interface
        """Put the problem back in a state it recorded at a converged point (for solves after the
        branch, e.g. locating a peak between recorded points)."""


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
    max_points: int = 5000
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
    newton: NewtonOptions = field(default_factory=NewtonOptions)


def _solve(A, b):
    if sp.issparse(A):
        return spla.splu(A.tocsc()).solve(b)
    return np.linalg.solve(A, b)


def _bordered(J, c, t):
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


def _scaled(fun, x_scale, lam_scale, r_scale):
    """Wrap fun(x, lam) -> (R, J, dR/dlam) into scaled variables."""
    Sx = sp.diags(x_scale) if np.ndim(x_scale) else None

    def g(y, mu):
        R, J, dl = fun(y * x_scale, mu * lam_scale)
        if J is not None:
            J = (J @ Sx) / r_scale if sp.issparse(J) and Sx is not None else J * x_scale / r_scale
            dl = dl * lam_scale / r_scale
        return R / r_scale, J, dl

    return g


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
        dz = _solve(A, -r)
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
                 options: NewtonOptions = NewtonOptions()) -> tuple[np.ndarray, int]:
    """Solve R(x, lam) = 0 at fixed lam.  Returns (x, iterations); raises ConvergenceError."""
    g = _scaled(fun, x_scale, 1.0, r_scale)

    def F(y):
        R, J, _ = g(y, lam)
        return R, J

    y, it, _ = _damped_newton(F, x0 / x_scale, options, "Newton", lambda z: lam)
    return y * x_scale, it


def correct(fun: Callable, x_p: np.ndarray, lam_p: float, direction: tuple[np.ndarray, float], *, x_scale,
            lam_scale: float, r_scale: float, options: NewtonOptions = NewtonOptions()):
    """Solve R(x, lam) = 0 on the hyperplane through (x_p, lam_p) normal to ``direction`` = (dx, dlam)
    (in the scaled variables of the continuation), as the corrector of a step does.

    Returns (x, lam, iterations, achieved max|R|/r_scale); raises ConvergenceError.  This meets
    the branch where it crosses the hyperplane, whether it is a graph over lam there or folds.
    """
    x_scale = np.broadcast_to(np.asarray(x_scale, float), np.shape(x_p))
    g = _scaled(fun, x_scale, lam_scale, r_scale)
    t = np.append(direction[0] / x_scale, direction[1] / lam_scale)
    t = t / np.linalg.norm(t)
    y, mu, it, res = _corrector(g, x_p / x_scale, lam_p / lam_scale, t, options, lam_scale)
    return y * x_scale, mu * lam_scale, it, res


@dataclass
class ContinuationPoint:
    x: np.ndarray
    lam: float
    iterations: int
    ds: float
    extra: object = None
    residual: float = 0.0  # achieved max|R|/r_scale


def _corrector(g, y_p, mu_p, t, opts: NewtonOptions, lam_scale: float = 1.0):
    """Newton on [R(y, mu); t.(z - z_p)] = 0.  Returns (y, mu, iterations, achieved max|r|) or raises."""
    z_p = np.append(y_p, mu_p)

    def F(z):
        R, J, dl = g(z[:-1], z[-1])
        return np.append(R, t @ (z - z_p)), _bordered(J, dl, t)

    z, it, res = _damped_newton(F, z_p.copy(), opts, "corrector", lambda z: z[-1] * lam_scale)
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
        lu = spla.splu(A.tocsc())
        d = lu.U.diagonal()
        return lu.solve(b), int(np.prod(np.sign(d))) * _parity(lu.perm_r) * _parity(lu.perm_c)
    lu, piv = sla.lu_factor(A)
    swaps = np.count_nonzero(piv != np.arange(piv.size))
    return sla.lu_solve((lu, piv), b), int(np.prod(np.sign(np.diag(lu)))) * (-1) ** swaps


def _tangent(J, dl, t_prev):
    """The unit tangent (oriented along t_prev) and the sign of det [[J, dl], [t_prev^T]]: the
    orientation of the branch, constant along it between bifurcation points, so a corrector that
    lands on another branch of the same shape shows as a change of sign."""
    t, sign = _solve_with_sign(_bordered(J, dl, t_prev), np.append(np.zeros(J.shape[0]), 1.0))
    return t / np.linalg.norm(t), sign


def continue_branch(fun: Callable, x0: np.ndarray, lam0: float, lam_end: float, *, x_scale, lam_scale: float,
                    r_scale: float, options: ContinuationOptions = ContinuationOptions(),
                    callback: Callable[[ContinuationPoint], None] | None = None,
                    extra: Callable[[np.ndarray, float], object] | None = None,
                    adapt: Adaptive | None = None) -> list[ContinuationPoint]:
    """Follow R(x, lam) = 0 from (x0, lam0) until lam passes lam_end (either direction).

    fun(x, lam) -> (R, dR/dx, dR/dlam).  x0 is an initial guess at lam0 (refined by Newton).
    ``extra(x, lam)`` is stored with each point; ``callback(point)`` is called per accepted point.
    ``adapt``: hooks of a problem that changes along the branch (see Adaptive).
    """
    opts = options
    x_scale = np.broadcast_to(np.asarray(x_scale, float), np.shape(x0)).copy()
    x, it0 = solve_newton(fun, x0, lam0, x_scale=x_scale, r_scale=r_scale, options=opts.newton)
    for _ in range(Adaptive.max_redo):
        if adapt is None or not adapt.after_converge(x, lam0):
            break
        x, it = solve_newton(fun, x, lam0, x_scale=x_scale, r_scale=r_scale, options=opts.newton)
        it0 += it
    else:
        raise ContinuationError(f"the problem kept changing at the start point lam = {lam0:.9g}")
    g = _scaled(fun, x_scale, lam_scale, r_scale)
    y, mu = x / x_scale, lam0 / lam_scale
    mu_end = lam_end / lam_scale
    direction = np.sign(mu_end - mu)
    if direction == 0:
        raise ValueError("lam_end equals lam0: nothing to continue")
    R, J, dl = g(y, mu)
    points = [ContinuationPoint(x, lam0, it0, 0.0, extra(x, lam0) if extra else None,
                                residual=float(np.max(np.abs(R))))]
    if callback:
        callback(points[-1])
    e_lam = np.zeros(y.size + 1)
    e_lam[-1] = direction
    t, _ = _tangent(J, dl, e_lam)
    if t[-1] * direction < 0:
        t = -t
    t, orient = _tangent(J, dl, t)
    ds = opts.ds0
    cos_max = np.cos(np.deg2rad(opts.max_turn_deg))
    redo = 0
    while (mu - mu_end) * direction < 0:
        if len(points) >= opts.max_points:
            raise ContinuationError(f"continuation stopped after {opts.max_points} points at "
                                    f"lam = {mu * lam_scale:.9g} before reaching {lam_end:.9g}; the last "
                                    f"solution is {np.max(np.abs(y)):.3g} times its scale"
                                    + ("" if np.max(np.abs(y)) < 100 else " (growing without bound: an undamped "
                                       "resonance that friction cannot hold?)"))
        if adapt is not None and redo == 0:
            x_new = adapt.before_step(y * x_scale, mu * lam_scale)
            if x_new is not None:
                y = x_new / x_scale
                R, J, dl = g(y, mu)
                t, orient = _tangent(J, dl, t)
        z_p = np.append(y, mu) + ds * t
        failure, changed = None, False
        try:
            # A root on a kink of the sampled law (a sample changing state) can stall Newton just
            # above kink_tol however short the step: accept it at a looser, recorded residual.
            nopts = opts.newton if ds > opts.relax_ds else replace(opts.newton, kink_tol=max(
                opts.newton.kink_tol, opts.newton.relaxed_kink_tol))
            y_new, mu_new, it, res = _corrector(g, z_p[:-1], z_p[-1], t, nopts, lam_scale)
            changed = adapt is not None and adapt.after_converge(y_new * x_scale, mu_new * lam_scale)
            if changed:
                # the problem changed: the tangent at the last accepted point, then the same step again
                R, J, dl = g(y, mu)
                t, orient = _tangent(J, dl, t)
                t_new, orient_new = t, orient
                log.debug("step redone at lam=%.6g: the problem changed", mu_new * lam_scale)
            else:
                R, J, dl = g(y_new, mu_new)
                t_new, orient_new = _tangent(J, dl, t)
            # A true corner of the branch (slip onset on a sampled period is one) turns the
            # tangent however short the step; only steps longer than turn_ds_floor are refused.
            jump = float(np.linalg.norm(np.append(y_new - y, mu_new - mu)))
            if not changed and jump > opts.max_jump * ds and ds > opts.turn_ds_floor:
                # the hyperplane met the branch far from the predictor: another part of it
                failure = f"corrector landed {jump / ds:.1f} step lengths away"
            elif not changed and orient_new != orient and ds > opts.turn_ds_floor:
                # the corrector met another branch (or passed a bifurcation point): never silently
                failure = "the orientation of the branch (sign of the bordered Jacobian) changed"
            elif float(t_new @ t) < cos_max and ds > opts.turn_ds_floor:
                failure = f"tangent turned by {np.rad2deg(np.arccos(np.clip(t_new @ t, -1, 1))):.1f} deg"
            elif not changed and opts.max_rel_change is not None and (rel := np.linalg.norm(y_new - y) / max(
                    np.linalg.norm(y), np.linalg.norm(y_new), 1e-300)) > opts.max_rel_change:
                # however short the step: x flipped sign (a branch through an unbounded resonance,
                # or another branch met by the hyperplane) -- never accepted silently
                failure = f"the solution changed by {rel:.2f} times its size in one step"
            elif float(t_new @ t) < -np.cos(np.deg2rad(opts.max_reversal_deg)):
                # however short the step: a tangent that reverses retraces the branch backwards
                failure = f"tangent reversed ({np.rad2deg(np.arccos(np.clip(t_new @ t, -1, 1))):.1f} deg)"
        except (ConvergenceError, np.linalg.LinAlgError, RuntimeError) as exc:
            failure = str(exc)
        if failure is None and changed:
            redo += 1
            if redo > Adaptive.max_redo:
                raise ContinuationError(f"the problem kept changing at lam = {mu * lam_scale:.9g} "
                                        f"after {redo - 1} redone steps")
            continue
        if failure is not None:
            ds *= 0.5
            log.debug("step rejected at lam=%.6g (%s); ds -> %.3g", mu * lam_scale, failure, ds)
            if ds < opts.ds_min:
                raise ContinuationError(
                    f"continuation step fell below ds_min = {opts.ds_min:.1e} at lam = {mu * lam_scale:.9g} "
                    f"after {len(points)} points; last failure: {failure}")
            continue
        if opts.lam_bounds is not None and not opts.lam_bounds[0] <= mu_new * lam_scale <= opts.lam_bounds[1]:
            raise ContinuationError(
                f"the branch left [{opts.lam_bounds[0]:.6g}, {opts.lam_bounds[1]:.6g}] at lam = "
                f"{mu_new * lam_scale:.9g} after {len(points)} points: it turned back at a fold and "
                f"does not come back to lam_end = {lam_end:.9g}")
        t_prev = t
        redo = 0
        y, mu, t, orient = y_new, mu_new, t_new, orient_new
        x = y * x_scale
        points.append(ContinuationPoint(x, mu * lam_scale, it, ds, extra(x, mu * lam_scale) if extra else None,
                                        residual=res))
        if callback:
            callback(points[-1])
        # Step control: grow after easy corrections, but keep the tangent turning at most
        # ``target_turn_deg`` per step so that peaks and folds are resolved, not stepped over.
        turn = float(np.rad2deg(np.arccos(np.clip(t_prev @ t, -1.0, 1.0))))
        if turn > opts.target_turn_deg:
            ds = max(ds * max(opts.target_turn_deg / turn, 0.25), opts.ds_min)
        elif it <= opts.target_iter:
            ds = min(ds * opts.grow, opts.ds_max)
    return points
