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
    amplitude (measured); the peak searched to the end (peak_share = 0) agrees with the dense search
    to 1.5e-8 (measured).  The default search, to a tenth of its error bar, keeps a point within that
    tolerance (frf.peak_tolerance: 0.1 e^2 / 4 at the top, 2e-7 to 7e-6 here) below the dense
    search's top (measured: 4e-9, 1.3e-7, 4.9e-7 of it)."""
    from jointfem.analysis.frf import peak_tolerance

    s = create_lumped(sdof(F))
    h = Harmonics(7, 128)
    for share in (0.0, SweepOptions(0.5, 2.0).peak_share):
        frf = compute_frf(s, SweepOptions(0.5, 2.0, h, peak_share=share))
        pk = frf.info["peaks"]["m.x"]
        assert pk.located and not pk.edge
        assert frf.peak("m.x") == (pk.omega, pk.amplitude)
        assert pk.amplitude >= frf.amplitude(0).max()
        i = int(np.argmax(frf.amplitude(0)))
        w_ref, a_ref = _dense_peak(s, h, frf, i)
        if share == 0.0:
            assert abs(pk.amplitude / a_ref - 1) < 1e-6, (pk, a_ref)
            assert abs(pk.omega / w_ref - 1) < 1e-5, (pk, w_ref)
        else:
            rtol = peak_tolerance(frf.U[i:i + 1], frf.info["arrays"]["harmonic_error"][i:i + 1], None, {"m.x": 0}, h,
                                  share)[0, 0]
            assert a_ref * (1 - rtol) <= pk.amplitude <= a_ref * (1 + 1e-6), (pk, a_ref, rtol)


@pytest.mark.parametrize("F, N, omega_tol", [(0.05, 128, 4e-6), (0.5, 128, 3e-5), (0.2, 64, 2e-5)])
def test_located_peak_does_not_depend_on_where_the_points_fall(F, N, omega_tol):
    """The SDOF oscillator of the test above (and at N = 64, whose scallops are deeper), swept from
    11 start frequencies 0.5 to 0.501: the steps differ (48 to 85 points), as round-off in a model
    makes them differ, and the scallops' kinks fall anywhere between the points.

    Searched to the end (peak_share = 0), the located peaks agree to 1e-8 in omega and amplitude:
    each keeps a point within omega_rtol / 2 = 5e-9 of the top's omega (measured spread: 3.4e-9,
    2.7e-9, 2.6e-9 in omega; 3.3e-9, 4.6e-10, 2.3e-9 in amplitude).  The search that refined only the
    interior maxima of each segment's samples missed the top by 6e-4, 8.6e-4 and 5.2e-3 in omega
    (1.7e-5, 1.9e-4, 6.1e-4 in amplitude): a kink next to a branch point, or between two samples
    neither of which was a local maximum.  Bounding every cell by the steepest sampled slope alone
    still missed at N = 64 (by 1.9e-5 in omega).

    Searched to its error bar (the default), every peak is within the tolerance it was located to
    (frf.peak_tolerance at the top's point: 2e-7, 7e-6 and 3e-6) of the top found by the full
    search, never above it by more than round-off (measured: 8e-8, 2.0e-6, 1.2e-6 below), and its
    omega within omega_tol of it, a quarter of the truncation error in omega of the H = 7 rows of
    docs/benchmarks_truncation.md (1.7e-5, 1.3e-4 and, at N = 1024, 7.8e-5 of omega; measured
    3.6e-8, 9.4e-6, 1.0e-6)."""
    from jointfem.analysis.frf import peak_tolerance

    s = create_lumped(sdof(F))
    h = Harmonics(7, N)
    found = {}
    for share in (0.0, SweepOptions(0.5, 2.0).peak_share):
        peaks, points, tol = [], set(), []
        for start in np.linspace(0.5, 0.501, 11):
            frf = compute_frf(s, SweepOptions(float(start), 2.0, h, peak_share=share))
            pk = frf.info["peaks"]["m.x"]
            assert pk.located and not pk.edge and pk.amplitude >= frf.amplitude(0).max()
            peaks.append((pk.omega, pk.amplitude))
            points.add(frf.omega.size)
            i = int(np.argmax(frf.amplitude(0)))
            tol.append(peak_tolerance(frf.U[i:i + 1], frf.info["arrays"]["harmonic_error"][i:i + 1], None,
                                      {"m.x": 0}, h, share)[0, 0])
        assert len(points) > 1  # the steps did differ
        found[share] = np.array(peaks).T, np.array(tol)
    (omega, amp), _ = found[0.0]
    assert np.ptp(omega) / omega.min() < 1e-8, omega
    assert np.ptp(amp) / amp.min() < 1e-8, amp
    (omega_e, amp_e), tol = found[SweepOptions(0.5, 2.0).peak_share]
    top = amp.max()
    assert (amp_e <= top * (1 + 1e-8)).all() and (amp_e >= top * (1 - tol)).all(), (amp_e, top, tol)
    assert (np.abs(omega_e / omega.mean() - 1) < omega_tol).all(), omega_e


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
    375 and 259 solves against 70 and 54: the pieces' bound takes at most 0.4 of them.  Both searched
    to the end (no amplitude tolerance, 126 solves for the two outputs); the sweep's own search, to
    a tenth of its error bar, keeps a point within that tolerance of their top (1.5e-4 of it: 0.1 of
    e^2 / 4, e = 0.078 at the top; measured 1.5e-5 and 5.7e-6 below) in 6 solves (at most a tenth; 22 by the branch and bound alone, MODEL_STEPS = 0
    asserted), its omega within 2e-4 of theirs (measured 9.2e-5 and 7.2e-5; the truncation error in
    omega at H = 3 is 2.5e-4, docs/benchmarks_truncation.md)."""
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
    to_bar, rtol = frf.info["peaks"], branch["kw"]["amplitude_rtol"]
    full = dict(branch["kw"], amplitude_rtol=None)
    pieces = real(*branch["args"], **full)
    monkeypatch.setattr(peaksmod, "KINK_BOUND", "steepest")
    steepest = real(*branch["args"], **full)
    assert set(pieces) == set(steepest) == {"a_mid.uy", "b_mid.uy"}
    total = {"pieces": 0, "steepest": 0}
    for name in pieces:
        a, b = pieces[name], steepest[name]
        assert a.located and b.located and not a.edge
        assert abs(a.omega / b.omega - 1) < 1e-8 and abs(a.amplitude / b.amplitude - 1) < 1e-8, (a, b)
        total["pieces"] += a.solves
        total["steepest"] += b.solves
        j = list(pieces).index(name)
        c, i = to_bar[name], int(np.argmax(frf.amplitude(frf.outputs[name])))
        assert a.amplitude * (1 - rtol[i, j]) <= c.amplitude <= a.amplitude * (1 + 1e-10), (c, a, rtol[i, j])
        assert abs(c.omega / a.omega - 1) < 2e-4, (c, a)
    assert total["pieces"] <= 0.4 * total["steepest"], total
    assert sum(p.solves for p in to_bar.values()) <= 0.1 * total["pieces"], (to_bar, total)


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


def test_newton_starts_on_the_hyperplane_from_the_branch_interpolant():
    """_Segments' first Newton iterate between two solved points of a segment (Hermite's cubic with
    both tangents, the quadratic with one): on the corrector's hyperplane to round-off (z . chord is
    linear in t on every such interpolant), and nearer the solution than the chord's point by far
    (SDOF oscillator, F = 0.2, N = 1024, the segment after the largest point, scaled distance;
    measured ratios 3.9e-3 with both tangents and 2.4e-2 with one; at N = 128 the scallops' kinks between the points leave 0.14 and 0.18).  A start off the hyperplane would
    converge to a point of another hyperplane: the branch point at another t."""
    from jointfem.analysis.peaks import _Segments

    s = create_lumped(sdof(0.2))
    h = Harmonics(7, 1024)
    frf = compute_frf(s, SweepOptions(0.5, 2.0, h, locate_peaks=False, stability=False))
    pb = create_problem(s, h)
    sc = pb.scales(0.5, 2.0)
    lam_scale = 2.0 - 0.5
    seg = _Segments(pb, frf.U, frf.omega, frf.info["arrays"]["residual"], scales=sc, lam_scale=lam_scale,
                    newton=NewtonOptions())
    k = int(np.argmax(frf.amplitude(0)))
    chord = np.append((frf.U[k + 1] - frf.U[k]) / sc.x, (frf.omega[k + 1] - frf.omega[k]) / lam_scale)

    def scaled(x, lam):
        return np.append(x / sc.x, lam / lam_scale)

    ratios = []
    for tangents in ((0.0, 0.5), (0.0,)):
        seg.cache.clear()
        seg.tangents.clear()
        seg.point(k, 0.5)
        for t in tangents:
            seg.derivative(k, t)
        x_p, lam_p = seg._predict(k, 0.25)
        x_s, lam_s, _ = seg.point(k, 0.25)
        z_chord = scaled(frf.U[k], frf.omega[k]) + 0.25 * chord
        assert abs((scaled(x_p, lam_p) - z_chord) @ chord) < 1e-12 * (chord @ chord)
        ratios.append(np.linalg.norm(scaled(x_p, lam_p) - scaled(x_s, lam_s))
                      / np.linalg.norm(z_chord - scaled(x_s, lam_s)))
    assert ratios[0] < 0.02 and ratios[1] < 0.1, ratios
