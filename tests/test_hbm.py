"""Harmonic balance: layout, residual Jacobian (FD), and solutions against independent references:
the closed-form linear FRF, the Jenkins describing function, and time integration."""
import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

from jointfem.continuation.arclength import ContinuationOptions, solve_newton
from jointfem.contact.jenkins import SEPARATED, SLIP
from jointfem.analysis.frf import SweepOptions, compute_frf
from jointfem.hbm.forced import compute_scales
from jointfem.hbm.problem import newton_system
from jointfem.harmonics import Harmonics
from jointfem.hbm.residual import HBMResidual
from jointfem.models.lumped import ForceSpec, JenkinsSpec, LinkSpec, LumpedSpec, MassSpec, create_lumped
from conftest import linear_amplitude, sdof  # sdof: the m = k = kt = Fs = 1 Jenkins oscillator
from reference_timeint import steady_amplitudes


def test_transform_pair_and_derivative():
    h = Harmonics(4, 16)
    rng = np.random.default_rng(0)
    X = rng.normal(size=(h.num_hc, 3))
    np.testing.assert_allclose(h.from_time(h.to_time(X)), X, atol=1e-14)
    np.testing.assert_allclose(h.to_time(X), h.gamma @ X, atol=1e-13)
    np.testing.assert_allclose(h.gamma_inv @ h.gamma, np.eye(h.num_hc), atol=1e-14)
    # d/dtau in coefficient space equals the derivative of the samples
    tau = h.tau
    x = h.gamma @ X[:, 0]
    dx = sum(k * (-X[h.block_cos(k), 0] * np.sin(k * tau) + X[h.block_sin(k), 0] * np.cos(k * tau))
             for k in range(1, h.H + 1))
    np.testing.assert_allclose(h.gamma @ (h.derivative_matrix() @ X[:, 0]), dx, atol=1e-12)
    # the synthesis is the series itself, sample by sample (which also fixes x's shape, (N,))
    series = X[0, 0] + sum(X[h.block_cos(k), 0] * np.cos(k * tau) + X[h.block_sin(k), 0] * np.sin(k * tau)
                           for k in range(1, h.H + 1))
    np.testing.assert_allclose(x, series, rtol=0, atol=1e-13)
    with pytest.raises(ValueError, match="2H\\+1"):
        Harmonics(4, 8)


def two_dof(Fx=0.3, Fz=0.8):
    """One mass, tangential x and normal z, Jenkins to ground with N = N0 + kn z."""
    return LumpedSpec(
        masses=(MassSpec("m", 1.0, ("x", "z")),),
        springs=(LinkSpec("m.x", "ground", 1.0), LinkSpec("m.z", "ground", 3.0)),
        dampers=(LinkSpec("m.x", "ground", 0.05), LinkSpec("m.z", "ground", 0.05)),
        jenkins=(JenkinsSpec("m", "ground", ("x",), "z", kt=1.0, kn=1.0, mu=0.5, N0=1.0),),
        forces=(ForceSpec("m.x", Fx), ForceSpec("m.z", Fz)), outputs=("m.x", "m.z"))


@pytest.mark.parametrize("dense", [False, True])
def test_residual_jacobian_matches_finite_differences(dense):
    s = create_lumped(two_dof())
    h = Harmonics(3, 64)
    hbm = HBMResidual(s, h, dense=dense)
    rng = np.random.default_rng(2)
    U = hbm.linear_solution(1.9) + 0.05 * rng.normal(size=hbm.num_unknowns)
    ev = hbm.evaluate(U, 1.9)
    states = np.bincount(ev.contact[0].state_t.ravel(), minlength=3)
    assert states[SLIP] > 0 and states[SEPARATED] > 0
    eps = 1e-7
    J_fd = np.column_stack([(hbm.evaluate(U + eps * e, 1.9, jacobian=False).R
                             - hbm.evaluate(U - eps * e, 1.9, jacobian=False).R) / (2 * eps)
                            for e in np.eye(U.size)])
    J = ev.J if dense else ev.J.toarray()
    assert isinstance(ev.J, np.ndarray) == dense
    assert np.abs(J - J_fd).max() <= 1e-6 * np.abs(J_fd).max()
    dw = (hbm.evaluate(U, 1.9 + eps, jacobian=False).R - hbm.evaluate(U, 1.9 - eps, jacobian=False).R) / (2 * eps)
    np.testing.assert_allclose(ev.dR_dlam, dw, atol=1e-7 * np.abs(dw).max())


def test_dense_and_sparse_residuals_agree_with_several_pairs():
    """The dense path contracts the per-pair AFT blocks with G and L (P m, n) directly; the sparse
    path multiplies the Kronecker matrices.  With two 2D pairs on two coupled masses, slipping
    and separating, R and J agree to 1e-12 of their size (round-off of different orders of
    summation)."""
    spec = LumpedSpec(
        masses=(MassSpec("a", 1.0, ("x", "z")), MassSpec("b", 2.0, ("x", "z"))),
        springs=(LinkSpec("a.x", "ground", 1.0), LinkSpec("a.z", "ground", 3.0), LinkSpec("b.x", "ground", 2.0),
                 LinkSpec("b.z", "ground", 1.0), LinkSpec("a.x", "b.x", 0.5), LinkSpec("a.z", "b.z", 0.7)),
        dampers=(LinkSpec("a.x", "ground", 0.05), LinkSpec("b.z", "ground", 0.05)),
        jenkins=(JenkinsSpec("a", "ground", ("x",), "z", kt=1.0, kn=1.0, mu=0.5, N0=1.0),
                 JenkinsSpec("a", "b", ("x",), "z", kt=2.0, kn=3.0, mu=0.3, N0=0.5)),
        forces=(ForceSpec("a.x", 0.3), ForceSpec("b.z", 0.8)), outputs=("a.x",))
    s = create_lumped(spec)
    h = Harmonics(3, 64)
    sparse, dense = HBMResidual(s, h, dense=False), HBMResidual(s, h, dense=True)
    U = sparse.linear_solution(1.3) * 4 + 0.05 * np.random.default_rng(5).normal(size=sparse.num_unknowns)
    es, ed = sparse.evaluate(U, 1.3), dense.evaluate(U, 1.3)
    st = np.concatenate([c.state_t.ravel() for c in es.contact])
    assert (st == SLIP).any() and (st == SEPARATED).any()
    np.testing.assert_allclose(ed.R, es.R, atol=1e-12 * np.abs(es.R).max())
    np.testing.assert_allclose(ed.J, es.J.toarray(), atol=1e-12 * np.abs(ed.J).max())


def test_linear_limit_equals_closed_form_frf():
    """At 1e-6 of the nominal forcing the joint never slips: |X| = F / |k + kt - m w^2 + i c w|."""
    F = 0.2e-6
    s = create_lumped(sdof(F))
    frf = compute_frf(s, SweepOptions(0.5, 2.0, Harmonics(5, 64)))
    assert (frf.states == 0).all()
    w = frf.omega
    closed = linear_amplitude(w, 2.0, F, c=0.02)
    np.testing.assert_allclose(frf.amplitude(0), closed, rtol=1e-8)
    # the other harmonics stay zero
    U = frf.U.reshape(frf.num_points, -1)
    assert np.abs(U[:, [0, 3, 4]]).max() <= 1e-8 * closed.max()


def describing_function_force(a, w, *, c=0.02):
    """Force amplitude that gives first-harmonic amplitude a at w under the describing function."""
    a = np.asarray(a)
    beta = np.arccos(np.clip(1 - 2 / a, -1, 1))
    slip = a > 1
    c1 = np.where(slip, a / np.pi * (beta - np.sin(2 * beta) / 2), a)
    s1 = np.where(slip, -4 / np.pi * (1 - 1 / np.where(slip, a, 2)), 0.0)
    return np.hypot(a - w**2 * a + c1, c * w * a - s1)


@pytest.mark.parametrize("F", [0.05, 0.2, 0.5])
def test_sdof_one_harmonic_is_the_describing_function(F):
    """With H = 1 every point satisfies the describing-function balance.  The sampled slider
    misses the velocity reversal between samples by O(a dtau^2) (9e-6 at N = 2048), so
    N = 2^16 is used to bring the AFT error to about 1e-8 against the 1e-6 tolerance."""
    s = create_lumped(sdof(F))
    frf = compute_frf(s, SweepOptions(0.5, 2.0, Harmonics(1, 2**16)))
    a = frf.amplitude(0)
    assert (a > 1).any()  # the sweep goes through slip
    np.testing.assert_allclose(describing_function_force(a, frf.omega), F, rtol=1e-6)


@pytest.mark.parametrize("F", [0.05, 0.2, 0.5])
def test_sdof_harmonic_balance_matches_time_integration(F):
    """H = 7: peak amplitude and frequency within 0.5 % of RK4 run to steady state from rest."""
    s = create_lumped(sdof(F))
    opts = SweepOptions(1.0, 1.7, Harmonics(7, 512), ContinuationOptions(ds_max=0.01))
    frf = compute_frf(s, opts)
    amp = frf.half_peak_to_peak(0)
    i = int(np.argmax(amp))
    sel = slice(max(i - 3, 0), i + 4)
    w_sel = frf.omega[sel]
    assert np.all(np.diff(w_sel) > 0)
    system = dict(M=[[1.0]], K=[[1.0]], D=[[0.02]], fc=[F], fs=[0.0], Gt=[[1.0]], Gn=[[0.0]], has_n=[False],
                  kt=[1.0], kn=[0.0], mu=[1.0], N0=[1.0])
    ti, drift = steady_amplitudes(system, w_sel, periods=400, steps=2000)
    assert drift.max() < 1e-5  # steady state reached
    np.testing.assert_allclose(amp[sel], ti[:, 0], rtol=5e-3)

    def peak(w, a):
        k = int(np.argmax(a))
        k = min(max(k, 1), len(a) - 2)
        c = np.polyfit(w[k - 1:k + 2] - w[k], a[k - 1:k + 2], 2)
        dw = -c[1] / (2 * c[0])
        return w[k] + dw, np.polyval(c, dw)

    w_h, a_h = peak(w_sel, amp[sel])
    w_t, a_t = peak(w_sel, ti[:, 0])
    assert w_h == pytest.approx(w_t, rel=5e-3)
    assert a_h == pytest.approx(a_t, rel=5e-3)


def test_variable_normal_load_with_separation_matches_time_integration():
    """2 DOF, N = N0 + kn z passes through zero: the sweep converges everywhere, and at three
    frequencies (stick-slip, slip, separation) HBM (H = 15) is within 1 % of time integration."""
    spec = two_dof()
    s = create_lumped(spec)
    h = Harmonics(15, 512)
    frf = compute_frf(s, SweepOptions(0.8, 2.4, h, ContinuationOptions(ds_max=0.02)))
    assert frf.omega[-1] >= 2.4
    sep = (frf.states == SEPARATED).any(axis=(1, 2))
    assert sep.any() and not sep.all()
    hbm = HBMResidual(s, h)
    targets = [1.2, 1.45, 2.0]
    U_t = []
    dof_scale = np.tile(compute_scales(s, 0.8, 2.4), h.num_hc)
    for w in targets:
        k = int(np.argmin(np.abs(frf.omega - w)))
        U, _ = solve_newton(newton_system(hbm), frf.U[k], w,
                            x_scale=dof_scale, r_scale=0.8)
        U_t.append(U)
    states = [hbm.evaluate(U, w, jacobian=False).contact[0].state_t for U, w in zip(U_t, targets)]
    assert (states[2] == SEPARATED).any()
    assert (states[0] == SLIP).any() or (states[1] == SLIP).any()
    fine = Harmonics(15, 4096)
    hb = np.array([[0.5 * np.ptp(fine.to_time(U.reshape(h.num_hc, 2)[:, j])) for j in range(2)] for U in U_t])
    system = dict(M=np.eye(2), K=np.diag([1.0, 3.0]), D=np.diag([0.05, 0.05]), fc=[0.3, 0.8], fs=[0.0, 0.0],
                  Gt=[[1.0, 0.0]], Gn=[[0.0, 1.0]], has_n=[True], kt=[1.0], kn=[1.0], mu=[0.5], N0=[1.0])
    ti, drift = steady_amplitudes(system, targets, periods=300, steps=4000)
    assert drift.max() < 1e-5
    np.testing.assert_allclose(hb, ti, rtol=1e-2)


def test_downward_sweep_gives_the_same_curve():
    s = create_lumped(sdof(0.2))
    h = Harmonics(3, 256)
    up = compute_frf(s, SweepOptions(1.0, 1.8, h))
    down = compute_frf(s, SweepOptions(1.8, 1.0, h))
    assert down.omega[0] == 1.8 and down.omega[-1] <= 1.0
    (w_up, a_up), (w_dn, a_dn) = up.peak("m.x"), down.peak("m.x")
    assert a_up == pytest.approx(a_dn, rel=2e-3)  # parabola through the three top points of each
    assert w_up == pytest.approx(w_dn, rel=2e-3)
    # every downward point solves the same equations
    hbm = HBMResidual(s, h)
    res = [np.abs(hbm.evaluate(U, w, jacobian=False).R).max() for U, w in zip(down.U, down.omega)]
    assert max(res) <= 1e-8 * 0.2


def test_solve_at_one_frequency_is_the_branch_point():
    """jointfem.solve_at: stuck (F = 0.01) it is the linear response |F / (k + kt - w^2 + i c w)|;
    slipping (F = 0.5) from the branch's own point as guess it returns that point (1e-9), and from
    the linear guess below the fold it finds the same solution."""
    import jointfem
    from conftest import sdof
    from jointfem.analysis.frf import SweepOptions, compute_frf
    from jointfem.harmonics import Harmonics
    from jointfem.models.lumped import create_lumped

    h = Harmonics(7, 256)
    s = create_lumped(sdof(0.01))
    sol = jointfem.solve_at(s, 1.2, h)
    assert sol.amplitudes["m.x"] == pytest.approx(0.01 / abs(2.0 - 1.44 + 0.02j * 1.2), rel=1e-10)
    assert (sol.record.states == 0).all() and sol.residual < 1e-10
    s = create_lumped(sdof(0.5))
    frf = compute_frf(s, SweepOptions(0.5, 2.0, h, stability=False))
    k = int(np.argmin(np.abs(frf.omega - 1.45)))  # past the peak (1.29 rad/s), slipping
    assert frf.amplitude(0)[k] > 1.0  # beyond Fs / kt: the pair slips
    sol = jointfem.solve_at(s, float(frf.omega[k]), h, guess=frf.U[k])
    np.testing.assert_allclose(sol.U, frf.U[k], rtol=0, atol=1e-9 * np.abs(frf.U[k]).max())
    assert (sol.record.states == 1).any()
    assert jointfem.solve_at(s, float(frf.omega[k]), h).amplitudes["m.x"] == pytest.approx(
        frf.amplitude(0)[k], rel=1e-8)
    modes = jointfem.linear_modes(s, 1)
    assert modes["stuck"]["omega_rad_s"][0] == pytest.approx(np.sqrt(2.0), rel=1e-12)
