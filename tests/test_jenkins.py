"""Jenkins contact law and its AFT: closed forms, invariants, exact Jacobian (FD), reference twin."""
import numpy as np
import pytest

from jointfem.contact.jenkins import (SEPARATED, SLIP, STICK, JenkinsPairs, compute_aft, compute_dissipation)
from jointfem.harmonics import Harmonics
from reference_jenkins import compute_aft_reference


def _one(kt=1.0, Fs=1.0):
    return JenkinsPairs(kt=[kt], kn=[0.0], mu=[1.0], N0=[Fs])


def _cos_gap(h, a):
    G = np.zeros((h.num_hc, 1, 1))
    G[h.block_cos(1), 0, 0] = a
    return G


@pytest.mark.parametrize("a", [1.2, 3.0, 10.0])
def test_describing_function_and_dissipation(a):
    """x = a cos(tau): c1 = (kt a/pi)(beta - sin(2 beta)/2), s1 = -(4 Fs/pi)(1 - Fs/(kt a)),
    W = 4 Fs (a - Fs/kt).  The sampled force is exact at the samples (reversals fall on samples
    for even N), so the only error is the aliasing of a kinked periodic force, O(N^-2):
    N = 4096 gives about 1e-7."""
    kt, Fs = 2.0, 1.5
    a = a * Fs / kt
    h = Harmonics(3, 4096)
    r = compute_aft(_one(kt, Fs), _cos_gap(h, a), h)
    beta = np.arccos(1 - 2 * Fs / (kt * a))
    c1 = kt * a / np.pi * (beta - np.sin(2 * beta) / 2)
    s1 = -4 * Fs / np.pi * (1 - Fs / (kt * a))
    assert r.F[h.block_cos(1), 0, 0] == pytest.approx(c1, rel=1e-6)
    assert r.F[h.block_sin(1), 0, 0] == pytest.approx(s1, rel=1e-6)
    W = compute_dissipation(r.f_t, r.g_t)[0]
    assert W == pytest.approx(4 * Fs * (a - Fs / kt), rel=1e-6)
    # Corners of the loop: the force never exceeds Fs and reaches it.
    assert np.abs(r.f_t).max() == pytest.approx(Fs, rel=1e-12)


def test_below_slip_is_exactly_linear():
    kt, Fs = 2.0, 1.5
    h = Harmonics(5, 64)
    a = 0.999 * Fs / kt
    r = compute_aft(_one(kt, Fs), _cos_gap(h, a), h)
    expected = np.zeros(h.num_hc)
    expected[h.block_cos(1)] = kt * a
    np.testing.assert_allclose(r.F[:, 0, 0], expected, rtol=0, atol=1e-14 * kt * a)
    assert (r.state_t == STICK).all()
    J = r.J[0, :, 0, :, 0]
    np.testing.assert_allclose(J, kt * np.eye(h.num_hc), atol=1e-12 * kt)


def test_2d_gross_slip_circle_has_constant_force_magnitude():
    """g_t on a large circle: the slider trails, |f_t| = mu N at every sample (radial return)."""
    h = Harmonics(2, 256)
    p = JenkinsPairs(kt=[3.0], kn=[0.0], mu=[0.4], N0=[2.0], num_tangential=2)
    G = np.zeros((h.num_hc, 1, 2))
    G[h.block_cos(1), 0, 0] = 5.0
    G[h.block_sin(1), 0, 1] = 5.0
    r = compute_aft(p, G, h)
    mag = np.linalg.norm(r.f_t[:, 0, :], axis=1)
    np.testing.assert_allclose(mag, 0.8, rtol=1e-10)
    assert (r.state_t == SLIP).all()
    # Energy per cycle: the force, of magnitude Fs = mu N = 0.8 along the slider's velocity, works
    # along the slider's circle.  The spring stretch s = Fs / kt is tangent to that circle (the
    # slider trails the gap at right angles to its radius), so its radius is sqrt(R^2 - s^2) and
    # W = 2 pi Fs sqrt(R^2 - s^2) (R = 5: 25.097; not R - s, 23.792).  Sampled, the return mapping
    # puts the slider on the chord through consecutive gaps, a circle smaller by about s sin(pi / N)
    # (first order in 1/N: -6.6e-4 relative at N = 256), and the loop integral's trapezoid rule adds
    # O(N^-2): measured -8.3e-4 at N = 256 (-4.2e-5 at N = 4096), so 2e-3 below, never above.
    W = compute_dissipation(r.f_t, r.g_t)[0]
    Fs, s = 0.8, 0.8 / 3.0
    W_circle = 2 * np.pi * Fs * np.sqrt(5.0**2 - s**2)
    assert W_circle * (1 - 2e-3) < W < W_circle


def test_separation_zeroes_every_force():
    h = Harmonics(1, 64)
    p = JenkinsPairs(kt=[1.0], kn=[10.0], mu=[0.5], N0=[1.0], num_tangential=2, has_normal=True)
    G = np.zeros((h.num_hc, 1, 3))
    G[0, 0, 2] = -0.5  # static opening: N0 + kn g_n = -4 < 0 always
    G[h.block_cos(1), 0, 0] = 0.3
    r = compute_aft(p, G, h)
    assert (r.state_t == SEPARATED).all()
    assert np.abs(r.f_t).max() == 0.0
    assert np.abs(r.J).max() == 0.0


def _random_case(nt, has_normal, P=7, seed=0, H=3, N=64, amp=0.7):
    rng = np.random.default_rng(seed)
    h = Harmonics(H, N)
    p = JenkinsPairs(kt=rng.uniform(1, 2, P), kn=rng.uniform(1, 3, P), mu=rng.uniform(0.2, 0.6, P),
                     N0=rng.uniform(0.5, 1.5, P), num_tangential=nt, has_normal=has_normal)
    G = rng.normal(size=(h.num_hc, P, p.num_comp)) * amp / (1 + h.orders)[:, None, None]
    return p, G, h


def _fd_jacobian(p, G, h, eps=1e-7):
    J = np.zeros((p.num_pairs, h.num_hc, p.num_comp, h.num_hc, p.num_comp))
    for k in range(h.num_hc):
        for b in range(p.num_comp):
            Gp, Gm = G.copy(), G.copy()
            Gp[k, :, b] += eps
            Gm[k, :, b] -= eps
            dF = (compute_aft(p, Gp, h, jacobian=False).F - compute_aft(p, Gm, h, jacobian=False).F) / (2 * eps)
            J[:, :, :, k, b] = np.moveaxis(dF, 1, 0)
    return J


@pytest.mark.parametrize("nt,has_normal", [(1, False), (1, True), (2, False), (2, True)])
@pytest.mark.parametrize("amp", [0.25, 0.7])
def test_jacobian_matches_finite_differences(nt, has_normal, amp):
    """Central differences, eps = 1e-7: truncation ~eps^2 and round-off ~1e-16/eps, so 1e-6
    relative to the largest entry is a safe bound away from a sample switching state."""
    p, G, h = _random_case(nt, has_normal, amp=amp)
    r = compute_aft(p, G, h)
    states = np.bincount(r.state_t.ravel(), minlength=3)
    assert states[SLIP] > 0  # the case exercises slip
    if has_normal and amp > 0.5:
        assert states[SEPARATED] > 0
    J_fd = _fd_jacobian(p, G, h)
    assert np.abs(r.J - J_fd).max() <= 1e-6 * np.abs(J_fd).max()


def test_shakedown_pair_jacobian():
    """A pair that slips in its first period and then sticks for good: its slider position, and
    so its force, depends on the gap through the transient (caught at a beam point by FD)."""
    h = Harmonics(2, 128)
    p = JenkinsPairs(kt=[1.0], kn=[4.0], mu=[0.3], N0=[1.0], num_tangential=1, has_normal=True)
    G = np.zeros((h.num_hc, 1, 2))
    G[0, 0, 0] = 0.6  # static tangential offset: slips once from w = 0 ...
    G[h.block_cos(1), 0, 0] = 0.05  # ... then the small oscillation fits inside the cone
    G[h.block_cos(1), 0, 1] = 0.02
    r = compute_aft(p, G, h)
    assert (r.state_t == STICK).all() and abs(r.w_start[0, 0]) > 0
    J_fd = _fd_jacobian(p, G, h)
    assert np.abs(r.J - J_fd).max() <= 1e-6 * np.abs(J_fd).max()


@pytest.mark.parametrize("nt,has_normal", [(1, False), (1, True), (2, False), (2, True)])
def test_compiled_kernel_matches_numpy_reference(nt, has_normal):
    p, G, h = _random_case(nt, has_normal, P=9, seed=3, H=4, N=96)
    r = compute_aft(p, G, h)
    ref = compute_aft_reference(p, G, h)
    np.testing.assert_allclose(r.F, ref.F, atol=1e-13 * np.abs(ref.F).max())
    np.testing.assert_array_equal(r.state_t, ref.state_t)
    assert np.abs(r.J - ref.J).max() <= 1e-11 * np.abs(ref.J).max()


def test_recontact_choice_depends_on_rates_not_on_the_first_contact_load():
    """After a separation the slider restarts where N crosses zero between two samples, so at the
    first contact sample kt (g_t - w) / (mu N) = kt g_t' / (mu N') whatever the size of that first
    load.  Moving the crossing through one sample interval (by N0) must not flip the state there;
    with the slider at the last separated sample it did, and stalled the beam's continuation."""
    h = Harmonics(3, 64)
    dtau = 2 * np.pi / h.N
    states = []
    for shift in np.linspace(0.05, 0.95, 19):
        # g_n = -cos(tau) - c: N = N0 + kn g_n crosses zero at tau_c; choose N0 so that the
        # crossing sits a fraction `shift` into the interval before sample 10.
        tau_c = (10 - shift) * dtau
        N0 = 1.0 * np.cos(tau_c)
        p = JenkinsPairs(kt=[1.0], kn=[1.0], mu=[0.3], N0=[N0], num_tangential=1, has_normal=True)
        G = np.zeros((h.num_hc, 1, 2))
        G[h.block_cos(1), 0, 1] = -1.0  # N = N0 - cos(tau): open around tau = 0
        G[h.block_sin(1), 0, 0] = 0.2  # tangential motion through the re-contact
        r = compute_aft(p, G, h)
        assert r.state_t[9, 0] == SEPARATED and r.state_t[10, 0] != SEPARATED
        states.append(int(r.state_t[10, 0]))
    assert len(set(states)) == 1, states


def test_pair_ratcheting_into_shakedown_converges():
    """A 2D pair whose plain periods converge only geometrically (ratio 0.81) towards a
    shakedown: Newton on the period map overshoots into the stick region, so the search follows
    the plain path.  Found in the 1,000-pair benchmark (pair 700 of this generator)."""
    rng = np.random.default_rng(0)
    h = Harmonics(5, 256)
    P = 1000
    for amp in (0.7, 0.2):
        kt, kn, mu, N0 = (rng.uniform(1, 2, P), rng.uniform(1, 3, P), rng.uniform(0.2, 0.6, P),
                          rng.uniform(0.5, 1.5, P))
        G = rng.normal(size=(h.num_hc, P, 3)) * amp / np.arange(1, 12)[:, None, None]
    k = 700
    p = JenkinsPairs(kt=kt[k:k + 1], kn=kn[k:k + 1], mu=mu[k:k + 1], N0=N0[k:k + 1], num_tangential=2,
                     has_normal=True)
    Gk = G[:, k:k + 1]
    r = compute_aft(p, Gk, h)  # used to raise ContactError after 50 periods
    ref = compute_aft_reference(p, Gk, h)
    np.testing.assert_allclose(r.F, ref.F, atol=1e-9 * np.abs(ref.F).max())
    np.testing.assert_allclose(r.w_start, ref.w_start, atol=1e-9)
    # The limit sits on the boundary of the stick region, where the steady state is not
    # differentiable (finite differences of either side disagree), so no FD check here.


@pytest.mark.parametrize("has_normal", [False, True])
def test_steady_slider_closes_below_the_search_tolerance(has_normal):
    """The slider state returned closes its period far below the search's rtol (1e-10 of the
    scale): with 2D slip the fixed point is found by Newton, and the iterate that first meets
    rtol is stepped once more.  An error of rtol * scale in w passes through kt into the forces:
    on the 25-pair lap joint it held the HBM residual at 1.1e-10 of its scale, just above the
    Newton tolerance, and cost every corrector two more iterations."""
    from reference_jenkins import _march

    p, G, h = _random_case(2, has_normal, P=40, seed=5, H=3, N=128)
    r = compute_aft(p, G, h, jacobian=False)
    worst = 0.0
    for k in range(p.num_pairs):
        one = JenkinsPairs(kt=p.kt[k:k + 1], kn=p.kn[k:k + 1], mu=p.mu[k:k + 1], N0=p.N0[k:k + 1],
                           num_tangential=2, has_normal=has_normal)
        g = r.g_t[:, k:k + 1]
        _, state_t, w_end, _ = _march(one, g, r.w_start[k:k + 1])
        if (state_t == SLIP).any():
            scale = max(p.mu[k] * p.N0[k] / p.kt[k], np.abs(g[:, :, :2]).max())
            worst = max(worst, np.abs(w_end - r.w_start[k:k + 1]).max() / scale)
    assert 0.0 < worst <= 1e-13


def test_kernels_run_on_openmp_not_tbb():
    """The prange loops run on numba's OpenMP layer unless the user chose one: a whole suite once
    hung at exit in numba's TBB finalize (jointfem/contact/_threading.py).  A fresh interpreter,
    because the layer is fixed by the first parallel call of a process."""
    import os
    import subprocess
    import sys

    try:
        from numba.np.ufunc import omppool  # noqa: F401
    except ImportError:
        pytest.skip("numba has no OpenMP layer here")
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_THREADING_LAYER")}
    code = ("import numpy as np; from jointfem.contact.jenkins import JenkinsPairs, compute_aft; "
            "from jointfem.harmonics import Harmonics; import numba; h = Harmonics(1, 16); "
            "G = np.zeros((h.num_hc, 1, 1)); G[h.block_cos(1), 0, 0] = 3.0; "
            "compute_aft(JenkinsPairs(kt=[1.0], kn=[0.0], mu=[1.0], N0=[1.0]), G, h); "
            "print(numba.threading_layer())")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "omp"
