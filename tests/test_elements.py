"""Scene elements beyond the Jenkins pair (issue 18): [[cubic_spring]], [[unilateral_spring]] and a
static force, each against an independent solution (a closed form or a time integration)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from jointfem.analysis.frf import compute_frf
from jointfem.app import sweep_options
from jointfem.contact import LAWS, CubicSprings
from jointfem.harmonics import Harmonics
from jointfem.scene import SceneError, create_structure, parse_scene

DUFFING = {  # m = 1, k = 1, c = 0.02, k3 = 0.5: a hardening oscillator, written as a user would
    "kind": "lumped",
    "solver": {"omega_range": [0.6, 1.6], "harmonics": 1, "samples": 16},
    "mass": [{"name": "m", "m": 1.0, "dofs": ["x"]}],
    "spring": [{"between": ["m.x", "ground"], "k": 1.0}],
    "damper": [{"between": ["m.x", "ground"], "c": 0.02}],
    "cubic_spring": [{"between": ["m.x", "ground"], "k3": 0.5}],
    "force": [{"dof": "m.x", "amplitude": 0.05}],
    "output": {"dofs": ["m.x"]},
}


def scene(data, **solver):
    d = {**data, "solver": {**data["solver"], **solver}}
    return parse_scene(d, "elements.toml")


def test_cubic_law_jacobian_matches_finite_differences():
    assert LAWS["cubic_spring"] is CubicSprings
    h = Harmonics(3, 32)
    law = CubicSprings(k3=[2.0, -0.5])
    G = 0.3 * np.random.default_rng(3).standard_normal((h.num_hc, 2, 1))
    res = law.aft(G, h)
    J = res.J.reshape(2, h.num_hc, h.num_hc)
    d = 1e-6
    for p in range(2):
        for j in range(h.num_hc):
            Gp, Gm = G.copy(), G.copy()
            Gp[j, p, 0] += d
            Gm[j, p, 0] -= d
            fd = (law.aft(Gp, h, jacobian=False).F - law.aft(Gm, h, jacobian=False).F)[:, p, 0] / (2 * d)
            np.testing.assert_allclose(J[p, :, j], fd, rtol=0, atol=1e-8 * np.abs(J).max())  # smooth: O(d^2)


def test_duffing_at_one_harmonic_is_the_closed_form():
    """H = 1 is the classic single-harmonic balance of the Duffing oscillator, which has a closed
    form: ((k - m w^2 + 3/4 k3 a^2)^2 + (c w)^2) a^2 = F^2.  Every point of the swept branch (through
    both folds of the hardening peak) satisfies it to 1e-9, and the branch folds (three amplitudes
    at some frequencies)."""
    sc = scene(DUFFING)
    frf = compute_frf(create_structure(sc), sweep_options(sc, stability="off"))
    a, w = frf.amplitude(0), frf.omega
    lhs = ((1.0 - w**2 + 0.75 * 0.5 * a**2) ** 2 + (0.02 * w) ** 2) * a**2
    np.testing.assert_allclose(lhs, 0.05**2, rtol=1e-9)
    assert (np.diff(w) < 0).any()  # the hardening branch turns back: a fold pair
    assert frf.info["status"] == "complete"


def _steady_first_harmonic(rhs, y0, omega, periods, n=512):
    T = 2 * np.pi / omega
    t = np.linspace((periods - 1) * T, periods * T, n + 1)[:-1]
    sol = solve_ivp(rhs, (0.0, periods * T), y0, method="DOP853", rtol=1e-10, atol=1e-12, t_eval=t)
    X = Harmonics(1, n).from_time(sol.y[0])
    return float(np.hypot(X[1], X[2]))


def test_duffing_with_seven_harmonics_against_time_integration():
    """H = 7 at 1.2 rad/s on the upper (resonant) branch: the first harmonic of a time integration
    (DOP853) started from the HBM orbit, after the transient has decayed by e^-12, agrees to 1e-4."""
    sc = scene(DUFFING, harmonics=7, samples=64)
    frf = compute_frf(create_structure(sc), sweep_options(sc, stability="on"))
    near = np.flatnonzero(np.abs(frf.omega - 1.2) < 0.02)
    i = int(near[np.argmax(frf.amplitude(0)[near])])  # the upper branch (the middle one is just below it)
    w, a = float(frf.omega[i]), float(frf.amplitude(0)[i])
    assert a > 1.0 and frf.stable[i]
    j = int(near[np.argmin(np.abs(frf.amplitude(0)[near] - 0.9 * a))])
    assert not frf.stable[j]  # Hill: the middle branch between the folds is unstable
    h = frf.harmonics
    Uh = frf.U[i].reshape(h.num_hc, 1)
    u0 = h.to_time(Uh)[0, 0]
    v0 = h.to_time(w * (h.derivative_matrix() @ Uh))[0, 0]

    def rhs(t, y):
        return [y[1], 0.05 * np.cos(w * t) - y[0] - 0.02 * y[1] - 0.5 * y[0] ** 3]

    periods = int(np.ceil(12 / 0.01 / (2 * np.pi / w)))
    assert _steady_first_harmonic(rhs, [u0, v0], w, periods) == pytest.approx(a, rel=1e-4)


GAP = {  # m = 1, k = 1, c = 0.05; a unilateral spring k = 4 engaging at u = 0.1 (a stop)
    "kind": "lumped",
    "solver": {"omega_range": [0.5, 1.8], "harmonics": 15, "samples": 512},
    "mass": [{"name": "m", "m": 1.0, "dofs": ["x"]}],
    "spring": [{"between": ["m.x", "ground"], "k": 1.0}],
    "damper": [{"between": ["m.x", "ground"], "c": 0.05}],
    "unilateral_spring": [{"between": ["m.x", "ground"], "k": 4.0, "gap": 0.1}],
    "force": [{"dof": "m.x", "amplitude": 0.05}],
    "output": {"dofs": ["m.x"]},
}


def test_unilateral_spring_element_open_limit_and_time_integration():
    """A gap larger than any motion: the linear FRF of the rest to round-off.  Near 1.1 rad/s on the
    stable branch with the stop engaged every period (H = 15): the first harmonic equals a time
    integration's to 1e-4."""
    wide = scene({**GAP, "unilateral_spring": [{"between": ["m.x", "ground"], "k": 4.0, "gap": 10.0}]},
                 harmonics=3, samples=64)
    s = create_structure(wide)
    frf = compute_frf(s, sweep_options(wide, stability="off"))
    lin = np.abs(1.0 / (1.0 - frf.omega**2 + 0.05j * frf.omega)) * 0.05
    np.testing.assert_allclose(frf.amplitude(0), lin, rtol=1e-10)

    sc = scene(GAP)
    frf = compute_frf(create_structure(sc), sweep_options(sc, stability="on"))
    near = np.flatnonzero((np.abs(frf.omega - 1.1) < 0.02) & frf.stable)
    i = int(near[np.argmax(frf.amplitude(0)[near])])
    w, a, U, h = float(frf.omega[i]), float(frf.amplitude(0)[i]), frf.U[i], frf.harmonics
    assert (frf.states[i] == 0).any() and (frf.states[i] == 2).any()  # engaged and open in the period
    Uh = U.reshape(h.num_hc, 1)
    u0, v0 = h.to_time(Uh)[0, 0], h.to_time(w * (h.derivative_matrix() @ Uh))[0, 0]

    def rhs(t, y):
        return [y[1], 0.05 * np.cos(w * t) - y[0] - 0.05 * y[1] - 4.0 * max(y[0] - 0.1, 0.0)]

    periods = int(np.ceil(12 / 0.025 / (2 * np.pi / w)))
    assert _steady_first_harmonic(rhs, [u0, v0], w, periods) == pytest.approx(a, rel=1e-4)


def test_static_force_against_a_static_solve():
    """A static force (the zeroth harmonic) on the Duffing oscillator, with a tiny harmonic force:
    the mean displacement solves k u + k3 u^3 = f_s (the real root of the cubic) to 1e-9."""
    data = {**DUFFING, "force": [{"dof": "m.x", "amplitude": 1e-9, "static": 0.8}]}
    sc = scene(data, harmonics=3, samples=32)
    s = create_structure(sc)
    frf = compute_frf(s, sweep_options(sc, stability="off"))
    roots = np.roots([0.5, 0.0, 1.0, -0.8])
    u_static = float(roots[np.abs(roots.imag) < 1e-12].real[0])
    np.testing.assert_allclose(frf.U[:, 0], u_static, rtol=1e-9)


@pytest.mark.parametrize("table,entry,words", [
    ("cubic_spring", {"between": ["m.x", "ground"], "k3": 0.0}, "cubic_spring[0].k3 = 0.0: must be > 0"),
    ("unilateral_spring", {"between": ["m.x", "ground"], "k": 1.0, "gap": -0.1},
     "unilateral_spring[0].gap = -0.1: must be >= 0"),
    ("unilateral_spring", {"between": ["ground", "m.x"], "k": 1.0}, "ground goes second"),
    ("force", {"dof": "m.x", "static": 1.0}, "no force has a harmonic amplitude"),
])
def test_bad_elements_are_one_line(table, entry, words):
    with pytest.raises(SceneError, match=words.replace("[", r"\[").replace("]", r"\]")):
        parse_scene({**DUFFING, table: [entry]}, "bad.toml")


def test_static_normal_load_splits_between_contact_and_parallel_spring():
    """docs/scenes.md's two-DOF scene: a Jenkins pair with normal stiffness kn = 1 in parallel with a
    spring kz = 3 on z.  Preloading it with N0 = 1 is the same as N0 = 0 and a static force
    P = (kn + kz) N0 / kn = 4 N on z: the pair then carries kn P / (kn + kz) = 1 N.  The two sweeps
    have the same harmonics k >= 1 to 1e-9, and z's mean differs by P / (kn + kz) = 1 m."""
    import re as _re

    from conftest import ROOT

    block = _re.findall(r"```toml\n(.*?)```", (ROOT / "docs" / "scenes.md").read_text(), _re.S)[2]
    import tomllib

    base = tomllib.loads(block)
    base["solver"].update(harmonics=5, samples=128)
    pre = parse_scene(base, "n0.toml")
    loaded = {**base, "jenkins": [{**base["jenkins"][0], "N0": 0.0}],
              "force": [base["force"][0], {**base["force"][1], "static": 4.0}]}
    st = parse_scene(loaded, "static.toml")
    a = compute_frf(create_structure(pre), sweep_options(pre, stability="off"))
    b = compute_frf(create_structure(st), sweep_options(st, stability="off"))
    assert (a.states == 1).any() and a.omega.size == b.omega.size
    # the two sweeps step by round-off differently (their omegas differ by up to 5e-9, where U moves
    # by 4e-8 on the steep flank): b is solved again at a's omegas, from its own nearest points
    from jointfem.analysis.frf import solve_at
    from jointfem.continuation.arclength import NewtonOptions
    from jointfem.harmonics import Harmonics

    model_b = create_structure(st)
    Ub = np.array([solve_at(model_b, w, Harmonics(5, 128), guess=u, newton=NewtonOptions(tol=1e-12)).U
                   for w, u in zip(a.omega, b.U)])
    n = 2
    np.testing.assert_allclose(Ub[:, n:], a.U[:, n:], rtol=0, atol=1e-9 * np.abs(a.U).max())
    np.testing.assert_allclose(Ub[:, 1] - a.U[:, 1], 1.0, rtol=1e-9)  # z's mean: P / (kn + kz)
    np.testing.assert_allclose(Ub[:, 0], a.U[:, 0], atol=1e-9)  # x's mean unchanged


@pytest.mark.parametrize("gap, omega", [(0.5, 1.0), (0.0, np.sqrt(5.0))])
def test_modes_at_rest_leave_an_open_unilateral_spring_out(gap, omega):
    """``jointfem modes`` (app.linear_modes): m = k = 1 with a unilateral spring k = 4 to ground.
    Open at rest (gap 0.5, the docs/scenes.md example) small vibrations never reach it: 1 rad/s,
    where it said sqrt(5) (issue 50, item 3).  Touching at rest (gap 0) it is engaged: sqrt(5).
    The reductions still linearise it engaged (Structure.K_lin), which the penalty ROM's p needs."""
    from jointfem.app import linear_modes
    from jointfem.models.lumped import ForceSpec, GapSpringSpec, LinkSpec, LumpedSpec, MassSpec, create_lumped

    s = create_lumped(LumpedSpec(masses=(MassSpec("m", 1.0),), springs=(LinkSpec("m.x", "ground", 1.0),),
                                 dampers=(LinkSpec("m.x", "ground", 0.02),),
                                 unilateral=(GapSpringSpec("m.x", "ground", 4.0, gap),),
                                 forces=(ForceSpec("m.x", 0.05),), outputs=("m.x",)))
    modes = linear_modes(s, 1)
    assert modes["stuck"]["omega_rad_s"][0] == pytest.approx(omega, rel=1e-12)
    assert modes["free"]["omega_rad_s"][0] == pytest.approx(1.0, rel=1e-12)
    assert s.K_lin.toarray()[0, 0] == pytest.approx(5.0)
