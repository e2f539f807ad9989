"""Pairs open at rest by an initial gap g0 (issue 16, "Initial gaps"): N = kn (g_n - g0), that is
N0 = -kn g0 < 0.  Such a pair carries nothing, and adds no stiffness to the linearisation, until
the motion closes it.  Checked on the one-mass system of tests/test_extremes_systems.py (x on a
spring k = 1 and the pair's kt = 1, z on kz = 3 and the pair's normal kn = 1):

* below the closing amplitude the response is the linear FRF of the structure without the pair
  (closed form);
* above it, the HBM branch meets RK4 time integration of the same equations at its peak;
* the scene key ``[[jenkins]] gap`` sets it, with one-line errors for what cannot be;
* the penalty ROM takes it, active at every point, and equals full order with every mode.
"""
from __future__ import annotations

import numpy as np
import pytest
from conftest import linear_amplitude
from reference_timeint import steady_amplitudes

from jointfem.analysis.frf import SweepOptions, compute_frf
from jointfem.contact.jenkins import SEPARATED, SLIP, STICK
from jointfem.harmonics import Harmonics
from jointfem.models.lumped import ForceSpec, JenkinsSpec, LinkSpec, LumpedSpec, MassSpec, create_lumped
from jointfem.rom import RomError, RomOptions, build_rom
from jointfem.scene import SceneError, load_scene


def xz(g0, Fx=0.3, Fz=0.8, *, kn=1.0, kz=3.0, mu=0.5, c=0.05):
    return LumpedSpec(
        masses=(MassSpec("m", 1.0, ("x", "z")),),
        springs=(LinkSpec("m.x", "ground", 1.0), LinkSpec("m.z", "ground", kz)),
        dampers=(LinkSpec("m.x", "ground", c), LinkSpec("m.z", "ground", c)),
        jenkins=(JenkinsSpec("m", "ground", ("x",), "z", kt=1.0, kn=kn, mu=mu, N0=-kn * g0),),
        forces=(ForceSpec("m.x", Fx), ForceSpec("m.z", Fz)), outputs=("m.x", "m.z"))


def test_a_gap_the_motion_never_closes_leaves_the_linear_structure():
    """g0 = 10 m against a z amplitude of at most 5.3 m (Fz / (c w) at kz's resonance): the pair
    stays open all period, so x follows k = 1 and z follows kz = 3 exactly (the pair adds neither
    force nor stiffness), and the stuck linearisation is the structure without the pair."""
    s = create_lumped(xz(10.0))
    assert np.allclose(s.K_lin.toarray(), np.diag([1.0, 3.0]))
    frf = compute_frf(s, SweepOptions(0.5, 2.5, Harmonics(3, 64)))
    assert (frf.states == SEPARATED).all()
    np.testing.assert_allclose(frf.amplitude(0), linear_amplitude(frf.omega, 1.0, 0.3, c=0.05), rtol=1e-8)
    np.testing.assert_allclose(frf.amplitude(1), linear_amplitude(frf.omega, 3.0, 0.8, c=0.05), rtol=1e-8)
    assert frf.amplitude(1).max() < 10.0


def test_a_gap_the_motion_closes_matches_time_integration():
    """g0 = 1 m: near kz's resonance z swings past the gap, the pair closes for part of the period
    (stuck and slipping; open 57 % of the period at least), and opens again.  At the peak of z the
    HBM branch (H = 15) meets RK4 time integration of the same equations, the gap included
    (tests/reference_timeint.py with N0 = -kn g0): measured 2.8e-5 in x and 1.2e-6 in z; 1e-3 allows
    for the integrator's first-order error at each switch."""
    frf = compute_frf(create_lumped(xz(1.0)), SweepOptions(0.8, 2.4, Harmonics(15, 512)))
    sep = (frf.states == SEPARATED).mean(axis=(1, 2))
    assert sep.max() == 1.0 and sep.min() < 0.9  # open at the ends of the range, closing near resonance
    assert (frf.states == STICK).any() and (frf.states == SLIP).any()
    i = int(np.argmax(frf.amplitude(1)))
    w = float(frf.omega[i])
    system = dict(M=np.eye(2), K=np.diag([1.0, 3.0]), D=np.diag([0.05, 0.05]), fc=[0.3, 0.8], fs=[0.0, 0.0],
                  Gt=[[1.0, 0.0]], Gn=[[0.0, 1.0]], has_n=[True], kt=[1.0], kn=[1.0], mu=[0.5], N0=[-1.0])
    ti, drift = steady_amplitudes(system, [w], periods=300, steps=4000)
    assert drift[0] < 1e-3
    for dof in (0, 1):
        assert frf.half_peak_to_peak(dof)[i] == pytest.approx(ti[0, dof], rel=1e-3)


def test_penalty_rom_keeps_an_open_pair_active_and_matches_full_order():
    """The penalty ROM takes an open pair as if closed at rest for its basis and Kc (the augmented
    system is exact for any Kc > 0) and keeps it active at every point; with every mode it is full
    order's branch: peaks to 1e-8, and the pair's internal variables are among the unknowns at every
    point."""
    s = create_lumped(xz(1.0))
    opts = SweepOptions(0.8, 2.4, Harmonics(7, 256), peak_share=0.0)  # peaks to omega_rtol: the same top
    ref = compute_frf(s, opts)
    pen = compute_frf(build_rom(s, "penalty", RomOptions(modes=2)), opts)
    for dof in ("m.x", "m.z"):
        a, b = ref.info["peaks"][dof], pen.info["peaks"][dof]
        assert abs(b.amplitude / a.amplitude - 1) < 1e-8 and abs(b.omega / a.omega - 1) < 1e-8, dof
    assert (pen.info["arrays"]["rom_size"] == 4).all()  # 2 modes + the pair's 2 components, everywhere


SCENE = """
kind = "lumped"
[solver]
omega_range = [0.8, 2.4]
[[mass]]
name = "m"
m = 1.0
dofs = ["x", "z"]
[[spring]]
between = ["m.x", "ground"]
k = 1.0
[[spring]]
between = ["m.z", "ground"]
k = 3.0
[[damper]]
between = ["m.x", "ground"]
c = 0.05
[[damper]]
between = ["m.z", "ground"]
c = 0.05
[[jenkins]]
between = ["m", "ground"]
tangential = ["x"]
normal = "z"
kt = 1.0
kn = 2.0
mu = 0.5
{extra}
[[force]]
dof = "m.z"
amplitude = 0.8

[output]
dofs = ["m.x", "m.z"]
"""


def test_scene_gap_key(tmp_path):
    p = tmp_path / "gap.toml"
    p.write_text(SCENE.format(extra="gap = 0.25"))
    from jointfem.scene import create_structure
    pairs = create_structure(load_scene(p)).contacts[0].pairs
    assert pairs.N0[0] == pytest.approx(-0.5) and pairs.initial_gap[0] == pytest.approx(0.25)


@pytest.mark.parametrize("extra, why", [("gap = 0.25\nN0 = 1.0", "either preloaded"), ("gap = -0.1", ">= 0")])
def test_scene_gap_errors(tmp_path, extra, why):
    p = tmp_path / "gap.toml"
    p.write_text(SCENE.format(extra=extra))
    with pytest.raises(SceneError, match=r"jenkins\[0\]\.gap") as exc:
        load_scene(p)
    assert why in str(exc.value)


def test_scene_gap_needs_a_normal_axis(tmp_path):
    p = tmp_path / "gap.toml"
    p.write_text(SCENE.format(extra="gap = 0.25").replace('normal = "z"\n', ""))
    with pytest.raises(SceneError, match=r"jenkins\[0\]\.gap = 0\.25: an initial gap needs a normal axis"):
        load_scene(p)


def test_event_aft_of_an_open_pair_equals_the_sampled_law():
    """The event-accurate AFT integrates the departure from the law's own spring (kt, kn, N0 as
    given); a pair open at rest must come out as the sampled law does, open, closing, slipping:
    force coefficients agree to 1e-5 of the largest (sampled N = 65536 against events N = 1024)."""
    from jointfem.contact.jenkins import JenkinsPairs

    rng = np.random.default_rng(7)
    h_ev, h_s = Harmonics(5, 1024), Harmonics(5, 65536)
    pairs = JenkinsPairs(kt=[1.0, 2.0], kn=[1.0, 3.0], mu=[0.5, 0.3], N0=[-0.5, -0.2], has_normal=True)
    G = 0.3 * rng.standard_normal((h_ev.num_hc, 2, 2))
    G[1, :, 1] += 1.0  # the normal gap swings past the initial gaps
    ev = pairs.__class__(**{**pairs.__dict__, "events": True}).aft(G, h_ev, jacobian=False)
    sa = pairs.aft(G, h_s, jacobian=False)
    assert (ev.state_t == SEPARATED).any() and (ev.state_t != SEPARATED).any()
    assert np.abs(ev.F - sa.F).max() < 1e-5 * np.abs(sa.F).max()


def test_exact_condensation_and_a_galerkin_rom_take_an_open_pair():
    """The exact condensation (its stuck initial guess and f0 from the linearisation) and the
    modal (tvd) ROM with every mode give full order's branch where the pair closes: peaks to 1e-8
    (the condensation's Newton floor)."""
    s = create_lumped(xz(1.0))
    opts = SweepOptions(0.8, 2.4, Harmonics(7, 256), peak_share=0.0)  # peaks to omega_rtol: the same top
    ref = compute_frf(s, opts).info["peaks"]["m.z"]
    for method in ("exact", "tvd"):
        pk = compute_frf(build_rom(s, method, RomOptions(modes=2, tvd=0)), opts).info["peaks"]["m.z"]
        assert abs(pk.amplitude / ref.amplitude - 1) < 1e-8 and abs(pk.omega / ref.omega - 1) < 1e-8, method


def test_penalty_rom_starts_with_its_open_pairs_removed():
    """Before any point is solved, the penalty ROM's active set already holds the open pair, so its
    linear model is the structure without the pair: the linear mode the nonlinear modes start from
    is sqrt(k_x) = 1 and sqrt(k_z) = sqrt(3) rad/s (closed form), not the closed pair's sqrt(2) and
    sqrt(3 + kn) (before: the first point and the reported linear mode were those of the pair
    closed)."""
    from jointfem.analysis.frf import create_problem
    from jointfem.analysis.nma import modal_problem

    s = create_lumped(xz(1.0))
    problem = create_problem(build_rom(s, "penalty", RomOptions(modes=2)), Harmonics(3, 64))
    assert problem.size == 4  # 2 modes + the open pair's 2 components
    w = sorted(modal_problem(problem, k, "m.x" if k == 1 else "m.z").omega0 for k in (1, 2))
    np.testing.assert_allclose(w, [1.0, np.sqrt(3.0)], rtol=1e-10)
