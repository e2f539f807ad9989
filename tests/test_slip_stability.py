"""Hill's method against an event-driven monodromy matrix on Jenkins oscillators with slip
(issue 46, item 4; docs/benchmarks_slip_stability.md, benchmarks/slip_stability.py).

The reference (tests/reference_monodromy.py) is checked first: its monodromy matrix against
central differences of its period map, its orbit against jointfem's HBM solution, and, fully
stuck, against the closed form of the stuck linear system.  jointfem's leading exponent (H = 31,
N = 2048), made with the sliders' memory (Hill's problem with the contact Jacobian of a perturbation
e^(st) v, contact/_floquet.py), is then held to the monodromy's at every point of the benchmark;
Hill's matrix without the memory (the AFT's periodic Jacobian, which replaces the weight
e^(-s tau) by 1) is recorded where it agrees and where not.  The memory-weighted Hill problem
rebuilt on the reference orbit (the benchmark's own, no jointfem code) gives the monodromy's
exponent too (last test).
"""
from __future__ import annotations

import sys
from functools import lru_cache

import numpy as np
import pytest

from conftest import ROOT

sys.path.insert(0, str(ROOT / "benchmarks"))
import reference_monodromy as rm  # noqa: E402
import slip_stability as ss  # noqa: E402

from dataclasses import replace  # noqa: E402

from jointfem.analysis.frf import create_problem, solve_at  # noqa: E402
from jointfem.app import override, sweep_options  # noqa: E402
from jointfem.scene import load_scene  # noqa: E402
from jointfem.harmonics import Harmonics  # noqa: E402
from jointfem.models.lumped import create_lumped  # noqa: E402


@lru_cache(maxsize=None)
def point(kind: str, c: float, omega: float, F: float):
    """(Hill's leading exponent, jointfem's (with the sliders' memory), reference orbit, U,
    harmonics) at the benchmark's (H2, N2) = (31, 2048)."""
    _, U, h, s, s_mem, _ = ss.hbm_point(kind, F, omega, c, ss.H2, ss.N2)
    return s, s_mem, ss.reference_orbit(kind, F, omega, c, U, h), U, h


def rel(kind, c, omega, F, *, memory: bool = True) -> float:
    s, s_mem, orbit, _, _ = point(kind, c, omega, F)
    mono = rm.leading_exponent(orbit)
    return ((s_mem if memory else s).real - mono.real) / abs(mono.real)


@pytest.mark.parametrize("kind,c,omega,F", [("sdof", 0.02, 1.4, 0.599), ("2-DOF", 0.02, 0.9, 1.853)])
def test_monodromy_is_the_derivative_of_the_period_map(kind, c, omega, F):
    """At 40 % (sdof) and 60 % (2-DOF) slip.  The shooting orbit is periodic to 1e-11 (Newton's
    stop; measured 5e-13, 6e-12) and is jointfem's H = 31 solution to 1e-5 of max |x| (measured
    1.8e-6, 2.3e-6: the HBM's truncation; an error of the reference's equations would be of order
    one).  Its monodromy matrix (variational matrices and saltation matrices) equals central
    differences of the period map (step 1e-6, events located afresh) to 1e-6 of max |Phi|
    (measured 1.7e-9, 2.2e-9; the central difference's own error is about 1e-10).  The slider's
    erased memory gives exactly one zero multiplier (below 1e-8 of the largest: ``floquet``
    asserts it), and the exponents do not depend on the start time: from the middle of the
    other stick interval they are the same to 1e-9 1/s."""
    _, _, orbit, U, h = point(kind, c, omega, F)
    assert orbit.residual <= rm.PERIODIC_TOL
    x_ref, _ = rm.sample_orbit(orbit, h.N)
    x_hbm = h.to_time(U.reshape(h.num_hc, -1))
    assert np.abs(x_ref - x_hbm).max() <= 1e-5 * np.abs(x_ref).max()
    fd = rm.flow_map_fd(orbit, eps=1e-6)
    assert np.abs(fd - orbit.Phi).max() <= 1e-6 * np.abs(orbit.Phi).max()
    expo, dropped = rm.floquet(orbit)
    assert expo.size == 2 * orbit.system.n and dropped.size == 1 and abs(dropped[0]) < 1e-8
    # the other stick interval: between the slip->stick event not followed by t0 and the next slip
    ev = orbit.events
    k = next(i for i, e in enumerate(ev) if e.after == 0)
    t1 = 0.5 * (ev[k].t + ev[k + 1].t)
    flow = rm.Flow(orbit.system, omega)
    y1 = flow.run(orbit.t0, orbit.y0, t1 - orbit.t0).y
    other = rm.periodic_orbit(orbit.system, omega, t1, y1)
    key = lambda z: (round(z.real, 8), round(z.imag, 8))  # noqa: E731
    np.testing.assert_allclose(sorted(rm.floquet(other)[0], key=key), sorted(expo, key=key), atol=1e-9)


@pytest.mark.parametrize("kind,c,omega,F", [("sdof", 0.02, 1.4, 0.02), ("sdof", 0.05, 1.4, 0.05),
                                            ("2-DOF", 0.02, 0.9, 0.2)])
def test_stuck_monodromy_is_the_linear_closed_form(kind, c, omega, F):
    """Fully stuck, the monodromy's physical exponents are those of the stuck linear system
    M s^2 + D s + (K + kt G^T G) = 0 folded into the strip: -c/2 (m = 1; the 2-DOF's dampers are
    mass-proportional) ± i the damped frequencies, to 1e-9 (the exact flow: measured 6e-17 in the
    real parts).  The
    slider's direction gives the multiplier 1 (a neighbouring orbit with another slider
    position), dropped.  Hill gives the same real part (measured 3e-15 apart, 1e-9 allowed), and
    with the memory the same exponent (a pair stuck all period has none)."""
    s, s_mem, orbit, _, _ = point(kind, c, omega, F)
    assert s_mem == s
    sy = orbit.system
    assert not orbit.events
    expo, dropped = rm.floquet(orbit)
    np.testing.assert_array_equal(dropped, [1.0])
    Ks = sy.K + sy.kt[0] * np.outer(sy.Gt[0], sy.Gt[0])
    n = sy.n
    lam = np.linalg.eigvals(np.block([[np.zeros((n, n)), np.eye(n)],
                                      [-np.linalg.solve(sy.M, Ks), -np.linalg.solve(sy.M, sy.D)]]))
    folded = lambda z: np.sort_complex(z.real + 1j * (np.mod(z.imag + omega / 2, omega) - omega / 2))  # noqa: E731
    np.testing.assert_allclose(folded(expo), folded(lam), atol=1e-9)
    np.testing.assert_allclose(expo.real, -c / 2, atol=1e-9)
    assert abs(s.real + c / 2) < 1e-9


@pytest.mark.parametrize("kind,c,omega,F", [p[:4] for p in ss.POINTS])
def test_exponent_is_the_monodromy_one_from_stuck_to_gross_slip(kind, c, omega, F):
    """jointfem's leading exponent (Hill's problem with the sliders' memory, contact/_floquet.py)
    against the monodromy's at all 23 points of docs/benchmarks_slip_stability.md, 0 % to 93 % slip,
    the slider-free modes above twice their frequency included: within 1 % of the real part
    (measured at most 0.75 %, the 2-DOF at 25 % slip: the sampled law's switches, first order in the
    sample spacing at N = 2048).  Hill's matrix as it was (the AFT's periodic Jacobian) was off by
    more than 5 % at 14 of these points, by up to 95 %."""
    assert abs(rel(kind, c, omega, F)) <= 0.01


@pytest.mark.parametrize("kind,c,omega,F,measured", [
    ("sdof", 0.02, 1.4, 0.02, 0.0),     # stuck
    ("sdof", 0.02, 1.4, 0.068, 0.008),  # 10 % slip: -0.01689 against -0.01703
    ("sdof", 0.02, 1.4, 0.219, -0.023),  # 25 % slip: -0.08129 against -0.07950
    ("sdof", 0.02, 1.0, 2.0, 0.0001),   # 90 % slip at the slipped resonance: -0.01005 both
    ("2-DOF", 0.02, 0.62, 3.0, -0.001),  # 93 % slip at the slipped system's first resonance
    ("sdof", 0.02, 1.4, 0.599, 0.257),  # 40 % slip: -0.19125 against -0.25747
    ("sdof", 0.02, 2.5, 5.0, 0.952),    # 24 % slip, the slider-free mode: -0.01000 against -0.20987
    ("2-DOF", 0.02, 0.9, 1.853, -0.178),  # 60 % slip: -0.06315 against -0.05362
])
def test_hill_without_the_memory_where_it_agrees_and_where_not(kind, c, omega, F, measured):
    """Hill's matrix without the memory (``leading_exponent(memory=False)``): its relative
    difference from the monodromy, recorded within 1 % (docs/benchmarks_slip_stability.md).  Within
    5 % where the slip is slight or the leading exponent nearly real; up to 95 % elsewhere, where the
    periodic Jacobian's e^(-s tau) = 1 matters, or its slider-free mode -c/2 leads."""
    assert abs(rel(kind, c, omega, F, memory=False) - measured) <= 0.01


def test_a_sweep_records_which_exponents_it_made():
    """Per point, branch.npz ``floquet_method``: "hill-memory" where the slider slips (its memory
    refines Hill's exponents), "hill" where it sticks all period (no memory: Hill's matrix is exact).
    The SDOF Jenkins oscillator at F = 0.2 through its resonance, N = 256.  With the scene's
    ``stability_memory = false`` the same branch has Hill's exponents everywhere, which differ from
    the memory's where it slips."""
    from conftest import sdof
    from jointfem.analysis.frf import SweepOptions, compute_frf

    frf = compute_frf(create_lumped(sdof(0.2)), SweepOptions(0.5, 2.0, Harmonics(7, 256), stability=True))
    method = frf.info["arrays"]["floquet_method"]
    slips = (frf.states == 1).any(axis=(1, 2))
    assert slips.any() and (~slips).any()
    assert np.array_equal(method == "hill-memory", slips)
    # [solver] stability_memory = false: Hill's matrix as it is, everywhere, and its exponents
    opts = sweep_options(override(load_scene(ROOT / "demos" / "sdof_jenkins.toml"), ["solver.stability_memory=false"]))
    assert opts.stability_memory is False
    plain = compute_frf(create_lumped(sdof(0.2)), replace(opts, omega_start=0.5, omega_end=2.0,
                                                          harmonics=Harmonics(7, 256), stability=True))
    assert set(plain.info["arrays"]["floquet_method"]) == {"hill"}
    assert np.array_equal(plain.omega, frf.omega)
    slip = np.flatnonzero(slips)
    moved = np.abs(plain.info["arrays"]["floquet_max_real"][slip] - frf.info["arrays"]["floquet_max_real"][slip])
    assert moved.max() > 1e-3 * np.abs(frf.info["arrays"]["floquet_max_real"][slip]).max()


@pytest.mark.parametrize("kind,c,omega,F", [("sdof", 0.02, 1.4, 0.599), ("sdof", 0.02, 2.5, 5.0)])
def test_memory_weighted_hill_gives_the_monodromy_exponent(kind, c, omega, F):
    """The cause, without jointfem's memory kernel: Hill's problem rebuilt on the reference orbit
    (H = 31, 4096 samples) with the stuck force's memory term weighted by e^(-s tau) (tau the time
    since the stick onset), solved by Newton from Hill's exponent, lands on the monodromy's
    exponent; with the weights set to 1 it gives Hill's exponent back.  Both to 1 % of the real part
    (measured 0.02 % and 0.04 % with the weights, 0.02 % and 5e-13 without; at most 0.3 % and
    1.0 % over the benchmark's 20 slipping points: the first-order quadrature error of the
    stick/slip switches, jointfem sampling 2048 points a period and this 4096)."""
    s, _, orbit, _, _ = point(kind, c, omega, F)
    mono = rm.leading_exponent(orbit)
    on = ss.memory_hill(orbit, ss.H2, ss.NMEM, s, memory=True)
    off = ss.memory_hill(orbit, ss.H2, ss.NMEM, s, memory=False)
    assert abs(on.real - mono.real) <= 0.01 * abs(mono.real), (on, mono)
    assert abs(off.real - s.real) <= 0.01 * abs(s.real), (off, s)


@pytest.mark.parametrize("kind,c,omega,F", [("sdof", 0.02, 1.4, 0.599), ("2-DOF", 0.02, 1.5, 4.0)])
def test_a_sparse_model_gives_the_same_exponent(kind, c, omega, F):
    """A full-order model's Hill problem is sparse (SuperLU, the Arnoldi path): the same oscillator
    assembled sparse gives the dense one's exponent with the memory, to 1e-9 of omega (measured
    1.5e-16), and its method is recorded as the dense one's."""
    from jointfem.analysis.stability import _leading
    from jointfem.hbm.residual import HBMResidual

    h = Harmonics(15, 1024)
    model = create_lumped(ss.SYSTEMS[kind][0](F, c))
    U = solve_at(model, omega, h).U
    pb = create_problem(model, h)
    dense = _leading(pb, U, omega, pb.evaluate(U, omega), None, 24)
    pb.hbm = HBMResidual(model, h, dense=False)
    ev = pb.evaluate(U, omega)
    assert hasattr(ev.J, "tocsr")
    sparse = _leading(pb, U, omega, ev, False, 24)
    assert dense[2] == sparse[2] == "hill-memory"
    assert abs(sparse[0] - dense[0]) <= 1e-9 * omega, (sparse[0], dense[0])
