"""Numerical stability at the extremes (issue 6), part 2: small lumped systems driven to the edges
of their parameters, each checked against an independent limit (a closed form, an exact property
of the equations, or time integration), or required to stop with a clear error.

Systems (m = 1 everywhere):
* ``xz``: one mass, tangential x (k = 1, kt = 1) and normal z (kz, kn) on one Jenkins pair to
  ground, N = N0 + kn z; separation when N <= 0.
* ``rotor``: one mass in the plane (kx = ky = 1: coincident resonances), one 2D Jenkins pair,
  driven by a rotating force: circular gross slip has a closed form.
* ``sdof``: the SDOF Jenkins oscillator of tests/conftest.py (k = kt = Fs = 1).
"""
from __future__ import annotations

import numpy as np
import pytest

from jointfem.continuation.arclength import ContinuationError, ContinuationOptions, solve_newton
from jointfem.contact.jenkins import SEPARATED, STICK
from jointfem.analysis.frf import SweepOptions, compute_frf
from jointfem.hbm.problem import newton_system
from jointfem.harmonics import Harmonics
from jointfem.hbm.residual import HBMResidual
from jointfem.models.lumped import ForceSpec, JenkinsSpec, LinkSpec, LumpedSpec, MassSpec, create_lumped
from conftest import ROOT, linear_amplitude, sdof
from reference_timeint import steady_amplitudes


def xz(Fx=0.3, Fz=0.8, *, kn=1.0, kz=3.0, N0=1.0, mu=0.5, c=0.05, normal=True):
    return LumpedSpec(
        masses=(MassSpec("m", 1.0, ("x", "z")),),
        springs=(LinkSpec("m.x", "ground", 1.0), LinkSpec("m.z", "ground", kz)),
        dampers=(LinkSpec("m.x", "ground", c), LinkSpec("m.z", "ground", c)),
        jenkins=(JenkinsSpec("m", "ground", ("x",), "z" if normal else None, kt=1.0, kn=kn if normal else 0.0,
                             mu=mu, N0=N0),),
        forces=(ForceSpec("m.x", Fx), ForceSpec("m.z", Fz)), outputs=("m.x", "m.z"))


def sweep(spec, w0, w1, H=7, N=512, **cont):
    frf = compute_frf(create_lumped(spec), SweepOptions(w0, w1, Harmonics(H, N), ContinuationOptions(**cont)))
    assert np.all(np.isfinite(frf.U)) and np.all(np.isfinite(frf.omega))
    assert min(frf.omega[0], frf.omega[-1]) <= min(w0, w1) + 1e-9 and max(frf.omega) >= max(w0, w1) - 1e-9
    return frf


# ---- normal stiffness from 1e-6 to 1e6 x nominal -------------------------------------------------

def test_soft_normal_spring_is_a_constant_normal_load():
    """kn x 1e-6: N = N0 + 1e-6 z stays within 1e-6 |z| of N0, so the branch is that of the same
    pair without a normal axis (constant N0) to the relative size of that change (tol 1e-5)."""
    a = sweep(xz(kn=1e-6), 0.8, 2.4)
    b = sweep(xz(normal=False), 0.8, 2.4)
    assert (a.states == 1).any()  # the comparison covers slip
    for dof in (0, 1):  # the peaks, from two independent sweeps (their points differ)
        assert a.amplitude(dof).max() == pytest.approx(b.amplitude(dof).max(), rel=1e-5)  # measured 1.5e-7
    # exact point-by-point check at fixed omega: the same Newton solution to 1e-5
    h = Harmonics(7, 512)
    sols = []
    for spec in (xz(kn=1e-6), xz(normal=False)):
        r = HBMResidual(create_lumped(spec), h)
        U, _ = solve_newton(newton_system(r),
                            r.linear_solution(1.4), 1.4, x_scale=1.0, r_scale=0.8)
        sols.append(U)
    assert np.abs(sols[0] - sols[1]).max() < 1e-5 * np.abs(sols[1]).max()


def test_stiff_normal_spring_is_linear_and_well_scaled():
    """kn x 1e6 with N0 x 1e6 (the pair stays closed and stuck): the linear FRF with k_x = 2 and
    k_z = 3 + 1e6, whose z amplitude is 1e-6 of x's.  The per-DOF scaling keeps both to 1e-6."""
    frf = sweep(xz(kn=1e6, N0=1e6), 0.8, 2.4)
    assert (frf.states == STICK).all()
    np.testing.assert_allclose(frf.amplitude(0), linear_amplitude(frf.omega, 2.0, 0.3, c=0.05), rtol=1e-6)
    np.testing.assert_allclose(frf.amplitude(1), linear_amplitude(frf.omega, 3.0 + 1e6, 0.8, c=0.05), rtol=1e-6)


# ---- N0 = 0: the joint opens at once --------------------------------------------------------------

def test_zero_preload_without_normal_axis_is_two_independent_parts():
    """N0 = 0 and no normal axis: the pair never carries load, so mass a follows its own linear FRF
    (k = 1) and mass b, joined to a only by the pair and not forced, stays at rest."""
    spec = LumpedSpec(
        masses=(MassSpec("a", 1.0), MassSpec("b", 1.0)),
        springs=(LinkSpec("a.x", "ground", 1.0), LinkSpec("b.x", "ground", 2.0)),
        dampers=(LinkSpec("a.x", "ground", 0.02), LinkSpec("b.x", "ground", 0.02)),
        jenkins=(JenkinsSpec("a", "b", ("x",), None, kt=1.0, kn=0.0, mu=1.0, N0=0.0),),
        forces=(ForceSpec("a.x", 0.2),), outputs=("a.x", "b.x"))
    frf = sweep(spec, 0.5, 2.0)
    assert (frf.states == SEPARATED).all()
    np.testing.assert_allclose(frf.amplitude(0), linear_amplitude(frf.omega, 1.0, 0.2, c=0.02), rtol=1e-9)
    assert np.abs(frf.amplitude(1)).max() < 1e-12


def test_zero_preload_with_normal_axis_is_homogeneous_and_matches_time_integration():
    """N0 = 0: N = kn z carries load only in compression, so the pair is open about half of every
    period.  Every term of the equations is then positively homogeneous of degree 1 in the
    displacements (mu N scales with them), so doubling the forcing doubles the response exactly
    (checked to 1e-7); and forcing x 1e3 with the nominal N0 = 1 tends to it, with a relative
    difference of order N0 / (kn |z|) (measured 1.2e-3, checked below 1e-2).  At the peak, HBM (H = 15) is within
    1 % of RK4 time integration."""
    a = sweep(xz(N0=0.0), 0.8, 2.4, H=15, N=512)
    b = sweep(xz(Fx=0.6, Fz=1.6, N0=0.0), 0.8, 2.4, H=15, N=512)
    share = (a.states == SEPARATED).mean(axis=(1, 2))
    assert share.min() > 0.25 and share.max() < 0.75  # measured 0.37-0.69 (the mean of z shifts)
    for dof in (0, 1):
        pa, pb = a.amplitude(dof), b.amplitude(dof)
        assert pb[0] == pytest.approx(2 * pa[0], rel=1e-7)  # the same start point, scaled
        assert pb.max() == pytest.approx(2 * pa.max(), rel=1e-7)  # the scaled continuation takes the same steps
    big = sweep(xz(Fx=300.0, Fz=800.0, N0=1.0), 0.8, 2.4, H=15, N=512)
    for dof in (0, 1):
        assert big.amplitude(dof).max() / 1e3 == pytest.approx(a.amplitude(dof).max(), rel=1e-2)
    i = int(np.argmax(a.amplitude(1)))
    w = float(a.omega[i])
    system = dict(M=np.eye(2), K=np.diag([1.0, 3.0]), D=np.diag([0.05, 0.05]), fc=[0.3, 0.8], fs=[0.0, 0.0],
                  Gt=[[1.0, 0.0]], Gn=[[0.0, 1.0]], has_n=[True], kt=[1.0], kn=[1.0], mu=[0.5], N0=[0.0])
    ti, drift = steady_amplitudes(system, [w], periods=300, steps=4000)
    assert drift[0] < 1e-3
    hb = a.half_peak_to_peak(1)[i]
    assert hb == pytest.approx(ti[0, 1], rel=1e-2)


# ---- near-zero damping ---------------------------------------------------------------------------

def _df_bound(F, Fs=1.0, kt=1.0):
    """Undamped Jenkins oscillator under F < 4 Fs / pi: the energy balance pi F a sin(phi) =
    4 Fs (a - Fs / kt) bounds the amplitude by a* = 4 Fs (Fs / kt) / (4 Fs - pi F)."""
    return 4 * Fs * (Fs / kt) / (4 * Fs - np.pi * F)


@pytest.mark.parametrize("c", [0.0, 1e-9])
def test_resonance_held_only_by_friction(c):
    """c = 0 or 1e-9 and F = 0.2 < 4 Fs / pi: the stuck resonance (w = sqrt 2) would be infinite,
    but friction holds it.  H = 1 (the describing function, N = 2^14): the peak is the energy-
    balance bound a* = 1.18635 to 2e-4 (the branch is sampled, ds_max = 0.005); H = 7 moves it by
    less than 1 %."""
    one = sweep(sdof(0.2, c=c), 0.5, 2.0, H=1, N=2**14, ds_max=0.005)
    peak = one.amplitude(0).max()
    assert peak <= _df_bound(0.2) * (1 + 1e-5)
    assert peak == pytest.approx(_df_bound(0.2), rel=2e-4)
    seven = sweep(sdof(0.2, c=c), 0.5, 2.0, H=7, N=1024)
    assert seven.amplitude(0).max() == pytest.approx(_df_bound(0.2), rel=1e-2)


def test_undamped_resonance_beyond_friction_stops_clearly():
    """c = 0 and F = 2 > 4 Fs / pi: no bounded steady state near w = 1 (friction dissipates
    4 Fs a per cycle, the force inputs pi F a).  The sweep must not jump across the resonance onto
    the branch beyond it (it did, before the sign-flip rule); it climbs the resonance and stops
    with a ContinuationError that says the solution is growing without bound."""
    with pytest.raises(ContinuationError, match="growing without bound"):
        sweep(sdof(2.0, c=0.0), 0.5, 2.0, H=3, N=256, max_points=2000)


# ---- coincident and close resonances -------------------------------------------------------------

def rotor(F, *, ky=1.0, c=0.02, H=3, N=1024):
    spec = LumpedSpec(
        masses=(MassSpec("m", 1.0, ("x", "y")),),
        springs=(LinkSpec("m.x", "ground", 1.0), LinkSpec("m.y", "ground", ky)),
        dampers=(LinkSpec("m.x", "ground", c), LinkSpec("m.y", "ground", c)),
        jenkins=(JenkinsSpec("m", "ground", ("x", "y"), None, kt=1.0, kn=0.0, mu=1.0, N0=1.0),),
        forces=(ForceSpec("m.x", F), ForceSpec("m.y", F, np.pi / 2)), outputs=("m.x", "m.y"))
    return sweep(spec, 0.5, 2.0, H=H, N=N)


def circular_slip_amplitude(omega, F, c=0.02):
    """Closed form of the rotor (k = kt = Fs = m = 1) under a rotating force F e^{i w t}.
    Stuck: a = F / |2 - w^2 + i c w|.  In gross slip the slider moves on a circle b e^{i w t},
    lagging the mass by the spring stretch Fs / kt at right angles: a = b + i b / |b|, and
    |D (beta + i) + i| = F with D = 1 - w^2 + i c w gives |D|^2 beta^2 + 2 c w beta + |D + 1|^2
    - F^2 = 0.  The motion is one harmonic: H = 1 would be exact but for the AFT's sampling."""
    D = 1 - omega**2 + 1j * c * omega
    A, B, C = np.abs(D) ** 2, c * omega, np.abs(D + 1) ** 2 - F**2
    beta = (-B + np.sqrt(np.maximum(B**2 - A * C, 0.0))) / A
    return np.where(C < 0, np.sqrt(beta**2 + 1.0), F / np.abs(D + 1))


def test_coincident_resonances_circular_slip_closed_form():
    """kx = ky (coincident resonances) coupled only through the 2D friction law, F = 1 (gross
    slip up to 2.9x the stick limit).  Along the whole branch, both DOFs equal the closed form of
    circular slip, and the motion is one harmonic (harmonic 3 below 1e-10 of harmonic 1).  The
    sampled return mapping lags by O(1/N): measured 2.49e-2 at N = 256, 6.1e-3 at N = 1024 and
    1.5e-3 at N = 4096 (worst point, near w = 1.035), so the test asserts 1e-2 at N = 1024 and
    first-order convergence (ratio 4 +- 0.4 between N = 256 and 1024)."""
    errs = []
    for N in (256, 1024):
        frf = rotor(1.0, N=N)
        ref = circular_slip_amplitude(frf.omega, 1.0)
        assert ref.max() > 2.5  # gross slip is covered
        errs.append(max(np.abs(frf.amplitude(d) / ref - 1).max() for d in (0, 1)))
        assert frf.amplitude(0, 3).max() < 1e-10 * frf.amplitude(0).max()
    assert errs[1] < 1e-2
    assert errs[0] / errs[1] == pytest.approx(4.0, abs=0.4)


def test_close_resonance_with_separation_folds_and_matches_time_integration():
    """x (k + kt = 2) and z (kz + kn = 2) resonate at the same frequency; the z forcing opens the
    pair, which softens z and bends its peak over into two folds.  The branch must pass both
    folds (omega turns back exactly twice), never leave its neighbourhood (no consecutive points
    farther apart than the largest step), and, where the solution is unique, match RK4."""
    frf = sweep(xz(Fx=0.02, Fz=0.1, kn=1.0, kz=1.0, c=0.02), 0.8, 2.2, H=7, N=512, ds_max=0.05)
    dw = np.diff(frf.omega)
    turns = np.flatnonzero(np.diff(np.sign(dw)) != 0)
    assert turns.size == 2
    w_fold = np.sort(frf.omega[turns + 1])
    assert (frf.states == SEPARATED).any()
    # three solutions between the folds, on three distinct parts of the branch
    w_mid = w_fold.mean()
    crossings = np.flatnonzero(np.diff(np.sign(frf.omega - w_mid)) != 0)
    assert crossings.size == 3
    amps = frf.amplitude(1)[crossings]
    assert np.diff(np.sort(amps)).min() > 0.05 * amps.max()
    # unique solutions below and above the fold band: time integration from rest
    targets = [w_fold[0] - 0.1, w_fold[1] + 0.1]
    system = dict(M=np.eye(2), K=np.diag([1.0, 1.0]), D=np.diag([0.02, 0.02]), fc=[0.02, 0.1], fs=[0.0, 0.0],
                  Gt=[[1.0, 0.0]], Gn=[[0.0, 1.0]], has_n=[True], kt=[1.0], kn=[1.0], mu=[0.5], N0=[1.0])
    ti, drift = steady_amplitudes(system, targets, periods=400, steps=2000)
    assert drift.max() < 1e-3
    spec = xz(Fx=0.02, Fz=0.1, kn=1.0, kz=1.0, c=0.02)
    h = Harmonics(7, 512)
    hbm = HBMResidual(create_lumped(spec), h)
    fine = Harmonics(7, 4096)
    for w, t in zip(targets, ti[:, 1]):
        k = int(np.argmin(np.abs(frf.omega - w)))
        U, _ = solve_newton(newton_system(hbm), frf.U[k], w,
                            x_scale=np.abs(frf.U).max(axis=0) + 1e-12, r_scale=0.1)
        z = fine.to_time(U.reshape(h.num_hc, 2)[:, 1])
        # H = 7 against RK4 (first order at the contact events, dt = T / 2000): 1 %
        assert 0.5 * np.ptp(z) == pytest.approx(t, rel=1e-2)


# ---- H from 1 to 25, N from 2H + 1 to 4096 -------------------------------------------------------

def _solve_at(F, H, N, w=1.29):
    """Half peak-to-peak of the SDOF oscillator at fixed w (stick-slip near the peak), by Newton."""
    h = Harmonics(H, N)
    r = HBMResidual(create_lumped(sdof(F)), h)
    U, _ = solve_newton(newton_system(r),
                        0.8 * r.linear_solution(w), w, x_scale=1.0, r_scale=F)
    assert np.all(np.isfinite(U))
    return 0.5 * np.ptp(Harmonics(H, 2**14).to_time(U.reshape(h.num_hc, 1)[:, 0]))


def test_harmonics_and_samples_converge():
    """Against H = 25, N = 2^14 at w = 1.29 (F = 0.5, stick-slip): the odd harmonics carry the
    response (the even ones vanish by symmetry).  Measured relative errors at N = 4096:
    H = 1, 3, 5, 7, 9: 1.5e-3, 2.4e-4, 6.4e-5, 1.9e-5, 4.7e-6, then a floor of about 1e-6 (the
    N = 4096 sampling error).  So each odd H up to 9 must at least halve the error, and H >= 11
    stay below 5e-6.  Samples at H = 7 against N = 2^14: 6.7e-3 at the smallest N = 15, then
    1.9e-4, 7.3e-5, 1.3e-5, 3.9e-6, 1.2e-6, 1.4e-7 for N = 128 ... 4096 (must decrease)."""
    ref = _solve_at(0.5, 25, 2**14)
    err = {H: abs(_solve_at(0.5, H, 4096) / ref - 1) for H in (1, 3, 5, 7, 9, 11, 15, 25)}
    assert all(err[b] < 0.5 * err[a] for a, b in zip((1, 3, 5, 7), (3, 5, 7, 9)))
    assert max(err[H] for H in (11, 15, 25)) < 5e-6
    ref7 = _solve_at(0.5, 7, 2**14)
    assert abs(_solve_at(0.5, 7, 15) / ref7 - 1) < 1e-2
    errN = [abs(_solve_at(0.5, 7, N) / ref7 - 1) for N in (128, 256, 512, 1024, 2048, 4096)]
    assert all(b < a for a, b in zip(errN, errN[1:]))
    assert errN[-1] < 1e-6


# ---- rigid-body modes ----------------------------------------------------------------------------

def test_rigid_body_lumped_dof_is_refused_before_solving(tmp_path):
    """A mass held only by a Jenkins pair has an undetermined mean position once it slips: the
    scene is refused before any work, naming the file, the key and the DOF.  (Unclamped continua
    are refused the same way: tests/test_continuum.py.)"""
    from jointfem.scene import SceneError, check_solvable, load_scene

    text = (ROOT / "demos" / "sdof_jenkins.toml").read_text()
    text = text.replace('[[spring]]\nbetween = ["m.x", "ground"]\nk = 1.0\n', "")
    f = tmp_path / "free.toml"
    f.write_text(text)
    with pytest.raises(SceneError, match=r"free.toml: spring = 'm.x': DOF m.x has no path of linear springs"):
        check_solvable(load_scene(f))
    # through the command line: one line, exit code 2, nothing written
    import subprocess
    import sys
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "jointfem", "frf", str(f), "--out", str(out)], capture_output=True,
                       text=True)
    assert r.returncode == 2 and "rigid-body" in r.stderr and not out.exists()
