"""The generic continuation on problems with known branches (no vibration in them)."""
import re

import numpy as np
import pytest

from jointfem.continuation.arclength import (ContinuationError, ContinuationOptions, ConvergenceError, NewtonOptions,
                                             continue_branch, solve_newton)


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


def test_stops_clearly_at_the_minimum_step():
    """R = |x| - lam has a right-angle corner at the origin: the hyperplane of a step never meets
    the outgoing half, so the step shrinks to ds_min and a ContinuationError says where."""
    def corner(x, lam):
        x = np.atleast_1d(x)
        return np.abs(x) - lam, np.diag(np.sign(x) + (x == 0)), -np.ones(1)

    with pytest.raises(ContinuationError, match=r"ds_min = 1.0e-04 at lam = ") as err:
        continue_branch(corner, np.array([-1.0]), 1.0, -1.0, x_scale=1.0, lam_scale=1.0, r_scale=1.0,
                        options=ContinuationOptions(ds0=0.1, ds_max=0.1, ds_min=1e-4, max_points=200))
    lam = float(re.search(r"at lam = (\S+)", str(err.value)).group(1))
    assert abs(lam) < 1e-3  # it stopped at the corner, not before or past it


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
