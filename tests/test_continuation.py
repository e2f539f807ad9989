"""The generic continuation on problems with known branches (no vibration in them)."""
import re

import numpy as np
import pytest

from jointfem.continuation.arclength import (ContinuationError, ContinuationOptions, ContinuationPoint, ConvergenceError,
                                             NewtonOptions, _retraced, continue_branch, correct, hyperplane_derivative,
                                             solve_newton)


def folded(x, lam):
    """R = x^3 - x - lam: an S-shaped branch with two folds at lam = -/+ 2/(3 sqrt 3)."""
    x = np.atleast_1d(x)
    R = x**3 - x - lam
    return R, np.diag(3 * x**2 - 1), -np.ones(1)


@pytest.mark.parametrize("lam0,lam1", [(-2.0, 2.0), (2.0, -2.0)])
def test_passes_both_folds_in_both_directions(lam0, lam1):
    x0 = np.array([-1.6 if lam0 < 0 else 1.6])
    pts = continue_branch(folded, x0, lam0, lam1, x_scale=1.0, lam_scale=1.0, r_scale=1.0,
                          options=ContinuationOptions(ds0=0.05, ds_max=0.1))
    x = np.array([p.x[0] for p in pts])
    lam = np.array([p.lam for p in pts])
    np.testing.assert_allclose(x**3 - x, lam, atol=1e-9)  # every point is on the branch
    # the branch is followed monotonically in x (the arclength parameter), through both folds
    assert np.all(np.diff(x) * np.sign(x[-1] - x[0]) > 0)
    assert (np.diff(lam) > 0).any() and (np.diff(lam) < 0).any()
    assert x.min() < -1.0 and x.max() > 1.0
    # no point jumps: consecutive points are within the largest step
    z = np.column_stack([x, lam])
    assert np.linalg.norm(np.diff(z, axis=0), axis=1).max() <= 0.1 * 1.01


def test_newton_error_names_iterations_residual_and_lam():
    def no_root(x, lam):
        return np.array([x[0] ** 2 + 1.0]), np.array([[2 * x[0]]]), np.zeros(1)

    with pytest.raises(ConvergenceError) as err:
        solve_newton(no_root, np.array([0.3]), 1.25, x_scale=1.0, r_scale=1.0, options=NewtonOptions(max_iter=5))
    msg = str(err.value)
    assert "lam = 1.25" in msg and "5 iterations" in msg and "residual" in msg
    assert err.value.iterations == 5 and err.value.residual >= 1.0


def corner(x, lam):
    """R = |x| - lam: a right-angle corner at the origin where the branch turns back in lam (a
    fold on a kink, as a sampled contact law makes them)."""
    x = np.atleast_1d(x)
    return np.abs(x) - lam, np.diag(np.sign(x) + (x == 0)), -np.ones(1)


def test_passes_a_fold_on_a_corner():
    """The hyperplane of a step never meets the outgoing half of |x| = lam, however short the
    step.  The corner step probes the Jacobian beyond the corner, steps along that piece's tangent
    (oriented to keep the orientation of the branch) and follows the branch up the other side."""
    with pytest.raises(ContinuationError, match=r"left \[-1, 2\]") as err:
        continue_branch(corner, np.array([-1.0]), 1.0, -1.0, x_scale=1.0, lam_scale=1.0, r_scale=1.0,
                        options=ContinuationOptions(ds0=0.1, ds_max=0.1, max_points=400, lam_bounds=(-1.0, 2.0)))
    pts = err.value.points  # lam never reaches -1: the branch turned back at the corner, up to lam = 2
    x = np.array([p.x[0] for p in pts])
    lam = np.array([p.lam for p in pts])
    np.testing.assert_allclose(np.abs(x), lam, atol=1e-12)  # on the branch
    assert np.all(np.diff(x) > 0)  # through the corner, never back
    assert x[-1] > 1.8
    # the corner step is taken only once the step is short (corner_ds = 1e-4): no point cuts it
    assert np.abs(x).min() < 1e-4
    assert lam.min() < 0.1  # the turn was taken near the corner (not skipped by a long step)


def sharp(x, lam, k=np.tan(np.deg2rad(84.0))):
    """R = k |x| - lam: a fold on a kink whose legs are 12 deg apart, so that the branch turns by
    168 deg there (the 9-pair 3D lap joint at N = 128 folds so at 1546.05 rad/s, issue 14)."""
    x = np.atleast_1d(x)
    return k * np.abs(x) - lam, np.diag(k * (np.sign(x) + (x == 0))), -np.ones(1)


@pytest.mark.parametrize("sharp_ok", [True, False])
def test_a_corner_sharper_than_the_reversal_guard_is_the_last_resort(sharp_ok):
    """The piece beyond the corner turns back by more than 180 - max_reversal_deg = 150 deg, and no
    step at fixed lam passes (there is no solution below lam = 0).  It is then taken, since the
    retrace rule tells it from the way the branch came (its legs part at sin(12 deg) = 0.21 of the
    step, twice retrace_tol), as the last resort where the sweep would stop; without the retrace
    rule it is not, and the sweep stops at the corner
    as it did before (below ds_min)."""
    k = np.tan(np.deg2rad(84.0))
    opts = ContinuationOptions(ds0=0.02, ds_max=0.02, max_points=2000, lam_bounds=(-1.0, 2 * k),
                               retrace_tol=0.1 if sharp_ok else None)
    with pytest.raises(ContinuationError) as err:
        continue_branch(sharp, np.array([-1.0]), k, -1.0, x_scale=1.0, lam_scale=1.0, r_scale=1.0, options=opts,
                        stats=(stats := {}))
    pts = err.value.points
    x = np.array([p.x[0] for p in pts])
    lam = np.array([p.lam for p in pts])
    np.testing.assert_allclose(k * np.abs(x), lam, atol=1e-12)  # every point on the branch
    if sharp_ok:
        assert "left [-1" in str(err.value)  # up the far leg to lam = 2k: through the corner
        assert np.all(np.diff(x) > 0) and x[-1] > 1.8 and np.abs(x).min() < 1e-4
        assert stats["sharp_corners"] == 1
    else:
        assert "ds_min" in str(err.value) and abs(x[-1]) < 1e-4


def test_without_corner_steps_stops_clearly_at_the_corner():
    """With corner steps off the step shrinks to ds_min at the corner and a ContinuationError says
    where, and carries the points converged before it."""
    with pytest.raises(ContinuationError, match=r"stopped at lam = .* ds_min = 1.0e-04") as err:
        continue_branch(corner, np.array([-1.0]), 1.0, -1.0, x_scale=1.0, lam_scale=1.0, r_scale=1.0,
                        options=ContinuationOptions(ds0=0.1, ds_max=0.1, ds_min=1e-4, max_points=200,
                                                    corner_steps=False))
    lam = float(re.search(r"at lam = (\S+)", str(err.value)).group(1))
    assert abs(lam) < 1e-3  # it stopped at the corner, not before or past it
    kept = err.value.points
    assert len(kept) > 5 and kept[-1].lam == pytest.approx(lam)
    assert all(abs(abs(p.x[0]) - p.lam) < 1e-12 for p in kept)


def test_time_limit_stops_with_the_points_kept():
    """A budget reached stops the branch with a message naming it, never a hang."""
    with pytest.raises(ContinuationError, match=r"time limit of 0 s") as err:
        continue_branch(folded, np.array([-1.6]), -2.0, 2.0, x_scale=1.0, lam_scale=1.0, r_scale=1.0,
                        options=ContinuationOptions(time_limit=0.0))
    assert len(err.value.points) == 1  # the start point


def twin(x, lam, eps=0.02):
    """R = (x - sin 3 lam)^2 - eps^2: two parallel curved branches x = sin(3 lam) +- eps."""
    x = np.atleast_1d(x)
    d = x - np.sin(3 * lam)
    return d**2 - eps**2, np.diag(2 * d), -6 * d * np.cos(3 * lam)


@pytest.mark.parametrize("ds_max", [0.05, 0.5, 1.0])
def test_never_jumps_onto_a_neighbouring_branch(ds_max):
    """With long steps the predictor leaves the curved branch by more than the 0.04 between the
    twins, and the corrector lands on the other one (before the orientation check it did, for
    ds_max >= 0.2).  The sign of the bordered Jacobian's determinant flips between the twins, so
    such a step is refused and shortened: every point must stay on x = sin(3 lam) + eps."""
    pts = continue_branch(twin, np.array([0.02]), 0.0, 4.0, x_scale=1.0, lam_scale=1.0, r_scale=1.0,
                          options=ContinuationOptions(ds0=ds_max, ds_max=ds_max))
    x = np.array([p.x[0] for p in pts])
    lam = np.array([p.lam for p in pts])
    np.testing.assert_allclose(x - np.sin(3 * lam), 0.02, atol=1e-8)
    assert lam[-1] >= 4.0 and np.all(np.diff(lam) > 0)  # this branch has no fold: lam is monotone


def test_recovers_from_failed_steps_by_shrinking(caplog):
    """A first step of 1.0 on the S-curve cannot converge onto the branch near the fold: the step
    is refused and halved (logged), and the branch is then followed correctly to the end."""
    import logging

    with caplog.at_level(logging.DEBUG, logger="jointfem.continuation.arclength"):
        pts = continue_branch(folded, np.array([-1.6]), -2.0, 2.0, x_scale=1.0, lam_scale=1.0, r_scale=1.0,
                              options=ContinuationOptions(ds0=1.0, ds_max=1.0))
    rejected = [r for r in caplog.records if "step rejected" in r.getMessage()]
    assert len(rejected) >= 1
    x = np.array([p.x[0] for p in pts])
    lam = np.array([p.lam for p in pts])
    np.testing.assert_allclose(x**3 - x, lam, atol=1e-9)
    assert np.all(np.diff(x) > 0) and x[-1] > 1.0  # through both folds, never back
    ds = np.array([p.ds for p in pts[1:]])
    assert ds.min() < 1.0  # the accepted steps include shortened ones


@pytest.mark.parametrize("select", [None, np.array([0, 2])])
def test_hyperplane_derivative_equals_finite_differences(select):
    """d/dt of the point that ``correct`` finds on the hyperplane at t along a chord, against a
    central difference of two corrector solutions (t +- 1e-5), on a two-fold S-curve coupled to a
    second unknown, with scales that differ, near a fold (the chord crosses it) and on a flank; with
    ``select``, the third coefficient is not an unknown (kept zero).  Truncation of the difference
    is O(1e-10), Newton's tolerance 1e-13: agreement to 1e-7 of the derivative's size."""
    def fun(x, lam):
        u, v = x[0], x[2]
        R = np.array([u**3 - u - lam + 0.1 * v, v - 0.5 * u**2 + 0.2 * lam, x[1] - 0.3 * u * v])
        J = np.array([[3 * u**2 - 1, 0.0, 0.1], [-u, 0.0, 1.0], [-0.3 * v, 1.0, -0.3 * u]])
        dl = np.array([-1.0, 0.2, 0.0])
        if select is None:
            return R, J, dl
        return R[[0, 1]], J[np.ix_([0, 1], select)], dl[[0, 1]]

    opts = NewtonOptions(tol=1e-13, max_iter=40)
    xs, ls = np.array([2.0, 0.01, 0.5]), np.array([10.0])
    for xa_u, xb_u in ((-0.7, -0.4), (1.2, 1.4)):  # across the fold at u = -1/sqrt 3; on the upper flank
        pts = []
        for u in (xa_u, xb_u):
            v = 0.5 * u**2  # a start; correct() puts it on the branch
            pts.append((np.array([u, 0.0 if select is not None else 0.3 * u * v, v]), u**3 - u + 0.1 * v))
        (xa, la), (xb, lb) = pts
        chord = (xb - xa, lb - la)
        kw = dict(x_scale=xs, lam_scale=ls[0], r_scale=1.0, options=opts, select=select)

        def at(t):
            x, lam, _, _ = correct(fun, xa + t * chord[0], la + t * chord[1], chord, **kw)
            return np.append(x, lam)

        z = at(0.4)
        dx, dlam = hyperplane_derivative(fun, z[:-1], z[-1], chord, x_scale=xs, lam_scale=ls[0], select=select)
        fd = (at(0.4 + 1e-5) - at(0.4 - 1e-5)) / 2e-5
        got = np.append(dx, dlam)
        assert np.abs(got - fd).max() < 1e-7 * np.abs(fd).max(), (got, fd)
        if select is not None:
            assert dx[1] == 0.0


def sawtooth(x, lam, period=2e-4, slope=0.3):
    """R = x - h(lam), h a triangle wave of slope +-0.3 and period 2e-4: a kink every 1e-4 in lam,
    across which the tangent turns by 2 atan 0.3 = 33 deg (beyond target_turn_deg, within max_turn_deg):
    neighbouring kinks closer than turn_ds_floor, as on the lap joint's separated loop (issue 14)."""
    phase = np.mod(lam, period) / period
    h = slope * period * np.where(phase < 0.5, phase, 1.0 - phase)
    dh = slope * np.where(phase < 0.5, 1.0, -1.0)
    x = np.atleast_1d(x)
    return x - h, np.eye(1), -np.atleast_1d(dh)


def test_kinks_closer_than_the_turn_floor_do_not_collapse_the_step():
    """The tangent turns by 33 deg at every kink, 1e-4 apart: shrinking the step for each turn
    followed that chatter down (before: 582 points for lam 0 to 0.02, median step 2.0e-5); the step
    is no longer shrunk for a turn below turn_ds_floor = 1e-4, so the steps stay about that long
    (measured 63 points, median step 2.0e-4).  Every point is on the branch."""
    pts = continue_branch(sawtooth, np.zeros(1), 0.0, 0.02, x_scale=1.0, lam_scale=1.0, r_scale=1.0,
                          options=ContinuationOptions(ds0=1e-3, ds_max=0.01, max_points=20000))
    x = np.array([p.x[0] for p in pts])
    lam = np.array([p.lam for p in pts])
    np.testing.assert_allclose(x, sawtooth(np.zeros(lam.size), lam)[0] * -1, atol=1e-12)
    assert lam[-1] >= 0.02 and len(pts) < 200



def _polyline(z):
    """ContinuationPoints at the rows (x..., lam) of z."""
    return [ContinuationPoint(np.array(row[:-1], float), float(row[-1]), 0, 0.0) for row in z]


def _turned(last, incoming, deg, h):
    """The point a step of length h from ``last`` reaches, turned by ``deg`` from ``incoming`` (2D)."""
    a = np.deg2rad(deg)
    d = incoming / np.linalg.norm(incoming)
    return last + h * np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]) @ d


def test_retrace_rule_tells_a_step_back_from_folds_and_corners():
    """The rule that refuses a step back along the branch (ContinuationOptions.retrace_tol = 0.1):
    a point on the traced polyline (to 1e-6 of the step, the chords' error on the 3D lap joint's
    retrace) walked backwards is found, with the segment it lies on; the legs of a smooth fold and of
    a corner that turns by 150 deg (the most a step may turn, max_reversal_deg = 30) part at half the
    step or more, ten times the tolerance, and are not; a turn of 175 deg is."""
    s = np.linspace(0.0, 1.0, 11)
    line = _polyline(np.column_stack([s, s]))  # x = lam, traced up to lam = 1
    last = np.array([1.0, 1.0])
    back = np.array([0.95, 0.95 + 1e-6 * 0.05])
    assert _retraced(line, np.ones(1), 1.0, last, back, 0.1) == 9  # on segment 0.9-1.0
    assert _retraced(line, np.ones(1), 1.0, np.array([0.3, 0.3]), np.array([0.35, 0.35]), 0.1) is None  # forward
    up = np.array([1.0, 1.0])
    assert _retraced(line, np.ones(1), 1.0, last, _turned(last, up, 150.0, 0.05), 0.1) is None
    assert _retraced(line, np.ones(1), 1.0, last, _turned(last, up, 175.0, 0.05), 0.1) is not None
    # in scaled coordinates: x_scale and lam_scale divide before the distances are taken
    assert _retraced(_polyline(np.column_stack([1e-3 * s, 50.0 * s])), np.full(1, 1e-3), 50.0,
                     np.array([1.0, 1.0]), back, 0.1) == 9
    # a smooth fold: lam = cos(theta), x = sin(theta), traced in 8 deg steps up to the fold at
    # theta = 0 and one step beyond it
    th = np.deg2rad(np.arange(-90.0, 1.0, 8.0))
    fold = _polyline(np.column_stack([np.sin(th), np.cos(th)]))
    nxt = th[-1] + np.deg2rad(8.0)
    assert _retraced(fold, np.ones(1), 1.0, np.array([np.sin(th[-1]), np.cos(th[-1])]),
                     np.array([np.sin(nxt), np.cos(nxt)]), 0.1) is None


def line(x, lam):
    """R = x - lam: the branch x = lam."""
    return np.atleast_1d(x) - lam, np.eye(1), -np.ones(1)


def test_a_resumed_branch_is_not_walked_back_along_its_points_before_the_stop():
    """The retrace rule sees the points a resumed branch had before it stopped (``traced``): a sweep
    that went down x = lam from 1 to 0.5, resumed heading up (as a tangent that reverses at a kink
    does), would walk back along them, and is stopped saying so; without them it walks back up
    unhindered (what let the 3D lap joint's resumed penalty sweep at 5 N step back once, issue 14)."""
    before = _polyline(np.column_stack([np.linspace(1.0, 0.52, 25)] * 2))
    opts = ContinuationOptions(ds0=0.02, ds_max=0.02)
    resume = ((np.array([1.0]), 1.0), 0.02)
    with pytest.raises(ContinuationError, match=r"the step goes back along the branch traced at lam = 0.52 "
                                                r"\(points 24-25 of this branch\)") as stopped:
        continue_branch(line, np.array([0.5]), 0.5, 1.0, x_scale=1.0, lam_scale=1.0, r_scale=1.0, options=opts,
                        resume=resume, traced=before)
    # the count is the branch's (25 before the stop and the point it resumed from), as the command
    # line's "N converged points" is: it had said 1
    assert "after 26 points" in str(stopped.value)
    pts = continue_branch(line, np.array([0.5]), 0.5, 1.0, x_scale=1.0, lam_scale=1.0, r_scale=1.0, options=opts,
                          resume=resume)
    assert pts[-1].lam >= 1.0


class _Spy:
    """An Adaptive problem that records where after_converge was asked (and never changes)."""
    max_redo = 5

    def __init__(self):
        self.asked = []

    def unknowns(self):
        return None

    def before_step(self, x, lam):
        return False

    def after_converge(self, x, lam):
        self.asked.append(lam)
        return False


def test_a_point_refused_for_landing_far_never_changes_the_problem():
    """A corrector that lands farther than max_jump steps is refused before the problem's
    after_converge hook sees the point: an adaptive problem (the penalty ROM's active set) changed
    for a point it then refuses need not have the last point as a solution any more (issue 14:
    the 3D lap joint at 5 N stopped at 1720.01 rad/s that way).  With max_jump = 0.5 every step on
    x = lam lands at least one step away and is refused: the hook is asked only at the start."""
    spy = _Spy()
    opts = ContinuationOptions(ds0=0.02, ds_max=0.02, max_jump=0.5, turn_ds_floor=1e-9, corner_steps=False,
                               kink_lam_steps=False)
    with pytest.raises(ContinuationError, match="corrector landed 1.0 step lengths away"):
        continue_branch(line, np.array([0.0]), 0.0, 1.0, x_scale=1.0, lam_scale=1.0, r_scale=1.0, options=opts,
                        adapt=spy)
    assert spy.asked == [0.0]


def torn(x, lam, gap=0.2):
    """R = x - lam - gap [lam > 0.5]: a branch torn at lam = 0.5, whose Jacobian is the same on both
    sides (no orientation flips, so no corner step is offered)."""
    x = np.atleast_1d(x)
    return x - lam - gap * (lam > 0.5), np.eye(1), -np.ones(1)


@pytest.mark.parametrize("leaps", [20, 0])
def test_a_leap_at_fixed_lam_is_the_last_resort_before_a_stop(leaps):
    """Where every step is refused down to ds_min, Newton at fixed lam = lam + corner_ds 2^k
    (towards lam_end) from the last point finds the branch beyond, and the branch goes on from
    there to lam_end; without leaps (max_leaps = 0) it stops at the tear with its points, as it did
    before.  The tear stands for a fold on a kink that no step's hyperplane reaches across (the
    9-pair lap joint under another OpenBLAS kernel, issue 52): with turn_ds_floor below ds_min every
    corrector that lands across it (0.2 away, 7 steps of 0.02) is refused as landing too far, and so is the step at
    fixed lam from the predictor (across())."""
    opts = ContinuationOptions(ds0=0.02, ds_max=0.02, max_points=2000, turn_ds_floor=1e-7, max_leaps=leaps)
    stats = {}

    def run():
        return continue_branch(torn, np.array([0.0]), 0.0, 1.0, x_scale=1.0, lam_scale=1.0, r_scale=1.0,
                               options=opts, stats=stats)

    if leaps:
        pts = run()
        assert stats["leaps"] == 1 and pts[-1].lam >= 1.0
    else:
        with pytest.raises(ContinuationError, match="ds_min") as err:
            run()
        pts = err.value.points
        assert stats["leaps"] == 0 and abs(pts[-1].lam - 0.5) < 1e-3
    x = np.array([p.x[0] for p in pts])
    lam = np.array([p.lam for p in pts])
    np.testing.assert_allclose(x, lam + 0.2 * (lam > 0.5), atol=1e-12)  # every point on the branch
    assert np.all(np.diff(lam) > 0)  # never back
