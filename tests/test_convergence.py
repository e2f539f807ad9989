"""The harmonic truncation estimate per point (jointfem.analysis.convergence) against what it
estimates: the change of the response when H grows by two."""
from __future__ import annotations

import numpy as np
import pytest

from conftest import sdof
from jointfem.analysis.convergence import top_harmonic_share
from jointfem.analysis.frf import SweepOptions, compute_frf, create_problem
from jointfem.continuation.arclength import NewtonOptions, solve_newton
from jointfem.harmonics import Harmonics
from jointfem.hbm.problem import newton_system
from jointfem.models.lumped import create_lumped


def _solve(structure, H, omega):
    h = Harmonics(H, 1024)
    pb = create_problem(structure, h)
    sc = pb.scales(0.5, 2.0)
    x, _ = solve_newton(newton_system(pb), pb.initial_guess(omega), omega, x_scale=sc.x, r_scale=sc.r,
                        options=NewtonOptions(tol=1e-12))
    return float(np.hypot(x[1], x[2])), top_harmonic_share(pb.evaluate(x, omega, jacobian=False).contact, h)


def test_estimate_bounds_the_change_when_h_grows_by_two():
    """SDOF Jenkins at 1.3 rad/s, F = 0.5 (slipping): the estimate falls with H (0.14 at H = 3 to
    0.0063 at H = 11, measured), and the first harmonic changes by less than it when H grows by two
    (measured: about e^2 / 4).  Stuck (F = 0.2 at 1.3 rad/s): the estimate is zero to round-off."""
    s = create_lumped(sdof(0.5))
    prev = None
    for H in (3, 5, 7, 9, 11):
        a, e = _solve(s, H, 1.3)
        a2, _ = _solve(s, H + 2, 1.3)
        assert abs(a2 / a - 1) < e, (H, a, a2, e)
        assert abs(a2 / a - 1) > 1e-3 * e**2, (H, a, a2, e)  # not vacuous: the change is of order e^2
        if prev is not None:
            assert e < prev
        prev = e
    assert _solve(create_lumped(sdof(0.2)), 7, 1.3)[1] < 1e-12


def test_branch_records_the_estimate_and_warns(caplog):
    frf = compute_frf(create_lumped(sdof(0.5)), SweepOptions(0.5, 2.0, Harmonics(3, 256), harmonic_tol=0.05))
    he = frf.info["arrays"]["harmonic_error"]
    stuck = (frf.states == 0).all(axis=(1, 2))
    assert he[stuck].max() < 1e-12 and he[~stuck].max() > 0.05
    assert "more harmonics are needed" in frf.info["harmonic_warning"]
    assert any("harmonic truncation estimate" in r.message for r in caplog.records)
    quiet = compute_frf(create_lumped(sdof(0.5)), SweepOptions(0.5, 2.0, Harmonics(3, 256), harmonic_tol=1.0))
    assert "harmonic_warning" not in quiet.info


SCENE = """
kind = "lumped"
[solver]
omega_range = [0.5, 2.0]
{solver}
[[mass]]
name = "m"
m = 1.0
dofs = ["x"]
[[spring]]
between = ["m.x", "ground"]
k = 1.0
[[damper]]
between = ["m.x", "ground"]
c = 0.02
[[jenkins]]
between = ["m", "ground"]
tangential = ["x"]
kt = 1.0
mu = 1.0
N0 = 1.0
[[force]]
dof = "m.x"
amplitude = 0.5
[output]
dofs = ["m.x"]
"""


@pytest.mark.parametrize("solver, key, words", [
    ('harmonics = "many"', "solver.harmonics", "must be an integer"),
    ('harmonics = 5\nharmonic_target = 0.01', "solver.harmonic_target", "only with harmonics"),
    ('harmonics = "auto"\nharmonic_target = 2.0', "solver.harmonic_target", "must be < 1"),
    ('harmonics = "auto"\nharmonics_max = 25\nsamples = 40', "solver.samples", "harmonics_max"),
    ('harmonics = 5\namplitude_tol = 0.01', "solver.amplitude_tol", "only with harmonics"),
    ('harmonics = "auto"\namplitude_tol = 1.5', "solver.amplitude_tol", "must be < 1"),
    ('harmonics = 3\npeak_error = 1', "solver.peak_error", "must be true or false"),
])
def test_bad_auto_harmonics_keys_are_refused(tmp_path, solver, key, words):
    from jointfem.scene import SceneError, load_scene

    path = tmp_path / "bad.toml"
    path.write_text(SCENE.format(solver=solver))
    with pytest.raises(SceneError, match=rf"{key}.*{words}"):
        load_scene(path)


def test_compare_refuses_auto_harmonics(tmp_path):
    from jointfem.app import compare_scene
    from jointfem.rom import RomOptions
    from jointfem.scene import SceneError, load_scene

    path = tmp_path / "auto.toml"
    path.write_text(SCENE.format(solver='harmonics = "auto"'))
    with pytest.raises(SceneError, match=r"solver.harmonics.*one H"):
        compare_scene(load_scene(path), "penalty", RomOptions(modes=1), out=tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_estimate_needs_three_harmonics():
    """With H <= 2 the two top harmonics would include the fundamental, and the slipping SDOF
    oscillator has no second harmonic (its law is symmetric): the estimate is 1 (not known to be
    converged) rather than a false 0, stuck or slipping.  At H = 3 it is measured (0.14)."""
    stuck, slip = create_lumped(sdof(0.2)), create_lumped(sdof(0.5))
    for H in (1, 2):
        assert _solve(stuck, H, 1.3)[1] == 1.0 and _solve(slip, H, 1.3)[1] == 1.0
    assert 0.1 < _solve(slip, 3, 1.3)[1] < 0.2


# ---- the truncation estimate of the response (TruncationEstimator) --------------------------------

def two_mass():
    """Mass a (1 kg, 1 N/m and a slider of slip force 0.3 N to ground, forced by 1.5 N) carries mass b
    (0.1 kg on 0.324 N/m): near omega = 0.643 rad/s the slider's third harmonic meets b's mode (a 3:1
    superharmonic resonance; benchmarks/truncation.py)."""
    from jointfem.models.lumped import ForceSpec, JenkinsSpec, LinkSpec, LumpedSpec, MassSpec
    return LumpedSpec(
        masses=(MassSpec("a", 1.0), MassSpec("b", 0.1)),
        springs=(LinkSpec("a.x", "ground", 1.0), LinkSpec("b.x", "a.x", 0.324)),
        dampers=(LinkSpec("a.x", "ground", 0.02), LinkSpec("b.x", "a.x", 0.002)),
        jenkins=(JenkinsSpec("a", "ground", ("x",), None, kt=1.0, kn=0.0, mu=1.0, N0=0.3),),
        forces=(ForceSpec("a.x", 1.5),), outputs=("a.x", "b.x"))


def _peak(structure, window, H, name, N=1024):
    """(omega, first-harmonic amplitude, RMS, x, problem, scales) at the located peak of ``name``."""
    from jointfem.analysis.convergence import amplitude_and_rms, output_signal
    from jointfem.analysis.frf import solve_at

    h = Harmonics(H, N)
    frf = compute_frf(structure, SweepOptions(window[0], window[1], h, stability=False))
    p = frf.info["peaks"][name]
    assert p.located, p
    sol = solve_at(structure, p.omega, h, guess=frf.U[int(np.argmin(np.abs(frf.omega - p.omega)))],
                   newton=NewtonOptions(tol=1e-12))
    pb = create_problem(structure, h)
    return (p.omega, p.amplitude, amplitude_and_rms(output_signal(sol.U, pb.layout.outputs[name], h), h)[1], sol.U,
            pb, pb.scales(*window))


@pytest.mark.parametrize("spec, window, name, Hs", [
    (sdof(0.05), (0.5, 2.0), "m.x", (1, 3)),
    (sdof(0.2), (0.5, 2.0), "m.x", (1, 3, 5)),
    (sdof(0.5), (0.5, 2.0), "m.x", (1, 3, 5)),
    (two_mass(), (0.60, 0.65), "b.x", (3, 5)),
], ids=["sdof-F0.05", "sdof-F0.2", "sdof-F0.5", "two-mass-3:1"])
def test_truncation_estimate_against_the_truth_at_the_peak(spec, window, name, Hs):
    """At each located peak whose error passes 1e-4 of it, the estimate of the error of the peak's
    amplitude (the (3H, 2N) branch's peak, found by TruncationEstimator.peak) and of the RMS at its
    frequency is within 3x of the truth (the issue's bound; measured 0.65-1.14 on these rows,
    docs/benchmarks_truncation.md) and of its sign; the homotopy reaches (3H, 2N) without turning
    back.  Truth: the located peak at (H, N) = (25, 2048) minus H's (H = 25 and 41 at N = 1024
    differ by at most 6.2e-7 here, measured); its RMS solved at H's peak frequency, minus H's.  On the two masses
    the RMS error at H = 5 (1.8e-3) is 14x the first harmonic's: b's missing third harmonic, which
    the estimate sees (0.99 of it)."""
    from jointfem.analysis.convergence import TruncationEstimator, amplitude_and_rms, output_signal
    from jointfem.analysis.frf import solve_at

    s = create_lumped(spec)
    w_ref, a_ref, _, _, pb_ref, _ = _peak(s, window, 25, name, N=2048)
    h_ref = pb_ref.harmonics
    checked = 0
    for H in Hs:
        w, a, rms, x, pb, sc = _peak(s, window, H, name)
        ref = solve_at(s, w, h_ref, guess=np.concatenate([x, np.zeros(pb_ref.num_coefficients - x.size)]),
                       newton=NewtonOptions(tol=1e-12))
        rms_ref = amplitude_and_rms(output_signal(ref.U, pb_ref.layout.outputs[name], h_ref), h_ref)[1]
        est = TruncationEstimator(lambda h: create_problem(s, h), pb.harmonics, {name: pb.layout.outputs[name]},
                                  window=window)
        pk = est.peak(x, w, name, span=2e-3 * w)
        e = pk.at_omega
        assert est.h2 == Harmonics(3 * H, 2048) and e.connected and e.folds == 0 and pk.peak.located, (H, pk)
        for true, guess in ((a_ref - a, pk.peak.amplitude - a), (rms_ref - rms, e.rms[0])):
            if abs(true) > 1e-4 * a:
                assert 1 / 3 < guess / true < 3, (H, true, guess)
                checked += 1
    assert checked >= len(Hs)  # every H's amplitude or RMS error passed 1e-4: none was skipped


def test_peak_error_in_summary(tmp_path):
    """[solver] peak_error = true: summary.json carries each located peak's estimated truncation
    error, the change to the same peak at (3H, 2N): on the SDOF oscillator at F = 0.5, H = 3, the
    peak at (9, 512) against the reference (25, 512) solved here: measured 1.019x of the true change
    of the amplitude and 1.017x of omega's, asserted within 10 % and 20 % (docs/benchmarks_truncation.md:
    0.97-1.05 at N = 1024 on this oscillator from H = 3); the keys as docs/scenes.md says."""
    import json

    from jointfem.app import solve_scene, write_frf
    from jointfem.rom import RomOptions
    from jointfem.scene import load_scene

    path = tmp_path / "err.toml"
    path.write_text(SCENE.format(solver="harmonics = 3\nsamples = 256\npeak_error = true"))
    scene = load_scene(path)
    sol = solve_scene(scene)
    write_frf(sol, scene, tmp_path / "out", method="full", rom_options=RomOptions())
    peak = json.loads((tmp_path / "out" / "summary.json").read_text())["peaks"]["m.x"]
    err = peak["truncation_error"]
    assert err["connected"] and (err["to_harmonics"], err["to_samples"]) == (9, 512) and "reason" not in err
    ref = compute_frf(create_lumped(sdof(0.5)), SweepOptions(0.5, 2.0, Harmonics(25, 512), stability=False))
    w_ref, a_ref = ref.peak("m.x")
    assert err["amp1_m"] == pytest.approx(a_ref - peak["amp1_m"], rel=0.1)
    assert abs(err["amp1_m"]) > 1e-4 * peak["amp1_m"]  # not a vacuous comparison
    assert err["omega_rad_s"] == pytest.approx(w_ref - peak["omega_rad_s"], rel=0.2)
    assert sol.frf.info["time_peak_error_s"] > 0
