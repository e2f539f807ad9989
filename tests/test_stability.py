"""Stability of every point by Hill's method (jointfem.analysis.stability): Floquet exponents
against the closed form of a linear system, and stable/unstable parts of a branch with folds
against a time integration of the same equations."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.integrate import solve_ivp

from pathlib import Path

from conftest import sdof
from jointfem.analysis.frf import SweepOptions, compute_frf, create_problem
from jointfem.analysis.stability import floquet_exponents
from jointfem.contact import UnilateralSprings
from jointfem.continuation.arclength import ContinuationOptions
from jointfem.harmonics import Harmonics
from jointfem.models.lumped import create_lumped
from jointfem.models.structure import ContactGroup, Structure

ROOT = Path(__file__).resolve().parents[1]


def test_linear_floquet_exponents_are_the_eigenvalues_folded_into_the_strip():
    """A linear 2-DOF system: its Floquet exponents about any periodic solution are the roots of
    det(K + s D + s^2 M) = 0, each shifted by a multiple of i omega into |Im s| <= omega / 2."""
    K = np.array([[3.0, -1.0], [-1.0, 2.0]])
    M = np.diag([1.0, 0.5])
    D = 0.02 * K + 0.01 * M
    s = Structure(K=sp.csr_matrix(K), M=sp.csr_matrix(M), D=sp.csr_matrix(D), fc=np.array([1.0, 0.0]),
                  fs=np.zeros(2))
    h = Harmonics(6, 32)
    omega = 0.9
    pb = create_problem(s, h)
    x = pb.initial_guess(omega)
    ev = pb.evaluate(x, omega)
    d1, d2 = pb.hill_operators(omega)
    got = floquet_exponents(ev.J, d1, d2, pb.num_dynamic())
    assert pb.num_dynamic() == 4
    # closed form: the quadratic eigenvalues, folded
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.linalg.solve(M, K), -np.linalg.solve(M, D)]])
    lam = np.linalg.eigvals(A)
    folded = lam.real + 1j * (np.mod(lam.imag + omega / 2, omega) - omega / 2)
    key = lambda z: (round(z.real, 9), round(z.imag, 9))  # noqa: E731
    np.testing.assert_allclose(sorted(got, key=key), sorted(folded, key=key), atol=1e-9)


def test_friction_oscillator_is_stable_and_stuck_exponents_are_the_damping():
    """The SDOF Jenkins oscillator (one branch, no fold) is stable at every point; where it sticks
    its exponents are those of the stuck linear system, -c/2 (m = 1)."""
    frf = compute_frf(create_lumped(sdof(0.2)), SweepOptions(0.5, 2.0, Harmonics(7, 128)))
    a = frf.info["arrays"]
    assert frf.info["stability"] == "computed" and a["stable"].all() and not a["fold"].any()
    stuck = (frf.states == 0).all(axis=(1, 2))
    assert stuck.sum() > 10
    np.testing.assert_allclose(a["floquet_max_real"][stuck], -0.01, atol=1e-9)
    assert (a["floquet_max_real"][~stuck] < 0).all()


F, C, K2, GAP = 0.1, 0.02, 1.0, 1.0  # N, N s/m, N/m, m


def _hardening():
    """m = k = 1 with a one-sided spring K2 beyond GAP: a hardening oscillator whose forced
    response folds over, with an unstable middle branch between its two folds."""
    law = UnilateralSprings(k=[K2], gap=[GAP])
    return Structure(K=sp.csr_matrix([[1.0]]), M=sp.identity(1, format="csr"), D=sp.csr_matrix([[C]]),
                     fc=np.array([F]), fs=np.zeros(1), contacts=(ContactGroup(law, sp.csr_matrix([[1.0]])),),
                     dof_names=("x",), outputs={"x": 0})


def _time_integrated_amplitude(h, x, omega, periods=150):
    """First-harmonic amplitude of the last of ``periods`` periods of the same equation, integrated
    (DOP853) from the HBM orbit's state at t = 0."""
    X = x.reshape(h.num_hc, 1)
    u0 = h.to_time(X)[0, 0]
    v0 = omega * h.to_time(h.derivative_matrix() @ X)[0, 0]

    def rhs(t, y):
        return [y[1], F * np.cos(omega * t) - y[0] - C * y[1] - K2 * max(y[0] - GAP, 0.0)]

    T = 2 * np.pi / omega
    sol = solve_ivp(rhs, (0.0, periods * T), [u0, v0], method="DOP853", rtol=1e-10, atol=1e-12,
                    t_eval=np.linspace((periods - 1) * T, periods * T, h.N + 1)[:-1])
    Y = h.from_time(sol.y[0])
    return float(np.hypot(Y[1], Y[2]))


def test_fold_middle_branch_is_unstable_against_time_integration():
    """Upper and lower branches stable, the middle one unstable.  Time integration (150 periods,
    e^-19 of a transient decaying at c/2) started from points marked stable stays on their orbit to
    1 % (measured 2e-4 and 4e-11); from points marked unstable (growth 0.007 and 0.018 1/s) it
    leaves by more than 5 % (measured 11 % and 82 %)."""
    h = Harmonics(9, 256)
    frf = compute_frf(_hardening(), SweepOptions(0.7, 1.5, h, ContinuationOptions(ds_max=0.05)))
    a = frf.info["arrays"]
    A, w, stable = frf.amplitude(0), frf.omega, a["stable"]
    assert a["fold"].sum() >= 2 and (~stable).sum() > 10
    top = int(np.argmax(A))
    # the middle branch: between the upper fold and the lower one (the last turn of omega)
    low_fold = int(np.flatnonzero(a["fold"])[-1])
    middle = np.arange(top + 1, low_fold)
    middle = middle[(w[middle] < w[top] - 0.005) & (w[middle] > w[low_fold] + 0.005)]
    assert middle.size > 5 and not stable[middle].any()
    # a fold's middle branch loses its stability by a real exponent (branch.npz says which kind)
    assert (a["floquet_leading_imag"][middle] <= 1e-9 * w[middle]).all()
    upper = np.flatnonzero((np.arange(w.size) < top) & (A > 3.0) & (w < w[top] - 0.005))
    lower = np.flatnonzero((np.arange(w.size) > low_fold) & (w > w[top] + 0.05))
    assert stable[upper].all() and stable[lower].all()
    for i in (upper[len(upper) // 2], lower[0]):
        assert abs(_time_integrated_amplitude(h, frf.U[i], w[i]) / A[i] - 1) < 0.01, (i, w[i])
    for i in (middle[len(middle) // 3], middle[2 * len(middle) // 3]):
        assert a["floquet_max_real"][i] > 0
        assert abs(_time_integrated_amplitude(h, frf.U[i], w[i]) / A[i] - 1) > 0.05, (i, w[i])


def test_stability_is_skipped_above_the_automatic_size_limit():
    frf = compute_frf(create_lumped(sdof(0.2)), SweepOptions(0.5, 2.0, Harmonics(7, 128), stability_auto_unknowns=10))
    assert frf.info["stability"].startswith("not computed: 15 unknowns > 10")
    forced = compute_frf(create_lumped(sdof(0.2)), SweepOptions(0.5, 2.0, Harmonics(7, 128), stability=True,
                                                                stability_auto_unknowns=10))
    assert forced.stable is not None and forced.stable.all()
    assert "floquet_max_real" not in frf.info["arrays"] and frf.stable is None  # no NaN written for "unknown"


def test_unstable_parts_are_drawn_dashed(tmp_path):
    """plot_branch draws stable segments solid and the others dashed; a segment between a stable
    and an unstable point counts as unstable (both lines share that point)."""
    from jointfem.plots import plot_branch, pyplot

    plt = pyplot()
    fig, ax = plt.subplots()
    x = np.arange(6.0)
    stable = np.array([True, True, True, False, False, True])
    plot_branch(ax, x, x**2, stable, label="a")
    solid, dashed = ax.get_lines()
    assert solid.get_linestyle() == "-" and dashed.get_linestyle() == "--"
    np.testing.assert_array_equal(np.isfinite(solid.get_ydata()), [True, True, True, False, False, False])
    np.testing.assert_array_equal(np.isfinite(dashed.get_ydata()), [False, False, True, True, True, True])
    # each unstable point marked: a run of a few unstable points on a fold is shorter than a dash
    assert dashed.get_marker() == "o" and list(dashed.get_markevery()) == [3, 4]
    plt.close(fig)


def test_exponents_near_zero_give_the_dense_verdict_on_the_separating_beam():
    """Shift-invert Arnoldi (the path above DENSE_LIMIT first-order unknowns) against the dense
    eigenproblem, through max_real_part on the same Jacobians: the paper's beam at 3 N (H = 5,
    N = 256), on the Craig-Bampton ROM (dense J, every 8th point of the branch: stuck, separating,
    folds) and at full order (sparse J, three points).  The largest real parts agree to 1e-6 omega
    (measured 1.1e-7 omega: the dense eigenvalues of a non-normal 600-2600 matrix carry that
    round-off; a stuck point's exponent -2.962198 1/s, the Rayleigh damping of mode 1, comes out of
    the Arnoldi path to 7 digits and of the dense one to 5), and the verdicts are equal."""
    import dataclasses

    from jointfem.analysis.stability import is_stable, max_real_part
    from jointfem.app import sweep_options
    from jointfem.rom import RomOptions, build_rom
    from jointfem.scene import create_structure, load_scene

    scene = load_scene(ROOT / "demos" / "beam2d.toml")
    scene = dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, harmonics=5, samples=256))
    structure = create_structure(scene)
    sweep = sweep_options(scene, stability="off")
    cb = build_rom(structure, "cb", RomOptions(modes=10))
    frf = compute_frf(cb, sweep)
    cases = [(cb, frf.U[i], frf.omega[i]) for i in range(0, frf.omega.size, 8)]
    # full order at three of the ROM's points: its solution there, by Newton from the ROM's field
    from jointfem.analysis.frf import solve_at
    sep = np.flatnonzero((frf.states == 2).any(axis=(1, 2)))
    nh = sweep.harmonics.num_hc
    for i in (0, sep[0], sep[sep.size // 2]):
        guess = (frf.U[i].reshape(nh, -1) @ cb.basis.T).ravel()
        cases.append((structure, solve_at(structure, frf.omega[i], sweep.harmonics, guess=guess).U, frf.omega[i]))
    verdicts = []
    for model, U, omega in cases:
        pb = create_problem(model, sweep.harmonics)
        ev = pb.evaluate(U, omega, jacobian=True)
        dense = max_real_part(pb, U, omega, ev, dense=True)
        near = max_real_part(pb, U, omega, ev, dense=False)
        assert abs(dense - near) < 1e-6 * omega, (omega, dense, near)
        assert is_stable(dense, omega) == is_stable(near, omega), (omega, dense, near)
        verdicts.append(is_stable(near, omega))
    assert any(verdicts) and not all(verdicts)  # both kinds of point were compared


def test_exact_condensation_has_the_full_models_stability():
    """The exact condensation's points get Hill's stability of the full model at their full field
    (CondensedProblem.full_coefficients): on the beam at 3 N (H = 5, N = 256), over the separating
    part of the branch.  At every 10th point the recovered field is the full-order solution (Newton
    on the full model from it moves it by at most 1e-7 of its largest coefficient; the condensation's
    tolerance floor is 1e-8 of the force), and the full-order problem's own largest real part there
    equals the one recorded on the condensed branch to 1e-5 omega (measured 2.2e-6 omega, next to a
    fold, where the exponent moves fastest with the point: 100.6822 against 100.6859 1/s); the branch
    has stable and unstable points."""
    import dataclasses

    from jointfem.analysis.frf import solve_at
    from jointfem.analysis.stability import max_real_part
    from jointfem.rom import build_rom
    from jointfem.scene import create_structure, load_scene

    scene = load_scene(ROOT / "demos" / "beam2d.toml")
    scene = dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, harmonics=5, samples=256))
    structure = create_structure(scene)
    h = Harmonics(5, 256)
    exact = build_rom(structure, "exact")
    frf = compute_frf(exact, SweepOptions(1570.0, 1760.0, h, ContinuationOptions(ds_max=0.05), stability=True))
    a = frf.info["arrays"]
    assert frf.info["stability"] == "computed"
    assert a["stable"].any() and not a["stable"].all()
    cp, fp = create_problem(exact, h), create_problem(structure, h)
    for i in range(0, frf.omega.size, 10):
        U = cp.full_coefficients(frf.U[i], frf.omega[i])
        polished = solve_at(structure, frf.omega[i], h, guess=U).U
        assert np.abs(polished - U).max() <= 1e-7 * np.abs(U).max(), i
        re = max_real_part(fp, polished, frf.omega[i], fp.evaluate(polished, frf.omega[i], jacobian=True))
        assert abs(re - a["floquet_max_real"][i]) < 1e-5 * frf.omega[i], (i, re, a["floquet_max_real"][i])


@pytest.mark.slow
def test_beam_separated_fold_loop_stability_against_time_integration():
    """The paper's beam at 3 N on its converged branch (H = 41, N = 1024, exact condensation, event
    AFT: the peak within 0.1 % of H = 41 from H = 21 on), over its first fold loop (1688 to
    1690.6 rad/s, where the joint starts to separate).  Hill's method on the full model at the
    points' full fields gives what a fold must: the leading exponent is real where the branch
    turns, and passes zero at both folds; stable on the lower and upper parts, unstable between.
    Newmark (demos/beam_timeint_check.py, 1000 steps a period, 60 periods) started on each orbit:
    from the stable separated points of the lower and upper parts it stays within 1 % (first
    harmonic, amplitude and phase; measured 1.6e-4 to 1.1e-3 with 2000 steps over 150 periods in
    make bench-stability); from the middle branch it leaves (e past 1 % within 60 periods), its
    departure growing at a rate within 25 % of Hill's largest real part.  Measured: 150 1/s against
    Hill's 126.7 here; 143 against 129 at a neighbour with 2000 steps.  The rate is the slope of
    log e over 1e-4 < e < 1e-2, over which the period-to-period growth itself falls from about 2.0 to
    1.6 (Hill: e^{129 T} = 1.62): the departure is not one clean exponential, the contact law being
    piecewise linear, so closer agreement is not to be expected of the fit."""
    import dataclasses
    import sys

    sys.path.insert(0, str(ROOT / "demos"))
    from beam_timeint_check import departure, growth_rate

    from jointfem.analysis.stability import leading_exponent
    from jointfem.app import override_harmonics
    from jointfem.rom import build_rom
    from jointfem.scene import create_structure, load_scene

    sc = override_harmonics(load_scene(ROOT / "demos" / "beam2d.toml"), 41, 1024)
    sc = dataclasses.replace(sc, solver=dataclasses.replace(sc.solver, aft="events"))
    structure = create_structure(sc)
    h = Harmonics(41, 1024)
    exact = build_rom(structure, "exact")
    frf = compute_frf(exact, SweepOptions(1688.0, 1690.6, h, ContinuationOptions(ds_max=0.05), stability=False))
    assert frf.info["status"] == "complete"
    w = frf.omega
    turns = 1 + np.flatnonzero(np.sign(np.diff(w[1:])) * np.sign(np.diff(w[:-1])) < 0)
    assert turns.size == 2, w[turns]  # the upper fold (omega turns back), then the lower one
    upper_fold, lower_fold = turns
    sep = (frf.states == 2).any(axis=(1, 2))
    pb = create_problem(exact, h)

    def lead(i):  # by the Arnoldi path, as the sweep would take it at this size
        return leading_exponent(pb, frf.U[i], w[i], pb.evaluate(frf.U[i], w[i], jacobian=True), dense=False)

    # at the folds a real exponent passes zero: small and real there (negative on the outer parts and
    # positive on the middle branch, below)
    for f in (upper_fold, lower_fold):
        s = lead(f)
        assert abs(s.imag) < 1e-6 * w[f] and abs(s.real) < 5.0, (w[f], s)
    lower = int(np.flatnonzero(sep[:upper_fold])[len(np.flatnonzero(sep[:upper_fold])) // 2])  # separated, stable
    middle = (upper_fold + lower_fold) // 2
    upper = lower_fold + int(np.argmin(np.abs(w[lower_fold:] - 1690.2)))
    s_lower, s_middle, s_upper = lead(lower), lead(middle), lead(upper)
    assert s_lower.real < 0 and s_upper.real < 0, (s_lower, s_upper)
    assert s_middle.real > 50.0 and abs(s_middle.imag) < 1e-6 * w[middle], s_middle
    dof = structure.outputs["b1.mid.uy"]
    for i in (lower, upper):
        e = departure(structure, pb.full_coefficients(frf.U[i], w[i]), w[i], h, periods=60, steps=1000, dof=dof)
        assert e.max() < 0.01, (w[i], e.max())
    e = departure(structure, pb.full_coefficients(frf.U[middle], w[middle]), w[middle], h, periods=60, steps=1000,
                  dof=dof)
    assert e.max() > 0.01
    rate = growth_rate(e, w[middle])
    assert rate is not None and abs(rate / s_middle.real - 1) < 0.25, (rate, s_middle)


def jenkins_chain(n=20, F=0.3):
    """n unit masses in a fixed-free chain of unit springs, each on a Jenkins slider to ground
    (kt = 1, slip force 0.5), 0.02 viscous damping, forced at the free end."""
    from jointfem.models.lumped import ForceSpec, JenkinsSpec, LinkSpec, LumpedSpec, MassSpec

    names = [f"m{i}" for i in range(n)]
    return LumpedSpec(
        masses=tuple(MassSpec(nm, 1.0) for nm in names),
        springs=(LinkSpec("m0.x", "ground", 1.0),) + tuple(LinkSpec(f"{a}.x", f"{b}.x", 1.0) for a, b in zip(names, names[1:])),
        dampers=tuple(LinkSpec(f"{nm}.x", "ground", 0.02) for nm in names),
        jenkins=tuple(JenkinsSpec(nm, "ground", ("x",), None, kt=1.0, kn=0.0, mu=1.0, N0=0.5) for nm in names),
        forces=(ForceSpec(f"{names[-1]}.x", F),), outputs=(f"{names[-1]}.x",))


def test_stability_is_computed_by_default_at_any_size_and_gives_the_dense_exponents():
    """A sweep computes stability by default whatever its size: the 20-mass Jenkins chain at H = 5
    has 220 unknowns (440 first-order, above DENSE_LIMIT: the Arnoldi path, its count of eigenvalues
    carried from point to point by ExponentTracker), with pairs stuck and slipping.  At every 6th point
    its recorded largest real part equals the dense eigenproblem's to 1e-7 omega (the chain is not
    stiff: both paths carry round-off far below that; STABILITY_RTOL, the verdict's margin, is 1e-7
    omega too) and the verdicts are equal."""
    from jointfem.analysis.stability import DENSE_LIMIT, is_stable, max_real_part

    s = create_lumped(jenkins_chain())
    h = Harmonics(5, 128)
    frf = compute_frf(s, SweepOptions(0.9, 1.2, h, ContinuationOptions(ds_max=0.05)))
    pb = create_problem(s, h)
    assert 2 * pb.hill_size > DENSE_LIMIT
    assert frf.info["stability"] == "computed"
    assert (frf.states == 1).any() and (frf.states == 0).any()
    re = frf.info["arrays"]["floquet_max_real"]
    for i in range(0, frf.omega.size, 6):
        w = frf.omega[i]
        dense = max_real_part(pb, frf.U[i], w, pb.evaluate(frf.U[i], w, jacobian=True), dense=True)
        assert abs(dense - re[i]) < 1e-7 * w, (w, dense, re[i])
        assert is_stable(dense, w) == frf.stable[i]


def test_a_failed_eigensolve_keeps_the_sweep_and_says_why(monkeypatch):
    """An eigensolve that fails at a point (here ARPACK, made to fail at every point above 1.05
    rad/s) leaves the sweep whole: its points are kept, status complete, and the stability is
    reported not computed with the count and the first failure, with no floquet arrays (no NaN
    written for "unknown")."""
    import scipy.sparse.linalg as spla

    from jointfem.analysis import stability

    real = stability.arnoldi_near

    def failing(J, d1, d2, omega, **kw):
        if omega > 1.05:
            raise spla.ArpackNoConvergence("no convergence (test)", np.array([]), np.array([]))
        return real(J, d1, d2, omega, **kw)

    monkeypatch.setattr(stability, "arnoldi_near", failing)
    frf = compute_frf(create_lumped(jenkins_chain()), SweepOptions(0.9, 1.2, Harmonics(5, 128),
                                                                   ContinuationOptions(ds_max=0.05)))
    assert frf.info["status"] == "complete" and frf.omega.max() >= 1.2
    msg = frf.info["stability"]
    assert msg.startswith("not computed: Hill's eigensolve failed at ") and "ArpackNoConvergence" in msg, msg
    n_fail = int(msg.split("failed at ")[1].split(" of ")[0])
    assert 0 < n_fail == int((frf.omega > 1.05).sum())
    assert frf.stable is None and "floquet_max_real" not in frf.info["arrays"]


def test_the_exact_condensation_leaves_stability_out_unless_asked():
    """Its Hill problem is the full model's at every point (CondensedProblem.hill_matrices), far
    larger than what Newton solves: "auto" leaves it out and says why; True computes it (above)."""
    from jointfem.rom import build_rom

    exact = build_rom(create_lumped(jenkins_chain(4)), "exact")
    frf = compute_frf(exact, SweepOptions(0.9, 1.2, Harmonics(3, 64)))
    assert frf.info["stability"].startswith("not computed: the exact condensation's stability is the full model's")
    assert frf.stable is None


def test_the_exponent_count_of_a_large_sparse_mass_needs_no_dense_svd(monkeypatch):
    """count_exponents: 2 per coordinate with mass, 1 per massless damped direction.  Above
    COUNT_DENSE coordinates a sparse positive definite M is recognised by the inertia of a sparse
    LDL^T, without the dense SVD (minutes for a continuum's 10k DOFs, issue 50); a singular one
    (a zero on the diagonal, or rank-deficient without one) gets the dense count, the same as
    before."""
    from jointfem.hbm import problem

    n = 2 * problem.COUNT_DENSE
    rng = np.random.default_rng(3)
    # a consistent-mass-like SPD matrix: a 1D chain's banded mass, each row dominated by its diagonal
    M = sp.diags([np.full(n - 1, 1.0), np.full(n, 4.0) + rng.random(n), np.full(n - 1, 1.0)], [-1, 0, 1], format="csr")
    D = 1e-3 * M
    dense = problem.count_exponents(M.toarray(), D.toarray())
    assert dense == 2 * n

    def no_svd(*args, **kwargs):
        raise AssertionError("dense SVD")

    with monkeypatch.context() as m:
        m.setattr(problem.np.linalg, "svd", no_svd)
        assert problem.count_exponents(M, D) == 2 * n
    # massless coordinates: 10 zero rows and columns of M, 4 of them damped
    keep = np.ones(n)
    keep[:10] = 0.0
    Ms = sp.diags(keep) @ M @ sp.diags(keep)
    Ds = sp.lil_matrix((n, n))
    for i in range(4):
        Ds[i, i] = 1.0
    assert problem.count_exponents(Ms.tocsr(), Ds.tocsr()) == 2 * (n - 10) + 4
    # rank-deficient without a zero on the diagonal: M = B B^T of rank n - 1 (one pair of equal rows)
    B = M.tolil()
    B[1, :] = B[0, :]
    Mr = (B @ B.T).tocsr()
    assert np.all(Mr.diagonal() > 0)
    assert problem.count_exponents(Mr, sp.csr_matrix((n, n))) == problem.count_exponents(Mr.toarray(), np.zeros((n, n))) == 2 * (n - 1)
