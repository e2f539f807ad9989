"""Numerical stability at the extremes (issue 6, first part): the SDOF Jenkins oscillator
(m = k = kt = 1, c = 0.02, Fs = mu N0 = 1) driven far outside its nominal range must converge to
the right limit, checked against closed forms, with no NaN or inf in the result.

* forcing x 1e-9: the stuck linear system (k + kt = 2);
* forcing x 1e3: gross slip, the system without the tangential spring (k = 1) with Coulomb
  friction, whose peak follows from the energy balance pi c w a^2 + 4 Fs a = pi F a;
* kt x 1e-6: the spring cannot carry force: k = 1; kt x 1e6: stuck, k = 1 + 1e6;
* mu -> 0 (mu = 0): frictionless, k = 1; mu N0 large (N0 x 1e6): stuck, k = 2.
"""
from __future__ import annotations

import copy

import numpy as np
import pytest

from jointfem.app import sweep_options
from jointfem.analysis.frf import compute_frf
from jointfem.scene import create_structure, load_scene, parse_scene
from conftest import ROOT, linear_amplitude

F0 = 0.2  # N, the scene's forcing


def _run(force=F0, kt=1.0, mu=1.0, N0=1.0, omega=(0.5, 2.0)):
    data = copy.deepcopy(load_scene(ROOT / "demos" / "sdof_jenkins.toml").data)
    data["force"][0]["amplitude"] = force
    data["jenkins"][0].update(kt=kt, mu=mu, N0=N0)
    data["solver"]["omega_range"] = list(omega)
    scene = parse_scene(data, "extreme.toml")
    frf = compute_frf(create_structure(scene), sweep_options(scene))
    amp = frf.amplitude(frf.outputs["m.x"])
    assert np.all(np.isfinite(frf.U)) and np.all(np.isfinite(frf.omega))
    return frf.omega, amp


@pytest.mark.parametrize("label,kwargs,k_lin", [
    ("forcing x 1e-9", dict(force=F0 * 1e-9), 2.0),
    ("kt x 1e-6", dict(kt=1e-6), 1.0 + 1e-6),
    ("kt x 1e6", dict(kt=1e6), 1.0 + 1e6),
    ("mu = 0", dict(mu=0.0), 1.0),
    ("N0 x 1e6", dict(N0=1e6), 2.0),
])
def test_linear_limits(label, kwargs, k_lin):
    """Every point of the branch on the closed-form linear FRF of its limit.  Tolerance: 1e-6
    relative, except kt x 1e-6, where the spring still carries kt a < 1e-6 a (its force bounds
    the difference) -- the same bound, so 1e-6 holds there too."""
    force = kwargs.get("force", F0)
    omega, amp = _run(**kwargs)
    assert omega.min() <= 0.5 + 1e-9 and omega.max() >= 2.0 - 1e-9  # the whole range was swept
    ref = linear_amplitude(omega, k_lin, force, c=0.02)
    assert np.abs(amp / ref - 1).max() < 1e-6, label


def test_gross_slip_limit():
    """Forcing x 1e3 (200 N against Fs = 1 N): the peak near w = 1 follows the Coulomb energy
    balance a = (F - 4 Fs / pi) / (c w) to 0.2 % (the short stuck phases at the reversals carry
    a stroke of 2 Fs / kt = 2 against a ~ 1e4, and the peak frequency is not exactly 1)."""
    F = F0 * 1e3
    omega, amp = _run(force=F, omega=(0.9, 1.1))
    i = int(np.argmax(amp))
    a_ref = (F - 4.0 / np.pi) / (0.02 * omega[i])
    assert amp[i] == pytest.approx(a_ref, rel=2e-3)
    assert omega[i] == pytest.approx(1.0, abs=2e-3)


# ---- fuzzed scenes -----------------------------------------------------------------------------

_GARBAGE = [-1, 0, -0.0, 1e308, -1e308, float("inf"), float("nan"), "x", "", True, [], [1, "a"], {}, {"a": 1},
            [0.0, 0.0], [-1.0, 2.0], 2**63, 1e-320, "ground", ["m.x", "m.x"]]


def _leaves(d, path=()):
    if isinstance(d, dict):
        for k, v in d.items():
            yield from _leaves(v, path + (k,))
    elif isinstance(d, list) and d and all(isinstance(x, dict) for x in d):
        for i, v in enumerate(d):
            yield from _leaves(v, path + (i,))
    else:
        yield path


def _set(d, path, value, delete=False):
    for p in path[:-1]:
        d = d[p]
    if delete:
        del d[path[-1]]
    else:
        d[path[-1]] = value


@pytest.mark.parametrize("scene_file", ["sdof_jenkins.toml", "beam2d.toml", "lap2d.toml"])
def test_fuzzed_scenes_fail_clearly(scene_file):
    """300 seeded mutations per scene (a value replaced by garbage of any type, or a key removed):
    each either parses, or raises a SceneError that names the scene and the key; lumped and
    beam2d scenes that parse also build.  Anything else (a TypeError, a crash) fails the test."""
    from jointfem.scene import SceneError

    base = load_scene(ROOT / "demos" / scene_file).data
    leaves = list(_leaves(base))
    rng = np.random.default_rng(20261122)
    errors = 0
    for trial in range(300):
        data = copy.deepcopy(base)
        path = leaves[rng.integers(len(leaves))]
        delete = rng.random() < 0.15 and isinstance(path[-1], str)
        value = _GARBAGE[rng.integers(len(_GARBAGE))]
        _set(data, path, value, delete=delete)
        try:
            scene = parse_scene(data, f"fuzz{trial}.toml")
        except SceneError as exc:
            errors += 1
            assert f"fuzz{trial}.toml" in str(exc)
            assert "\n" not in str(exc)
            continue
        if scene.kind in ("lumped", "beam2d"):
            s = create_structure(scene)
            assert np.all(np.isfinite(s.K.data)) and np.all(np.isfinite(s.M.data))
    assert errors > 150  # most garbage must be caught


@pytest.mark.parametrize("factor", [1e-6, 1e6])
def test_beam_contact_stiffness_extremes_stay_linear_and_well_conditioned(factor):
    """The jointed beam with kt and kn both x 1e-6 or x 1e6 (10 to 1e10 N/m tangential, 5 to
    5e12 N/m normal) at 1e-6 of the nominal forcing stays stuck: every point of the full-order
    branch equals the stuck linear FRF to 1e-6 (measured 3e-9 and 7e-9, so the per-DOF scaling
    and the round-off floor of the Newton test cope with a 1e12 spread of stiffness).  The
    penalty ROM (default 10 modes) differs from it only by modal truncation: measured 2.0e-3
    (x 1e-6) and 4.8e-4 (x 1e6), asserted below 5e-3."""
    from jointfem.rom import build_rom

    data = copy.deepcopy(load_scene(ROOT / "demos" / "beam2d.toml").data)
    data["joint"]["kt"] *= factor
    data["joint"]["kn"] *= factor
    data["force"]["amplitude"] *= 1e-6
    scene = parse_scene(data, "stiffness.toml")
    s = create_structure(scene)
    for method, tol in (("full", 1e-6), ("penalty", 5e-3)):
        frf = compute_frf(s if method == "full" else build_rom(s, "penalty"), sweep_options(scene))
        assert np.all(np.isfinite(frf.U)) and (frf.states == 0).all()
        assert frf.omega.min() <= 1570.0 + 1e-6 and frf.omega.max() >= 1760.0 - 1e-6
        a = frf.amplitude(frf.outputs["b1.mid.uy"])
        ref = np.abs(s.linear_response(frf.omega)[:, s.outputs["b1.mid.uy"]])
        assert np.abs(a / ref - 1).max() < tol, method
