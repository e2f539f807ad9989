"""Contact laws behind one interface: the unilateral spring (jointfem/contact/unilateral.py, one
file and one registry entry) against finite differences, closed forms and a time integration,
solved through every problem of the protocol (full order, the penalty ROM, the exact
condensation) without any of them knowing which law it is."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.integrate import solve_ivp

from jointfem.analysis.frf import create_problem
from jointfem.contact import LAWS, ContactLaw, JenkinsPairs, UnilateralSprings
from jointfem.continuation.arclength import NewtonOptions, solve_newton
from jointfem.harmonics import Harmonics
from jointfem.hbm.problem import newton_system
from jointfem.models.structure import ContactGroup, Structure
from jointfem.rom import RomOptions, build_rom


def test_registry_names_every_law():
    from jointfem.contact import CubicSprings

    assert LAWS == {"jenkins": JenkinsPairs, "unilateral_spring": UnilateralSprings, "cubic_spring": CubicSprings}
    assert all(issubclass(law, ContactLaw) for law in LAWS.values())


def test_unilateral_aft_jacobian_matches_finite_differences():
    """dF/dG of the AFT against central differences (the law is piecewise linear: a difference
    of 1e-7 m crosses no sample's switch for this seed, so the two agree to round-off)."""
    h = Harmonics(4, 64)
    law = UnilateralSprings(k=[2.0e5, 3.0e4, 1.0e5], gap=[1e-4, 0.0, 5e-4])
    rng = np.random.default_rng(7)
    G = 4e-4 * rng.standard_normal((h.num_hc, 3, 1))
    res = law.aft(G, h)
    state = res.state_t
    assert (state == 0).any() and (state == 2).any()  # engaged and open samples: a real test
    J = res.J.reshape(3, h.num_hc, h.num_hc)
    d = 1e-7
    for p in range(3):
        for j in range(h.num_hc):
            Gp, Gm = G.copy(), G.copy()
            Gp[j, p, 0] += d
            Gm[j, p, 0] -= d
            fd = (law.aft(Gp, h, jacobian=False).F - law.aft(Gm, h, jacobian=False).F)[:, p, 0] / (2 * d)
            np.testing.assert_allclose(J[p, :, j], fd, rtol=0, atol=1e-6 * np.abs(J).max())
        # pairs do not couple
        other = [q for q in range(3) if q != p]
        Gp = G.copy()
        Gp[:, p, 0] += 1e-5
        np.testing.assert_array_equal(law.aft(Gp, h, jacobian=False).F[:, other], res.F[:, other])


def test_unilateral_limits_are_closed_forms():
    """Engaged at every sample with no gap: the linear spring (F = k G, nothing breaks).  Open at
    every sample: no force.  Half-wave: g = A cos tau with gap 0 gives the half-wave rectified
    cosine, whose first harmonic is k A / 2 and whose mean is k A / pi."""
    h = Harmonics(3, 256)
    k, A = 5.0e4, 1e-3
    law = UnilateralSprings(k=[k], gap=[0.0])
    G = np.zeros((h.num_hc, 1, 1))
    G[0], G[1], G[4] = 2e-3, 5e-4, 3e-4  # mean 2 mm, oscillation below 1 mm: always engaged
    res = law.aft(G, h)
    np.testing.assert_allclose(res.F, k * G, rtol=1e-12, atol=1e-15 * k)
    assert not law.linear_breaks(res.g_t, tol=1e-9).any() and not law.busy(res).any()
    far = UnilateralSprings(k=[k], gap=[5e-3])
    res = far.aft(G, h)
    assert np.abs(res.F).max() == 0.0 and (res.state_t == 2).all()
    assert far.linear_breaks(res.g_t, tol=1e-9).all()  # k g != 0 where the real spring is open
    G = np.zeros((h.num_hc, 1, 1))
    G[1] = A
    F = UnilateralSprings(k=[k], gap=[0.0]).aft(G, Harmonics(3, 4096), jacobian=False).F
    assert abs(F[1, 0, 0] - k * A / 2) < 1e-6 * k * A and abs(F[0, 0, 0] - k * A / np.pi) < 1e-6 * k * A
    assert abs(F[2, 0, 0]) < 1e-9 * k * A  # no sine part: the force is even in tau


def _oscillator(*, F=0.5, c=0.05, k2=3.0, gap=0.1):
    """Two masses on springs to ground, coupled by a spring; mass 1 forced, mass 2 hits a
    unilateral spring to ground (m = 1 kg, k = 1 N/m, Rayleigh-free dampers c N s/m)."""
    K = sp.csr_matrix(np.array([[2.0, -1.0], [-1.0, 2.0]]))
    M = sp.identity(2, format="csr")
    D = sp.csr_matrix(c * np.eye(2))
    law = UnilateralSprings(k=[k2], gap=[gap])
    group = ContactGroup(law, sp.csr_matrix(np.array([[0.0, 1.0]])), names=("stop",))
    return Structure(K=K, M=M, D=D, fc=np.array([F, 0.0]), fs=np.zeros(2), contacts=(group,),
                     dof_names=("m1.x", "m2.x"), outputs={"m1.x": 0})


def _solve(problem, omega):
    x0 = problem.initial_guess(omega)
    s = problem.scales(0.5, 1.0)
    x, _ = solve_newton(newton_system(problem), x0, omega, x_scale=s.x, r_scale=s.r,
                        options=NewtonOptions(tol=1e-12, max_iter=60), select=problem.unknowns())
    return x


def test_unilateral_spring_through_every_problem_and_against_time_integration():
    """The same periodic orbit from the full model, the penalty ROM with every mode (its active set
    found by the law's own linear-hold check) and the exact condensation, and against a time
    integration of the same equations (scipy's DOP853, started from the HBM orbit and run until
    its transient has decayed by e^-12)."""
    s = _oscillator()
    h = Harmonics(15, 512)
    omega = 0.7  # rad/s, below the first resonance (1 rad/s): the spring engages every period
    full = create_problem(s, h)
    U = _solve(full, omega)
    ev = full.evaluate(U, omega)
    rec = full.record(U, omega, ev)
    assert (rec.states == 0).any() and (rec.states == 2).any()
    # elastic: no loss, up to the trapezoid rule's error at the two samples around each switch,
    # O((2 pi / N)^2) of the spring's peak energy k (g - gap)^2 / 2
    law = s.contacts[0].pairs
    peak_energy = 0.5 * law.k[0] * (ev.contact[0].g_t.max() - law.gap[0]) ** 2
    assert rec.pair_summary.shape == (1, 3) and abs(rec.pair_summary[0, 0]) < (2 * np.pi / h.N) ** 2 * peak_energy
    assert rec.pair_summary[0, 2] == pytest.approx(law.k[0] * (ev.contact[0].g_t.max() - law.gap[0]), rel=1e-12)
    x1 = U.reshape(h.num_hc, 2)[:, 1]

    pen = create_problem(build_rom(s, "penalty", RomOptions(modes=2)), h)
    z = _solve(pen, omega)
    assert pen.violations(z).any()  # the stuck ROM breaks the law ...
    for _ in range(5):  # ... so the active set grows, as the continuation's after_converge does
        if not pen.after_converge(z, omega):
            break
        z = _solve(pen, omega)
    u_pen = z.reshape(h.num_hc, -1) @ pen.rom.T.T
    np.testing.assert_allclose(u_pen[:, 1], x1, atol=1e-9 * np.abs(x1).max())

    ex = create_problem(build_rom(s, "exact"), h)
    y = _solve(ex, omega).reshape(h.num_hc, -1)  # retained: the gap (u2 itself), then the output m1.x
    np.testing.assert_allclose(y[:, 0], x1, atol=1e-8 * np.abs(x1).max())
    np.testing.assert_allclose(y[:, 1], U.reshape(h.num_hc, 2)[:, 0], atol=1e-8 * np.abs(x1).max())

    # time integration of M u'' + D u' + K u + e2 f(u2) = F cos(omega t)
    K, D = s.K.toarray(), s.D.toarray()

    def rhs(t, y):
        u, v = y[:2], y[2:]
        f = np.array([0.5 * np.cos(omega * t), 0.0]) - K @ u - D @ v
        f[1] -= law.k[0] * max(u[1] - law.gap[0], 0.0)
        return np.concatenate([v, f])

    Uh = U.reshape(h.num_hc, 2)
    u0 = h.to_time(Uh)[0]
    v0 = omega * (h.derivative_matrix() @ Uh)
    v0 = h.to_time(v0)[0]
    T = 2 * np.pi / omega
    periods = int(np.ceil(12 / (0.05 / 2) / T))  # decay rate c/2m: e^-12 of any transient
    t_last = np.linspace((periods - 1) * T, periods * T, 513)[:-1]
    sol = solve_ivp(rhs, (0.0, periods * T), np.concatenate([u0, v0]), method="DOP853", rtol=1e-11, atol=1e-13,
                    t_eval=t_last)
    X = Harmonics(15, 512).from_time(sol.y[1])
    a_ti, a_hb = np.hypot(X[1], X[2]), np.hypot(x1[1], x1[2])
    # the orbit's first harmonic to 1e-4 (H = 15 truncates a force with a kink in its slope: the
    # k-th harmonic falls as 1/k^2)
    assert abs(a_hb / a_ti - 1) < 1e-4, (a_hb, a_ti)
    assert abs(X[0] - x1[0]) < 1e-4 * a_ti  # the mean offset the one-sided spring drives


def test_jenkins_energy_is_the_exact_slider_work_and_never_negative():
    """The energy per cycle is the friction force's work on the slider, sum f_(i+1) (w_(i+1) - w_i):
    the closed form 4 Fs (a - Fs / kt) of a Jenkins element under g = a cos(tau) to the sampling's
    O(step^2), exactly zero when stuck, and >= 0 (to round-off) on every pair of a stick-slip
    branch.  The trapezoid rule over the loop of g gave -1.5e-11 J on a pair of the beam."""
    from jointfem.contact.law import STICK

    h = Harmonics(3, 4096)
    law = JenkinsPairs(kt=[1.0, 1.0], kn=[0.0, 0.0], mu=[1.0, 1.0], N0=[1.0, 1.0], num_tangential=1,
                       has_normal=False)
    G = np.zeros((h.num_hc, 2, 1))
    G[1, 0, 0], G[1, 1, 0] = 3.0, 0.5  # gross slip, and a stuck pair (a < Fs / kt)
    res = law.aft(G, h)
    e = law.summary(res.f_t, res.g_t)[:, 0]
    assert e[0] == pytest.approx(4 * 1.0 * (3.0 - 1.0), rel=1e-5)
    assert (res.state_t[:, 1] == STICK).all() and e[1] == 0.0
    # also where w = g - f / kt does not come out exact: two tangential directions, a varying normal
    # load, stiffnesses that are not powers of two (the recovered w differed by round-off, which
    # showed as +-1e-23 J on the beam's stuck pairs)
    law3 = JenkinsPairs(kt=[3.7e4], kn=[1.3e6], mu=[0.3], N0=[20.0], num_tangential=2, has_normal=True)
    G3 = np.zeros((h.num_hc, 1, 3))
    G3[1, 0] = [1.1e-5, -0.7e-5, 2.3e-6]
    G3[2, 0] = [0.3e-5, 0.2e-5, -0.9e-6]
    res3 = law3.aft(G3, h)
    assert (res3.state_t == STICK).all() and law3.summary(res3.f_t, res3.g_t)[0, 0] == 0.0
    # a branch of the SDOF oscillator through stick and slip: every point's energy >= 0
    from conftest import sdof
    from jointfem.analysis.frf import SweepOptions, compute_frf
    from jointfem.models.lumped import create_lumped

    frf = compute_frf(create_lumped(sdof(0.5)), SweepOptions(0.5, 2.0, Harmonics(7, 128), stability=False))
    E = frf.info["arrays"]["pair_energy_J"]
    assert (frf.states == 1).any() and E.max() > 0.1
    assert E.min() >= -1e-12 * E.max()
