"""Sweeps at strong separation pass the corners of the sampled contact law (issue 14).

The jointed beam at 3 N, H = 11 stalled at its separation onset (1690.118 rad/s: the step fell to
ds_min with the corrector's residual stuck near 1e-6, docs/theory.md): a fold of the branch sits
on a kink there, and the hyperplane of a step along the incoming tangent never meets the branch
beyond it.  The continuation's corner step passes it (docs/theory.md, Continuation).
benchmarks/corners.py runs the full list of issue 14 (docs/benchmarks_corners.md).
"""
from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np
import pytest

from jointfem.analysis.frf import compute_frf
from jointfem.app import override_harmonics, sweep_options
from jointfem.continuation.arclength import ContinuationError
from jointfem.scene import create_structure, load_scene, parse_scene
from conftest import ROOT


def beam_scene(H, N, omega_range):
    data = copy.deepcopy(load_scene(ROOT / "demos" / "beam2d.toml").data)
    data["solver"]["omega_range"] = list(omega_range)
    return override_harmonics(parse_scene(data, "beam_corner.toml"), H, N)


@pytest.fixture(scope="module")
def beam11():
    scene = beam_scene(11, 1024, (1570.0, 1692.0))
    return scene, create_structure(scene)


def test_beam_h11_passes_the_fold_on_a_kink(beam11):
    """The sweep completes through the separation onset and its folds, every point converged to
    the Newton tolerance (no point accepted on a relaxed kink residual), and at least one corner
    step was taken: the fold on a kink at 1690.12 rad/s."""
    scene, s = beam11
    opts = sweep_options(scene, stability="off")
    frf = compute_frf(s, replace(opts, locate_peaks=False))
    steps = frf.info["continuation"]
    assert steps["corners_passed"] >= 1
    assert frf.omega.max() >= 1692.0
    # past the fold at 1690.12 rad/s the branch turns back, to 1684.4 rad/s (docs/theory.md, H = 11)
    top = int(np.argmax(frf.omega > 1690.1))
    assert frf.omega[top:].min() < 1685.0
    assert frf.info["arrays"]["residual"].max() <= opts.continuation.newton.tol
    # the branch separates: some samples of some pair are open
    assert (frf.states == 2).any()
    # every point solves the HBM equations (the residual recorded is the one achieved)
    assert np.all(np.isfinite(frf.U))


def test_beam_h11_stalls_without_corner_steps(beam11):
    """The same sweep with corner steps off stops at the fold on a kink with a clear error: the
    test above can fail, and the stall it guards against is real."""
    scene, s = beam11
    opts = sweep_options(scene, stability="off")
    opts = replace(opts, locate_peaks=False, continuation=replace(
        opts.continuation, corner_steps=False, secant_on_kinks=False, ds_min=1e-4))
    with pytest.raises(ContinuationError, match=r"ds_min") as err:
        compute_frf(s, opts)
    lam = err.value.points[-1].lam  # at the separation onset (1690.12 rad/s, or a fold on a kink before it)
    assert 1689.0 < lam < 1690.2, lam
