"""Peaks located to the solver's tolerance (jointfem.analysis.peaks), against an independent dense
search of fixed-omega solutions, the same peak wherever the branch's points fall, and the edge of a
range reported as an edge."""
from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from conftest import sdof
from jointfem.analysis.frf import SweepOptions, compute_frf, create_problem
from jointfem.analysis.peaks import output_amplitude, output_amplitude_derivative
from jointfem.continuation.arclength import NewtonOptions, solve_newton
from jointfem.harmonics import Harmonics
from jointfem.hbm.problem import newton_system
from jointfem.models.lumped import create_lumped
from jointfem.results import save_frf


def _dense_peak(structure, h, frf, k):
    """The largest first-harmonic amplitude of fixed-omega Newton solutions (tol 1e-12): 2001 omegas
    between branch points k-2 and k+2 (each started from the last), then Brent at fixed omega to
    1e-12 rad/s between the best one's neighbours.  Shares with the located peak only the
    residual."""
    pb = create_problem(structure, h)
    sc = pb.scales(0.5, 2.0)
    state = {"x": frf.U[k - 2]}

    def amp(w):
        x, _ = solve_newton(newton_system(pb), state["x"], float(w), x_scale=sc.x, r_scale=sc.r,
                            options=NewtonOptions(tol=1e-12))
        state["x"] = x
        return float(np.hypot(x[1], x[2]))  # m.x is DOF 0: its cos 1 and sin 1 coefficients

    ws = np.linspace(frf.omega[k - 2], frf.omega[k + 2], 2001)
    A = np.array([amp(w) for w in ws])
    j = int(np.argmax(A))
    state["x"] = frf.U[k]
    r = minimize_scalar(lambda w: -amp(w), bounds=(ws[j - 1], ws[j + 1]), method="bounded",
                        options={"xatol": 1e-12})
    return float(r.x), float(-r.fun)


@pytest.mark.parametrize("F", [0.05, 0.2, 0.5])
def test_sdof_peak_equals_a_dense_fixed_omega_search(F):
    """m = k = kt = Fs = 1, c = 0.02, H = 7, N = 128.  With 128 samples the amplitude near the peak
    is scalloped (a kink where a sample changes state; the sags are ~1e-4 of the amplitude), so a
    parabola through the three highest points misses the top by up to 9e-4 in omega and 6e-4 in
    amplitude (measured); the located peak agrees with the dense search to 1.5e-8 (measured)."""
    s = create_lumped(sdof(F))
    h = Harmonics(7, 128)
    frf = compute_frf(s, SweepOptions(0.5, 2.0, h))
    pk = frf.info["peaks"]["m.x"]
    assert pk.located and not pk.edge
    assert frf.peak("m.x") == (pk.omega, pk.amplitude)
    assert pk.amplitude >= frf.amplitude(0).max()
    w_ref, a_ref = _dense_peak(s, h, frf, int(np.argmax(frf.amplitude(0))))
    assert abs(pk.amplitude / a_ref - 1) < 1e-6, (pk, a_ref)
    assert abs(pk.omega / w_ref - 1) < 1e-5, (pk, w_ref)


@pytest.mark.parametrize("F, N", [(0.05, 128), (0.5, 128), (0.2, 64)])
def test_located_peak_does_not_depend_on_where_the_points_fall(F, N):
    """The SDOF oscillator of the test above (and at N = 64, whose scallops are deeper), swept from
    11 start frequencies 0.5 to 0.501: the steps differ (48 to 85 points), as round-off in a model
    makes them differ, and the scallops' kinks fall anywhere between the points.  The located peaks
    agree to 1e-8 in omega and amplitude: each keeps a point within omega_rtol / 2 = 5e-9 of the
    top's omega (measured spread: 3.4e-9, 2.7e-9, 2.6e-9 in omega; 3.3e-9, 4.6e-10, 2.3e-9 in
    amplitude).  The search that refined only the interior maxima of each segment's samples missed
    the top by 6e-4, 8.6e-4 and 5.2e-3 in omega (1.7e-5, 1.9e-4, 6.1e-4 in amplitude): a kink next
    to a branch point, or between two samples neither of which was a local maximum.  Bounding every
    cell by the steepest sampled slope alone still missed at N = 64 (by 1.9e-5 in omega)."""
    s = create_lumped(sdof(F))
    h = Harmonics(7, N)
    peaks, points = [], set()
    for start in np.linspace(0.5, 0.501, 11):
        frf = compute_frf(s, SweepOptions(float(start), 2.0, h))
        pk = frf.info["peaks"]["m.x"]
        assert pk.located and not pk.edge and pk.amplitude >= frf.amplitude(0).max()
        peaks.append((pk.omega, pk.amplitude))
        points.add(frf.omega.size)
    assert len(points) > 1  # the steps did differ
    omega, amp = np.array(peaks).T
    assert np.ptp(omega) / omega.min() < 1e-8, omega
    assert np.ptp(amp) / amp.min() < 1e-8, amp


def test_edge_of_the_range_is_not_a_peak(tmp_path):
    """A sweep that ends below the resonance rises to its last point: that is the edge of the range,
    reported as such in summary.json, not a peak."""
    s = create_lumped(sdof(0.2))
    frf = compute_frf(s, SweepOptions(0.5, 0.9, Harmonics(3, 64)))
    pk = frf.info["peaks"]["m.x"]
    assert pk.edge and not pk.located and pk.omega == frf.omega[-1] and "edge" in pk.reason
    summary = save_frf(frf, tmp_path, summary={})
    on_disk = json.loads((tmp_path / "summary.json").read_text())["peaks"]["m.x"]
    assert on_disk["edge"] is True and on_disk["located"] is False and summary["peaks"]["m.x"]["edge"] is True


def test_amplitude_derivative_equals_finite_differences():
    """output_amplitude_derivative (the first harmonic's amplitude, linearised) against a central
    difference, for a DOF index and for a recovery row; truncation O(1e-12)."""
    h = Harmonics(3, 16)
    rng = np.random.default_rng(3)
    x, dx = rng.standard_normal(h.num_hc * 4), rng.standard_normal(h.num_hc * 4)
    for dof in (2, rng.standard_normal(4)):
        fd = (output_amplitude(x + 1e-6 * dx, dof, h) - output_amplitude(x - 1e-6 * dx, dof, h)) / 2e-6
        assert abs(output_amplitude_derivative(x, dx, dof, h) - fd) < 1e-8 * abs(fd)


def test_flat_top_covered_with_kinks_costs_a_fraction_of_the_steepest_bound(monkeypatch):
    """demos/lap3d_friction.toml (25 pairs, exact condensation, H = 3, N = 256, 32 points): its
    tops carry many small kinks (pairs' samples slipping), where a cell is bounded by the slopes of
    the pieces near it.  The same branch searched with the steepest slope anywhere (the conservative
    bound, peaks.KINK_BOUND = "steepest") gives the same peaks (measured: equal to 11 digits), at
    375 and 259 solves against 70 and 54: the pieces' bound takes at most 0.4 of them."""
    from pathlib import Path

    from jointfem.analysis import frf as frfmod
    from jointfem.analysis import peaks as peaksmod
    from jointfem.app import sweep_options
    from jointfem.rom.common import ExactModel
    from jointfem.scene import create_structure, load_scene

    scene = load_scene(Path(__file__).resolve().parents[1] / "demos" / "lap3d_friction.toml")
    branch = {}
    real = frfmod.locate_peaks

    def spy(*args, **kw):
        branch.update(args=args, kw=kw)
        return real(*args, **kw)

    monkeypatch.setattr(frfmod, "locate_peaks", spy)
    frf = compute_frf(ExactModel(create_structure(scene)), sweep_options(scene, stability="off"))
    pieces = frf.info["peaks"]
    monkeypatch.setattr(peaksmod, "KINK_BOUND", "steepest")
    steepest = real(*branch["args"], **branch["kw"])
    assert set(pieces) == set(steepest) == {"a_mid.uy", "b_mid.uy"}
    total = {"pieces": 0, "steepest": 0}
    for name in pieces:
        a, b = pieces[name], steepest[name]
        assert a.located and b.located and not a.edge
        assert abs(a.omega / b.omega - 1) < 1e-8 and abs(a.amplitude / b.amplitude - 1) < 1e-8, (a, b)
        total["pieces"] += a.solves
        total["steepest"] += b.solves
    assert total["pieces"] <= 0.4 * total["steepest"], total


def test_without_tangents_the_search_falls_back_to_the_steepest_bound(monkeypatch):
    """Where the bordered system of a point's tangent is singular (a bifurcation on the branch),
    its slope is taken as the steepest anywhere: with every tangent refused the search is the
    "steepest" one, to the solve (SDOF oscillator of the tests above, F = 0.2, N = 64)."""
    import jointfem.analysis.peaks as peaksmod

    s = create_lumped(sdof(0.2))
    h = Harmonics(7, 64)

    def refused(*args, **kw):
        raise np.linalg.LinAlgError("singular")

    monkeypatch.setattr(peaksmod, "hyperplane_derivative", refused)
    fallback = compute_frf(s, SweepOptions(0.5, 2.0, h)).info["peaks"]["m.x"]
    monkeypatch.setattr(peaksmod, "KINK_BOUND", "steepest")
    steepest = compute_frf(s, SweepOptions(0.5, 2.0, h)).info["peaks"]["m.x"]
    assert fallback.located and (fallback.omega, fallback.amplitude, fallback.solves) == (
        steepest.omega, steepest.amplitude, steepest.solves)
