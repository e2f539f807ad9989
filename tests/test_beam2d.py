"""The jointed beam: Euler-Bernoulli frequencies, linearised-model invariants, linear limit,
and the time-integration check demo on a light setting.  (The three-level demo,
demos/jointed_beam_levels.py, is run by tests/test_demos.py.)"""
import dataclasses
import json
import sys

import numpy as np
import scipy.linalg as sla

from jointfem.analysis.frf import SweepOptions, compute_frf
from jointfem.harmonics import Harmonics
from jointfem.models.beam2d import Beam2DSpec, cantilever_frequencies, create_beam2d
from conftest import ROOT


def test_cantilever_first_four_bending_frequencies_within_half_percent_of_euler_bernoulli():
    spec = Beam2DSpec()
    EI = spec.young * spec.width * spec.height**3 / 12
    rhoA = spec.density * spec.width * spec.height
    beta_L = np.array([1.875104069, 4.694091133, 7.854757438, 10.99554073])
    w_eb = beta_L**2 * np.sqrt(EI / (rhoA * spec.length**4))
    w_fe = cantilever_frequencies(spec, 4)
    np.testing.assert_allclose(w_fe, w_eb, rtol=5e-3)
    # and the cubic elements converge from above at about h^4: 10 elements are worse than 20
    w_10 = cantilever_frequencies(dataclasses.replace(spec, elements=10), 4)
    assert np.all(w_10 >= w_fe) and np.all(np.abs(w_10 / w_eb - 1) > np.abs(w_fe / w_eb - 1))


def test_linearised_jointed_beam_is_symmetric_and_positive():
    s = create_beam2d(Beam2DSpec())
    K, M = s.K_lin.toarray(), s.M.toarray()
    np.testing.assert_allclose(K, K.T, atol=1e-9 * np.abs(K).max())
    w2 = sla.eigh(K, M, eigvals_only=True)
    assert w2[0] > 0
    f = np.sqrt(w2[:9]) / (2 * np.pi)
    # all nine are bending modes below the first axial one, and stay ordered
    assert np.all(np.diff(f) > 0) and 80 < f[0] < 110 and 250 < f[1] < 290


def test_beam_linear_limit_equals_closed_form():
    """1e-6 of the demo's forcing: nothing slips, and the HBM equals the complex linear solve."""
    spec = dataclasses.replace(Beam2DSpec(), force=3e-6, damping="rayleigh", rayleigh_alpha=4.391,
                               rayleigh_beta=4.368e-6)
    s = create_beam2d(spec)
    frf = compute_frf(s, SweepOptions(1600.0, 1800.0, Harmonics(3, 64)))
    assert (frf.states == 0).all()
    X = s.linear_response(frf.omega)[:, s.outputs["b1.mid.uy"]]
    np.testing.assert_allclose(frf.amplitude(s.outputs["b1.mid.uy"]), np.abs(X), rtol=1e-8)


def test_time_integration_check_runs_and_holds_on_the_stuck_flank(tmp_path):
    """The beam's Newmark check, on a light setting (H = 3, N = 256, 3 periods of 1000 steps):
    it asserts itself that the stuck-flank orbit is kept to 0.1 %."""
    import subprocess

    r = subprocess.run([sys.executable, str(ROOT / "demos" / "beam_timeint_check.py"), "--harmonics", "3",
                        "--samples", "256", "--periods", "3", "--steps", "1000", "--out", str(tmp_path)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    report = json.loads((tmp_path / "check.json").read_text())
    assert abs(report["points"]["stuck flank 275 Hz"]["rel_diff"]) < 1e-3
    assert report["points"]["separated, largest amplitude"]["separated_share_hbm"] > 0
