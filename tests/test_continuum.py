"""The FEniCSx continuum models: gmsh meshes, dolfinx assembly, matched interfaces, SLEPc/MUMPS
offline solves, the exact harmonic condensation, and clear errors for bad meshes.

References: Euler-Bernoulli frequencies (closed form), the beam2d model of the same joint,
and the full-order HBM residual (the condensation must reproduce it to round-off).
"""
from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("dolfinx")

from jointfem.continuation.arclength import NewtonOptions, solve_newton  # noqa: E402
from jointfem.fem import geometry as geo  # noqa: E402
from jointfem.fem.continuum import ContinuumError, ContinuumSpec, build_mesh, create_continuum  # noqa: E402
from jointfem.analysis.frf import create_problem  # noqa: E402
from jointfem.hbm.forced import compute_scales  # noqa: E402
from jointfem.harmonics import Harmonics  # noqa: E402
from jointfem.linalg import LinAlgError, eigen  # noqa: E402
from jointfem.rom import ExactModel  # noqa: E402
from jointfem.scene import SceneError, check_solvable, create_structure, load_scene, parse_scene  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
E, RHO, H, B, L = 2.1e11, 7850.0, 0.006, 0.025, 0.3
BETA_CANT = np.array([1.8751040687, 4.6940911330, 7.8547574382])  # cantilever beta_n L
BETA_CC = np.array([4.7300407449, 7.8532046241, 10.9956078380])  # clamped-clamped


def euler_bernoulli(beta):
    return beta**2 / L**2 * np.sqrt(E * H**2 / 12 / RHO)  # rad/s, bending about the thin axis


def bending_y(structure, num=10):
    """Frequencies (rad/s) of the modes dominated by uy (bending in the thin direction)."""
    w2, Phi = eigen(structure.K_lin, structure.M, num)
    comp = np.array([n.rsplit(".", 1)[1] for n in structure.dof_names])
    share = (Phi[comp == "uy"] ** 2).sum(axis=0) / (Phi**2).sum(axis=0)
    return np.sqrt(w2[share > 0.9])


@pytest.mark.parametrize("dim,clamped_end,beta", [(3, False, BETA_CANT), (3, True, BETA_CC), (2, False, BETA_CANT)])
def test_bar_against_euler_bernoulli(dim, clamped_end, beta):
    """Q2 bars (6 mm thick, 300 mm long) give the first 3 bending frequencies within 1 % of
    Euler-Bernoulli.  What is left is physics the beam theory drops: shear and rotary inertia
    lower mode 3 by about 0.4 % for h/L = 0.02 (Timoshenko: (beta_3 r / L)^2 (1 + E / kappa G) / 2),
    and in 3D the 25 mm width raises it a little (the plate modulus E/(1-nu^2) is the +4.6 % bound
    of a very wide strip); docs/validation.md has the mesh convergence."""
    spec = ContinuumSpec(geometry="bar", dim=dim, clamped=(True, clamped_end), size=0.01, size_normal=0.006)
    w = bending_y(create_continuum(spec))[:3]
    err = w / euler_bernoulli(beta) - 1
    assert np.all(np.abs(err) < 0.01), err


@pytest.fixture(scope="module")
def lap3d():
    spec = ContinuumSpec(geometry="lap", dim=3, size=0.01, size_normal=0.006, kt_total=3e4, kn=2e11,
                         pressure=8e4, outputs=(("a_mid", (0.15, 0.0, 0.0125), "uy"),))
    return spec, create_continuum(spec)


def test_interface_pairs_areas_frames(lap3d):
    """Matched pairs cover the overlap; consistent nodal areas sum to its area; the frames are
    (x, -z, y) for the +y outward normal of A; the preload and stiffness totals are kept."""
    spec, s = lap3d
    g = s.contacts[0]
    pr = g.pairs
    nx = 2 * geo.divisions(spec.overlap, spec.size) + 1  # Q2 nodes along the overlap
    nz = 2 * geo.divisions(spec.width, spec.size) + 1
    assert pr.num_pairs == nx * nz
    area = spec.overlap * spec.width
    assert pr.N0.sum() == pytest.approx(spec.pressure * area, rel=1e-12)
    assert pr.kt.sum() == pytest.approx(3e4, rel=1e-12)
    assert pr.kn.sum() == pytest.approx(2e11 * area, rel=1e-12)
    assert np.all(pr.N0 > 0)
    G = g.gap.toarray()
    P = pr.num_pairs
    # each row is one unit direction on A's node minus the same on B's: normal rows pick uy
    comp = np.array([n.rsplit(".", 1)[1] for n in s.dof_names])
    n_rows = G[2::3]
    assert np.allclose(np.abs(n_rows).sum(axis=1), 2.0)
    assert np.all(comp[np.argmax(n_rows, axis=1)] == "uy")
    assert np.allclose(n_rows.sum(axis=1), 0.0)
    assert np.allclose(np.abs(G[0::3][:, comp == "ux"]).sum(axis=1), 2.0)
    assert np.all(g.coords[:, 1] == pytest.approx(spec.height))
    assert g.coords[:, 0].min() == pytest.approx(spec.length - spec.overlap)
    assert P == len(g.names)


def test_size_joint_refines_the_interface_only():
    """size_joint = 4.2 mm on the 15 mm lap of demos/lap3d_friction_fine.toml: the overlap carries
    17 x 13 Q2 nodes (221 pairs; 25 at 15 mm), the bars keep 15 mm along x away from it (the DOF
    count below), and the pairs' consistent areas still carry the whole preload.  The first three stuck
    frequencies move by 1.2e-3, 3.2e-4 and 4.4e-4 against the uniform 15 mm mesh (measured; the
    width's 2 elements become 6): bounded at 2e-3, a mesh that lost its matching or its clamps
    would move them by far more or be refused."""
    kw = dict(geometry="lap", dim=3, size=0.015, size_normal=0.006, kt=2e11, kn=2e11, pressure=1e6)
    spec = ContinuumSpec(**kw, size_joint=0.0042)
    fine, coarse = create_continuum(spec), create_continuum(ContinuumSpec(**kw))
    nx = geo.divisions(spec.length - spec.overlap, spec.size) + geo.divisions(spec.overlap, spec.size_joint)
    nz = geo.divisions(spec.width, spec.size_joint)
    per_bar = (2 * nx + 1) * (2 * nz + 1) * 3  # Q2 nodes, one element through the thickness
    assert fine.num_dofs == 3 * (2 * per_bar - 2 * (2 * nz + 1) * 3) == 12168
    nxj = 2 * geo.divisions(spec.overlap, spec.size_joint) + 1
    assert fine.num_pairs == nxj * (2 * nz + 1) == 221 and coarse.num_pairs == 25
    assert fine.contacts[0].pairs.N0.sum() == pytest.approx(spec.pressure * spec.overlap * spec.width, rel=1e-12)
    w = [np.sqrt(eigen(s.K_lin, s.M, 3, what="lap")[0]) for s in (fine, coarse)]
    assert np.all(np.abs(w[0] / w[1] - 1) < 2e-3), w


def test_lap_joint_against_beam2d(lap3d):
    """Stuck, the continuum lap joint and the beam2d model of the same joint agree on the
    first two bending modes within 2.5 % (docs/validation.md explains the rest: beam2d's
    rotational springs against the continuum's distributed normal stiffness)."""
    from jointfem.models.beam2d import Beam2DSpec, create_beam2d

    _, s = lap3d
    beam = create_beam2d(Beam2DSpec())
    wb = np.sqrt(eigen(beam.K_lin, beam.M, 2)[0])
    wc = bending_y(s)[:2]
    assert np.all(np.abs(wc / wb - 1) < 0.025), (wc / 2 / np.pi, wb / 2 / np.pi)


def test_brb_free_free_modes():
    """The free-free Brake-Reuss-like beam: six rigid-body modes, found with a negative shift,
    then the elastic modes; the first bending mode lies between the fully open and the
    monolithic bounds (docs/validation.md compares it with the published 168-170 Hz)."""
    spec = ContinuumSpec(geometry="brb", dim=3, length=0.42, height=0.0254, width=0.0254, overlap=0.12,
                         clamped=(False, False), size=0.0254, size_normal=0.0127, degree=2,
                         young=192.85e9, poisson=0.29, density=7857.8, kt=1e12, kn=1e12,
                         force_at=(0.3, 0.0, 0.0127))
    s = create_continuum(spec)
    assert not s.info["supported"]
    w2, _ = eigen(s.K_lin, s.M, 10, sigma=-1e3)
    f = np.sqrt(np.abs(w2)) / 2 / np.pi
    assert np.all(f[:6] < 1.0), f  # rigid-body modes
    Ltot, a = 0.72, 0.0254
    mono = 22.3733 / (2 * np.pi * Ltot**2) * np.sqrt(192.85e9 * a**2 / 12 / 7857.8)  # free-free EB, Hz
    assert 0.5 * mono < f[6] < 1.02 * mono, (f[6], mono)


def test_exact_condensation_equals_full_order():
    """Newton at fixed omega on the full 2D lap joint and on its exact condensation (stick and
    separation at 1700 rad/s, 3 N) solve the same equations: the full solution Yf, taken to the
    gaps and outputs, satisfies the condensed equations to the round-off of forming S, and the two
    solutions differ by no more than that round-off carried through the condensed Jacobian.

    The bound, derived (issue 51: the test asked 1e-8 of the largest output before, and one Intel
    host's OpenBLAS kernels gave 1.38e-8 where others give 5e-9):
    - S_k = R_k^-1 is formed by an LU of the receptance, a backward-stable inverse whose relative
      error is at most c eps kappa(R_k) (c of order 1), so the condensed residual at the exact
      solution is, row by row, at most c eps kappa_k (|J| |Y|)_i, with kappa_k of the row's harmonic
      (1.3e4 to 6.8e4 on harmonics 1-3, 3.4e6 on the static one).  Measured c: 2.6 to 3.8 over the
      host's kernel, Cooperlake, SkylakeX, Haswell, Sandybridge and one thread; asserted with 16.
    - To first order Y - Yf = J^-1 (R(Y) - R(Yf)), so |Y - Yf| <= |J^-1| (|R(Y)| + |R(Yf)|)
      componentwise; the factor 2 covers the second-order terms and the round-off of J^-1 (the
      linear prediction matches the difference to 7e-5 of itself; the difference reaches 0.84 of
      the bound).  That bound is 4e-8 to 7e-8 of the largest output, where the difference is 5e-9
      to 1.4e-8: the old 1e-8 sat inside the spread of round-off.  The bound is also asserted to
      stay below 1e-6 of the output, so that a condensation off by more than round-off fails.
    """
    s = create_structure(load_scene(ROOT / "demos" / "lap2d.toml"))
    h = Harmonics(3, 512)
    full, ex = create_problem(s, h), create_problem(ExactModel(s), h)
    w = 1700.0
    opts = NewtonOptions(tol=1e-12, max_iter=60)

    def solve(pb):
        def fun(U, lam):
            ev = pb.evaluate(U, lam)
            return ev.R, ev.J, ev.dR_dlam
        xs = pb.scales(1550.0, 1800.0).x
        return solve_newton(fun, pb.initial_guess(w), w, x_scale=xs, r_scale=3.0, options=opts)[0]

    U, Y = solve(full), solve(ex)
    states = full.record(U, w, full.evaluate(U, w, jacobian=False)).states
    assert (states == 2).any() and (states == 0).any()  # separates and sticks: a real test of the law
    Yf = (U.reshape(h.num_hc, -1) @ ex.C.T).ravel()
    ev, ev_f = ex.evaluate(Y, w), ex.evaluate(Yf, w, jacobian=False)
    J = ev.J.toarray() if hasattr(ev.J, "toarray") else np.asarray(ev.J)
    kappa = np.array([np.linalg.cond(op.S) for op in ex._operators(w)])
    row_kappa = kappa[(np.arange(J.shape[0]) // ex.r + 1) // 2]  # block j holds harmonic (j + 1) // 2
    floor = 16 * np.finfo(float).eps * row_kappa * (np.abs(J) @ np.abs(Yf))
    assert np.all(np.abs(ev_f.R) <= floor), (np.abs(ev_f.R) / floor).max()
    Jinv = np.linalg.inv(J)
    bound = np.abs(Jinv) @ (np.abs(ev.R) + np.abs(ev_f.R))
    assert np.all(np.abs(Y - Yf) <= 2 * bound)
    assert bound.max() <= 1e-6 * np.abs(Yf).max()


@pytest.mark.parametrize("path", ["modal", "schur"])
def test_exact_condensation_jacobian_fd(path):
    """The condensed residual's Jacobian and omega-derivative against central differences, on the
    modal path and on the Schur path (whose dS/domega is two solves per product)."""
    s = create_structure(load_scene(ROOT / "demos" / "lap2d.toml"))
    h = Harmonics(2, 128)
    ex = create_problem(ExactModel(s) if path == "modal" else ExactModel(s, modal=False, sparse="schur"), h)
    assert ex.branch_info() == {"condensation": path}
    w = 1700.0
    rng = np.random.default_rng(3)
    Y = ex.initial_guess(w) * 2.0 + 1e-7 * rng.standard_normal(ex.num_unknowns)
    ev = ex.evaluate(Y, w)
    d = 1e-7 * np.abs(Y).max() * rng.standard_normal(Y.size)
    fd = 0.5 * (ex.evaluate(Y + d, w, jacobian=False).R - ex.evaluate(Y - d, w, jacobian=False).R)
    assert np.abs(fd - ev.J @ d).max() <= 1e-5 * np.abs(ev.J @ d).max()
    dw = 0.2  # rad/s: S = R^-1 of an ill-conditioned receptance carries ~1e-9 relative round-off
    fdw = (ex.evaluate(Y, w + dw, jacobian=False).R - ex.evaluate(Y, w - dw, jacobian=False).R) / (2 * dw)
    assert np.abs(fdw - ev.dR_dlam).max() <= 1e-5 * np.abs(ev.dR_dlam).max()


def test_exact_condensation_modal_path_equals_the_lu_path(monkeypatch):
    """The modal path (one eigendecomposition, hbm.condensed) gives the sparse-LU path's operators
    and solution on the 2D lap joint (Rayleigh damping), also with the EPMC's xi; a damping that is
    not diagonal in the modes falls back to a sparse factorisation (MUMPS's Schur complement here,
    SuperLU where asked), and refuses the modal path when it is required.

    Tolerances: both paths carry the round-off of S = R^-1 of a receptance whose condition number
    reaches 1e8 (CondensedProblem.tol_floor); measured here S 2e-10, its derivatives and the linear
    response up to 2e-9."""
    import scipy.sparse as sp

    from jointfem.hbm import condensed
    from jointfem.hbm.condensed import CondensedProblem, modal_basis

    s = create_structure(load_scene(ROOT / "demos" / "lap2d.toml"))
    h = Harmonics(2, 128)
    ex = create_problem(ExactModel(s), h)
    lu = CondensedProblem(s, h, modal=False, sparse="lu")
    assert ex.branch_info() == {"condensation": "modal"} and lu.branch_info() == {"condensation": "lu"}
    # Rayleigh damping is recognised, so the stiff modes' share is summed as a series (_stiff); the
    # third omega is above what the first split covers, so the split is formed again
    alpha, beta = ex._modal[5]
    assert abs(alpha / 4.391 - 1) < 1e-6 and abs(beta / 4.368e-6 - 1) < 1e-6
    cuts = []
    for w, xi, orders in ((1650.0, 0.0, ()), (1711.3, 0.4, (1,)), (3000.0, 0.0, ())):
        ops = ex._operators(w, xi, orders)
        cuts.append(ex._split[0])
        assert ex._split[3].sum() <= 12  # modes summed one by one at each omega, of 720: measured 8 and 10
        for a, b in zip(ops, lu._operators(w, xi, orders)):
            for name, tol in (("S", 1e-8), ("dS", 1e-7), ("dSxi", 1e-7), ("ylin", 1e-7), ("dylin", 1e-7), ("T", 1e-7)):
                x, y = getattr(a, name), getattr(b, name)
                if y is None:
                    assert x is None
                    continue
                assert np.abs(x - y).max() <= tol * max(np.abs(y).max(), 1e-300), (w, name)
    assert cuts[0] == cuts[1] > cuts[2]
    # the series is what makes it exact: cut after its second term, S is off by 100 times the
    # tolerance above at least (measured 5.9e-6 of its largest entry)
    short = create_problem(ExactModel(s), h)
    monkeypatch.setattr(condensed, "SPLIT_ORDER", 1)
    S1, S2 = short._operators(1650.0)[1].S, lu._operators(1650.0)[1].S
    assert np.abs(S1 - S2).max() > 1e-6 * np.abs(S2).max()
    monkeypatch.undo()
    opts = NewtonOptions(tol=1e-12, max_iter=60)
    w = 1700.0

    def solve(pb):
        def fun(U, lam):
            ev = pb.evaluate(U, lam)
            return ev.R, ev.J, ev.dR_dlam
        return solve_newton(fun, pb.initial_guess(w), w, x_scale=pb.scales(1550.0, 1800.0).x, r_scale=3.0,
                            options=opts)[0]

    Y1, Y2 = solve(ex), solve(lu)
    # each path lands within about 1e-8 of the full-order solution (test_exact_condensation_equals_full_order),
    # so they are 2e-8 apart at most: measured 1.9e-8
    assert np.abs(Y1 - Y2).max() <= 3e-8 * np.abs(Y2).max()
    U1, U2 = ex.full_coefficients(Y1, w), lu.full_coefficients(Y1, w)
    assert np.abs(U1 - U2).max() <= 1e-8 * np.abs(U2).max()
    # a damping matrix that is not diagonal in the modes (a dashpot on one DOF)
    D = s.D + sp.csr_matrix(([1e-3 * s.D.diagonal().max()], ([5], [5])), shape=s.D.shape)
    odd = dataclasses.replace(s, D=D)
    assert modal_basis(odd) is None
    with pytest.raises(LinAlgError, match="not diagonal in the modes"):
        modal_basis(odd, required=True)
    assert create_problem(ExactModel(odd), h).branch_info() == {"condensation": "schur"}
    assert create_problem(ExactModel(odd, sparse="lu"), h).branch_info() == {"condensation": "lu"}


def test_petsc_and_scipy_backends_agree(lap3d, monkeypatch):
    """SLEPc shift-invert and MUMPS give the modes and static solves of ARPACK and SuperLU, and
    MUMPS on the real block form the complex solves of SuperLU."""
    from jointfem import linalg

    _, s = lap3d
    assert linalg.backend(s.num_dofs) == "petsc"
    w_p, Phi_p = linalg.eigen(s.K_lin, s.M, 6)
    X_p = linalg.Factorized(s.K_lin).solve(s.fc)
    monkeypatch.setenv("JOINTFEM_LINALG", "scipy")
    w_s, Phi_s = linalg.eigen(s.K_lin, s.M, 6)
    X_s = linalg.Factorized(s.K_lin).solve(s.fc)
    # rtol 1e-9: mode 1 (w^2 = 3.4e5) of this slender lap is fixed by K only to about 1e-9 at round-off
    # (K's entries changed at random by 1e-15 of themselves move w1 by 4e-10 to 8e-10, measured), so two
    # backward-stable solvers may differ by that much: measured 1.6e-11 on Debian 12 (PETSc 3.18),
    # 1.5e-10 on Debian 13 (PETSc 3.22, MUMPS 5.7), where ARPACK and SLEPc agree no closer
    assert np.allclose(w_p, w_s, rtol=1e-9)
    assert np.abs(np.abs(Phi_p.T @ (s.M @ Phi_s)) - np.eye(6)).max() < 1e-8
    # 5e-9: K's entries changed at random by 1e-15 of themselves move this static solution by 2e-10 to
    # 3e-9 (measured on both stacks); MUMPS against SuperLU measured 9.9e-11 on Debian 12, 5.6e-10 on Debian 13
    assert np.abs(X_p - X_s).max() <= 5e-9 * np.abs(X_s).max()
    # a complex dynamic stiffness (the exact condensation's): MUMPS on the real 2n form against SuperLU
    w = 1700.0
    Z = (s.K - w**2 * s.M + 1j * w * s.D).tocsr()
    B = s.contacts[0].gap.T.toarray()[:, :20]
    Y_s = linalg.Factorized(Z).solve(B)
    monkeypatch.setenv("JOINTFEM_LINALG", "petsc")
    monkeypatch.setenv("JOINTFEM_MUMPS_COMPLEX", "1")
    F = linalg.Factorized(Z)
    assert type(F).__name__ == "_MumpsComplex"
    Y_p = F.solve(B)
    assert np.abs(Y_p - Y_s).max() <= 1e-8 * np.abs(Y_s).max()


@pytest.mark.parametrize("dim", [2, 3])
def test_unstructured_interfaces_match(dim):
    """Triangles/tetrahedra, B's contact face a periodic copy of A's: the pairs still match, the
    consistent areas (degree 1) sum to the overlap's area.  Degree 2: in 3D the contact faces are
    P2 triangles, whose corner weights are zero, so it is refused; in 2D they are P2 edges (weights
    1/6, 2/3, 1/6), which work."""
    kw = dict(geometry="lap", dim=dim, size=0.005, size_normal=0.003, structured=False, kt_total=3e4, kn=2e11,
              pressure=8e4, force_at=(0.15, 0.0, 0.0125)[:dim])
    s = create_continuum(ContinuumSpec(degree=1, **kw))
    area = 0.03 * 0.025
    assert s.contacts[0].pairs.N0.sum() == pytest.approx(8e4 * area, rel=1e-12)
    assert s.contacts[0].pairs.num_pairs >= 5
    if dim == 3:
        with pytest.raises(ContinuumError, match="zero area"):
            create_continuum(ContinuumSpec(degree=2, **kw))
    else:
        s2 = create_continuum(ContinuumSpec(degree=2, **kw))
        assert s2.contacts[0].pairs.N0.sum() == pytest.approx(8e4 * area, rel=1e-12)


def test_mesh_written_through_meshio(tmp_path):
    """[mesh] file: the gmsh mesh is written once (atomically) and reads back with its cells."""
    import meshio

    path = tmp_path / "meshes" / "lap2d.msh"
    s = create_continuum(ContinuumSpec(geometry="lap", dim=2, size=0.01, size_normal=0.006, kt_total=3e4, kn=2e11,
                                       force_at=(0.15, 0.0), mesh_file=str(path)))
    m = meshio.read(path)
    assert sum(len(c.data) for c in m.cells if c.type == "quad") == s.info["cells"]
    assert not list(path.parent.glob("*.tmp*"))


# ---- bad meshes and bad scenes -----------------------------------------------------------------

def _spec_with_layout(monkeypatch, layout, **kw):
    spec = ContinuumSpec(geometry="lap", dim=2, size=0.01, size_normal=0.006, kt_total=3e4, kn=2e11, **kw)
    monkeypatch.setattr(ContinuumSpec, "layout", lambda self: layout)
    return spec


def test_unmatched_interface_is_refused(monkeypatch):
    """Shift B's overlap block by 1 mm along x: the faces no longer match node to node."""
    lay = geo.lap_layout(2, L, H, B, 0.03)
    boxes = list(lay.boxes)
    boxes[2] = dataclasses.replace(boxes[2], x=boxes[2].x + 0.001)
    boxes[3] = dataclasses.replace(boxes[3], x=boxes[3].x + 0.001)
    bad = dataclasses.replace(lay, boxes=tuple(boxes), contact=(lay.contact[0], lay.contact[1] + 0.001, H))
    with pytest.raises(ContinuumError, match="do not match node to node"):
        create_continuum(_spec_with_layout(monkeypatch, bad))


def test_empty_contact_surface_is_refused(monkeypatch):
    """B lifted 1 mm above A: no face lies on the joint plane."""
    lay = geo.lap_layout(2, L, H, B, 0.03)
    boxes = [dataclasses.replace(b, y=b.y + 0.001) if b.sub == 1 else b for b in lay.boxes]
    bad = dataclasses.replace(lay, boxes=tuple(boxes))
    with pytest.raises(ContinuumError, match="contact surface is empty"):
        create_continuum(_spec_with_layout(monkeypatch, bad))


def test_unmatched_interface_from_the_cli(tmp_path, monkeypatch, capsys):
    """The command line reports a mesh error in one line with exit code 2, and writes nothing."""
    from jointfem.cli import main

    lay = geo.lap_layout(2, L, H, B, 0.03)
    boxes = [dataclasses.replace(b, y=b.y + 0.001) if b.sub == 1 else b for b in lay.boxes]
    monkeypatch.setattr(ContinuumSpec, "layout", lambda self: dataclasses.replace(lay, boxes=tuple(boxes)))
    assert main(["frf", str(ROOT / "demos" / "lap2d.toml"), "--quiet", "--out", str(tmp_path / "out")]) == 2
    assert "contact surface is empty" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_free_free_substructure_refused_before_work(tmp_path):
    """A lap joint with B unsupported is refused by the scene check (no meshing), naming the key;
    building its penalty ROM anyway fails with a clear LinAlgError, not a NaN."""
    data = load_scene(ROOT / "demos" / "lap2d.toml").data
    data = {**data, "geometry": {**data["geometry"], "clamped": ["A"]}}
    scene = parse_scene(data, tmp_path / "free.toml")
    with pytest.raises(SceneError, match=r"geometry.clamped.*substructure B has no supports"):
        check_solvable(scene)
    s = create_structure(scene)
    from jointfem.rom import build_rom
    with pytest.raises(LinAlgError, match="rigid-body"):
        create_problem(ExactModel(s), Harmonics(1, 8))  # harmonic 0: K of the free B is singular
    assert s.info["supported"]  # A is clamped; B hangs on the stuck joint only
    build_rom(s, "penalty")  # the stuck joint holds B: the linearised model is regular


def test_size_joint_on_an_unstructured_mesh_is_refused(tmp_path):
    """size_joint sets transfinite divisions: an unstructured mesh has none, so it is refused by name."""
    data = load_scene(ROOT / "demos" / "lap2d.toml").data
    data = {**data, "mesh": {**data["mesh"], "structured": False, "size_joint": 0.002}}
    with pytest.raises(SceneError, match="structured meshes only") as exc:
        parse_scene(data, tmp_path / "bad.toml")
    assert "mesh.size_joint" in str(exc.value)


@pytest.mark.parametrize("section,key,value,match", [
    ("mesh", "size", 0.05, "at least one element in the joint"),
    ("mesh", "degree", 3, "must be 1 or 2"),
    ("force", "at", [0.9, 0.0], "outside the model's bounding box"),
    ("contact", "kt", 1e9, "give exactly one of kt"),
    ("geometry", "shape", "ring", "must be one of"),
    ("mesh", "structured", "no", "must be true or false"),
    ("mesh", "size_joint", 0.05, "at least one element in the joint"),
    ("mesh", "size_joint", 0.0, "must be > 0"),
])
def test_bad_continuum_scene(tmp_path, section, key, value, match):
    data = load_scene(ROOT / "demos" / "lap2d.toml").data
    data = {**data, section: {**data[section], key: value}}
    with pytest.raises(SceneError, match=match) as exc:
        parse_scene(data, tmp_path / "bad.toml")
    assert f"{section}.{key}" in str(exc.value)


# ---- MPI --------------------------------------------------------------------------------------

def _mpirun():
    cmd = ["mpirun", "--oversubscribe", "-n", "2"]
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        cmd.insert(1, "--allow-run-as-root")
    return cmd


def same_curve(serial: Path, other: Path):
    """Assert that the FRF in folder ``other`` lies on the one in ``serial``: the same first point to
    1e-8, every point on a cubic spline through the serial points to 1e-6 of the peak, the same peak
    to 1e-4 (the points' omegas differ: see test_mpi_two_ranks_equal_serial).  Returns both tables."""
    from scipy.interpolate import CubicSpline

    a = np.loadtxt(serial / "frf.csv", delimiter=",", skiprows=1)
    b = np.loadtxt(other / "frf.csv", delimiter=",", skiprows=1)
    assert a[0, 0] == b[0, 0]
    # each sweep ends at its own first step past omega_end, so their last omegas differ by a hair
    # either way (5e-8 rad/s on one machine); the spline is compared where it interpolates
    inside = b[:, 0] <= a[-1, 0]
    assert inside.sum() >= b.shape[0] - 1
    for c in range(2, a.shape[1]):
        peak = a[:, c].max()
        assert abs(a[0, c] - b[0, c]) <= 1e-8 * a[0, c], c
        assert np.abs(CubicSpline(a[:, 0], a[:, c])(b[inside, 0]) - b[inside, c]).max() <= 1e-6 * peak, c
        assert b[:, c].max() == pytest.approx(peak, rel=1e-4)
    return a, b


@pytest.mark.slow
def test_mpi_two_ranks_equal_serial(tmp_path):
    """`mpirun -n 2 python -m jointfem frf` (distributed assembly, SLEPc and MUMPS) gives the
    serial FRF to 1e-8, written once, pictures included."""
    scene = tmp_path / "lap2d.toml"
    text = (ROOT / "demos" / "lap2d.toml").read_text()
    scene.write_text(text.replace("amplitude = 3.0", "amplitude = 1.0").replace("size = 0.01", "size = 0.0025")
                     .replace("size_normal = 0.006", "size_normal = 0.003"))
    from jointfem import linalg
    n = create_structure(load_scene(scene)).num_dofs
    assert linalg.backend(n) == "petsc", n  # big enough that SLEPc and MUMPS run distributed
    env = dict(os.environ, JOINTFEM_LINALG="petsc")
    args = [sys.executable, "-m", "jointfem", "frf", str(scene), "--method", "penalty", "--modes", "10",
            "--quiet", "--out"]
    subprocess.run(args + [str(tmp_path / "serial")], check=True, env=env, cwd=ROOT, timeout=600)
    subprocess.run(_mpirun() + args[:-1] + ["--plots", "--out", str(tmp_path / "mpi")], check=True, env=env, cwd=ROOT,
                   timeout=600)
    assert len(list((tmp_path / "mpi").glob("interface_*.png"))) == 1  # drawn once, by rank 0
    # The ROM's modal coordinates (and so the arclength metric and the points' omegas) depend on
    # the eigenvectors SLEPc returns, which differ between layouts within its tolerance; the
    # physical curve does not.  The first point (the linear solution at omega_min, the same omega
    # on both) agrees to 1e-8 (measured 4e-10); every MPI point lies on the serial curve: a cubic
    # spline through the serial points, evaluated at the MPI omegas (at most 0.02 rad/s from a
    # serial point, against steps of 0.6 rad/s or more), matches to 1e-6 of the peak (measured 2e-7,
    # while the points' own omegas drift by up to 1e-5 relative along the branch).
    a, _ = same_curve(tmp_path / "serial", tmp_path / "mpi")
    # both sweeps cover the range: each ends at its own first step past omega_end (1800 rad/s)
    assert min(a[-1, 0], np.loadtxt(tmp_path / "mpi" / "frf.csv", delimiter=",", skiprows=1)[-1, 0]) >= 1800.0
    import json
    sa = json.loads((tmp_path / "mpi" / "summary.json").read_text())
    assert sa["mpi_ranks"] == 2


def test_mpi_error_is_printed_once(tmp_path):
    """Under mpirun every rank meets the same bad scene; the one-line error comes from rank 0 only."""
    r = subprocess.run(_mpirun() + [sys.executable, "-m", "jointfem", "frf", str(ROOT / "demos" / "sdof_jenkins.toml"),
                                    "--set", "jenkins[0].mu=-1", "--out", str(tmp_path / "o")],
                       capture_output=True, text=True, cwd=ROOT, timeout=300,
                       env=dict(os.environ))  # Python's view: without MPI_Init's own variables (this
    # process imported dolfinx, a singleton MPI, which set some in the C environment; mpirun then fails)
    assert r.stderr.count("jointfem: error:") == 1, r.stderr
    assert "jenkins[0].mu = -1" in r.stderr
