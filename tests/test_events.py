"""The event-accurate Jenkins AFT (jointfem.contact._events): closed forms, its Jacobian against
finite differences, the limit of the sampled law, exact linear and separated pairs, and the scene
key that selects it."""
from dataclasses import replace

import numpy as np
import pytest

from conftest import sdof
from jointfem.analysis.frf import SweepOptions, compute_frf
from jointfem.contact.jenkins import SEPARATED, SLIP, STICK, JenkinsPairs, compute_aft
from jointfem.harmonics import Harmonics
from jointfem.models.lumped import create_lumped
from jointfem.models.structure import with_event_aft
from jointfem.scene import SceneError, parse_scene
from test_jenkins import _cos_gap, _fd_jacobian, _random_case


@pytest.mark.parametrize("a", [1.2, 3.0, 10.0])
def test_describing_function_to_round_off_with_64_samples(a):
    """x = a cos(tau) through one slider: c1 = (kt a/pi)(beta - sin(2 beta)/2),
    s1 = -(4 Fs/pi)(1 - Fs/(kt a)).  The sampled law needs N = 4096 for 1e-6; with the reversals and
    slip onsets located between samples and the pieces integrated exactly, N = 64 gives 3e-13
    (measured; 1.5e-8 at N = 16 for a = 10, where the interpolant locates the onset to O(N^-4))."""
    kt, Fs = 2.0, 1.5
    a = a * Fs / kt
    h = Harmonics(3, 64)
    r = compute_aft(JenkinsPairs(kt=[kt], kn=[0.0], mu=[1.0], N0=[Fs], events=True), _cos_gap(h, a), h)
    beta = np.arccos(1 - 2 * Fs / (kt * a))
    c1 = kt * a / np.pi * (beta - np.sin(2 * beta) / 2)
    s1 = -4 * Fs / np.pi * (1 - Fs / (kt * a))
    assert r.F[h.block_cos(1), 0, 0] == pytest.approx(c1, rel=1e-10)
    assert r.F[h.block_sin(1), 0, 0] == pytest.approx(s1, rel=1e-10)
    # odd harmonics only, by the half-wave symmetry of the loop
    assert np.abs(r.F[h.cos(2, 1)]).max() < 1e-12 * abs(c1)


@pytest.mark.parametrize("has_normal", [False, True])
@pytest.mark.parametrize("amp", [0.25, 2.0])
def test_jacobian_matches_finite_differences(has_normal, amp):
    """Central differences, eps = 1e-6 (truncation and round-off below 1e-8 of the largest entry).
    The Jacobian leaves out only the force's jump at a switch located on the cubic interpolant
    times d tau/dG, O(N^-4): 2e-5 at N = 64, 7e-8 at N = 256, 3e-8 (the FD floor) at N = 1024
    (measured over 9 random cases), hence 2e-7 at N = 256."""
    p, G, h = _random_case(1, has_normal, amp=amp, N=256)
    p = replace(p, events=True)
    r = compute_aft(p, G, h)
    states = np.bincount(r.state_t.ravel(), minlength=3)
    assert states[SLIP] > 0 and states[STICK] > 0
    if has_normal and amp > 1:
        assert states[SEPARATED] > 0
    J_fd = _fd_jacobian(p, G, h, eps=1e-6)
    assert np.abs(r.J - J_fd).max() <= 2e-7 * np.abs(J_fd).max()


def test_converges_to_the_limit_of_the_sampled_law():
    """Seven pairs with separation (H = 3): the sampled law converges like N^-2 and the event law
    like N^-4 to the same force.  Measured: sampled at N = 65536 and events at N = 1024 differ by
    9e-10 of the largest coefficient; events at N = 256 and N = 4096 by 9e-9."""
    p, G, _ = _random_case(1, True, amp=0.7, seed=1)
    pe = replace(p, events=True)
    F_ev = compute_aft(pe, G, Harmonics(3, 1024), jacobian=False).F
    F_s = compute_aft(p, G, Harmonics(3, 65536), jacobian=False).F
    scale = np.abs(F_ev).max()
    assert np.abs(F_s - F_ev).max() < 3e-9 * scale
    F_256 = compute_aft(pe, G, Harmonics(3, 256), jacobian=False).F
    F_4096 = compute_aft(pe, G, Harmonics(3, 4096), jacobian=False).F
    assert np.abs(F_256 - F_4096).max() < 5e-8 * scale


def test_stuck_pair_is_exactly_linear_and_a_separated_one_exactly_zero():
    kt, Fs = 2.0, 1.5
    h = Harmonics(5, 64)
    a = 0.999 * Fs / kt
    r = compute_aft(JenkinsPairs(kt=[kt], kn=[0.0], mu=[1.0], N0=[Fs], events=True), _cos_gap(h, a), h)
    expected = np.zeros(h.num_hc)
    expected[h.block_cos(1)] = kt * a
    np.testing.assert_allclose(r.F[:, 0, 0], expected, rtol=0, atol=1e-14 * kt * a)
    np.testing.assert_allclose(r.J[0, :, 0, :, 0], kt * np.eye(h.num_hc), atol=1e-12 * kt)
    assert (r.state_t == STICK).all()
    p = JenkinsPairs(kt=[1.0], kn=[10.0], mu=[0.5], N0=[1.0], has_normal=True, events=True)
    G = np.zeros((h.num_hc, 1, 2))
    G[0, 0, 1] = -0.5  # N0 + kn g_n = -4 < 0 always
    G[h.block_cos(1), 0, 0] = 0.3
    r = compute_aft(p, G, h)
    assert (r.state_t == SEPARATED).all()
    assert np.abs(r.F).max() < 1e-14 and np.abs(r.J).max() < 1e-13


def test_sdof_sweep_converges_and_agrees_with_the_sampled_law_at_many_samples():
    """The SDOF Jenkins oscillator (F = 0.2, H = 7), located peaks.  Measured: with the event law,
    N = 64 and 1024 differ by 8e-7 in omega and 1.3e-8 in amplitude (N = 256 and 1024 by 3e-8 and
    5e-10); the sampled law at N = 65536 differs from the event law at N = 1024 by 5e-7 in omega and
    1e-9 in amplitude (its peak sits on the scallops of its sample kinks: 4096 samples are 1e-5 off
    in omega)."""
    s = create_lumped(sdof(0.2))
    ev = with_event_aft(s)
    p64, p1024 = (compute_frf(ev, SweepOptions(0.5, 2.0, Harmonics(7, N), peak_share=0.0)).info["peaks"]["m.x"] for N in (64, 1024))
    ref = compute_frf(s, SweepOptions(0.5, 2.0, Harmonics(7, 65536), peak_share=0.0)).info["peaks"]["m.x"]
    assert p64.located and p1024.located and ref.located
    assert abs(p64.omega / p1024.omega - 1) < 2e-6 and abs(p64.amplitude / p1024.amplitude - 1) < 3e-8
    assert abs(ref.omega / p1024.omega - 1) < 1e-6 and abs(ref.amplitude / p1024.amplitude - 1) < 3e-9


_LUMPED_2T = """
kind = "lumped"
[solver]
omega_range = [0.5, 2.0]
aft = "events"
[[mass]]
name = "m"
m = 1.0
dofs = ["x", "y"]
[[spring]]
between = ["m.x", "ground"]
k = 1.0
[[spring]]
between = ["m.y", "ground"]
k = 1.0
[[jenkins]]
between = ["m", "ground"]
tangential = ["x", "y"]
kt = 1.0
mu = 1.0
N0 = 1.0
[[force]]
dof = "m.x"
amplitude = 0.2
[output]
dofs = ["m.x"]
"""


def test_scene_key_selects_it_and_refuses_two_tangential_directions():
    import tomllib
    data = tomllib.loads(_LUMPED_2T)
    with pytest.raises(SceneError, match=r"solver\.aft = 'events'.*one tangential direction"):
        parse_scene(data, "two.toml")
    data["solver"]["aft"] = "exact"
    with pytest.raises(SceneError, match=r"solver\.aft = 'exact': must be one of sampled, events"):
        parse_scene(data, "two.toml")
    data["solver"]["aft"] = "events"
    data["jenkins"][0]["tangential"] = ["x"]
    scene = parse_scene(data, "one.toml")
    from jointfem.scene import create_structure
    assert all(g.pairs.events for g in create_structure(scene).contacts)
