"""Reductors return reduced models that check their bases, reconstruct the physical DOFs and offer
an HBM problem of the one protocol (jointfem.hbm.problem)."""
from __future__ import annotations

import numpy as np
import pytest

from jointfem.analysis.frf import create_problem
from jointfem.harmonics import Harmonics
from jointfem.hbm.problem import PointRecord, Problem, Scales
from jointfem.models.beam2d import Beam2DSpec, create_beam2d
from jointfem.rom import METHODS, BasisError, RomError, RomOptions, build_rom
from jointfem.rom.common import check_modes, project
from jointfem.linalg import eigen

RAYLEIGH = dict(damping="rayleigh", rayleigh_alpha=4.391, rayleigh_beta=4.368e-6)


def _beam():
    return create_beam2d(Beam2DSpec(elements=6, force=1.0, **RAYLEIGH))


def test_dependent_basis_is_refused():
    """A basis with two equal columns has a singular reduced mass: BasisError names the method."""
    s = _beam()
    _, Phi = eigen(s.K_lin, s.M, 4, what="test")
    T = np.column_stack([Phi, Phi[:, 1]])
    with pytest.raises(BasisError, match="cb basis.*rank deficient"):
        project(s, T, "cb")
    with pytest.raises(BasisError, match="non-finite"):
        project(s, np.where(np.arange(Phi.shape[0])[:, None] == 0, np.nan, Phi), "cb")
    project(s, Phi, "cb")  # the modes themselves pass


def test_modes_that_are_not_mass_normalised_are_refused():
    s = _beam()
    _, Phi = eigen(s.K_lin, s.M, 4, what="test")
    check_modes(Phi, s.M, "modes")
    with pytest.raises(BasisError, match=r"not M-orthonormal: max \|Phi\^T M Phi - I\| = 3\.000e\+00"):
        check_modes(2 * Phi, s.M, "modes")  # Phi^T M Phi = 4 I: off by 3 on the diagonal


@pytest.mark.parametrize("method", [m for m in METHODS if m != "full"])
def test_every_reduction_offers_a_problem_and_reconstructs(method):
    """Each reductor's model gives a Problem whose unknowns, scales, initial guess and record fit
    together; the Ritz models reconstruct u = T z, the exact condensation says it cannot."""
    s = _beam()
    h = Harmonics(2, 32)
    rom = build_rom(s, method, RomOptions(modes=6))
    pb = create_problem(rom, h)
    assert isinstance(pb, Problem)
    x = pb.initial_guess(2150.0)
    assert x.shape == (pb.num_coefficients,) == (pb.layout.num_coords * h.num_hc,)
    sel = pb.unknowns()
    n = x.size if sel is None else sel.size
    assert pb.num_unknowns == n
    if method == "penalty":  # all stuck at the start: modes only, the 6 internal variables (3 pairs, t and n) no unknowns
        assert n == 6 * h.num_hc and x.size == (6 + 6) * h.num_hc
    sc = pb.scales(2100.0, 2250.0)
    assert isinstance(sc, Scales) and sc.x.shape == x.shape and np.all(sc.x > 0)
    # the residual's scale is the largest force on the solved coordinates: the physical 1 N on the
    # gaps and outputs of the exact condensation, T^T f on a Ritz model's
    # (the dual Craig-Bampton's compatibility rows carry k C G_res f, in N: its own reduced force)
    force = 1.0 if method == "exact" else np.abs(rom.structure.fc if method == "dcb" else rom.basis.T @ s.fc).max()
    assert sc.r == pytest.approx(force, rel=1e-12) or method == "penalty"  # penalty: p rows carry no force
    assert 0 < sc.r <= force * (1 + 1e-12)
    ev = pb.evaluate(x, 2150.0)
    assert ev.J.shape == (n, n) and ev.dR_dlam.shape == ev.R.shape == (n,)
    rec = pb.record(x, 2150.0, ev)
    assert isinstance(rec, PointRecord) and rec.states.shape == (h.N, s.num_pairs)
    assert rec.pair_summary.shape == (s.num_pairs, 3)
    assert len(pb.layout.pair_names) == s.num_pairs and set(pb.layout.outputs) == set(s.outputs)
    if method == "exact":
        assert rom.basis is None
        with pytest.raises(RomError, match="cannot be reconstructed"):
            rom.reconstruct(x)
        return
    Z = x.reshape(h.num_hc, -1)
    u = rom.reconstruct(Z)
    np.testing.assert_allclose(u, Z @ rom.basis.T)
    # the stuck linear solution reconstructed is the full model's to the ROM's accuracy at the
    # drive point (six modes of a beam, far from their truncation near 2150 rad/s)
    full = create_problem(s, h).initial_guess(2150.0).reshape(h.num_hc, -1)
    dof = s.outputs["b1.mid.uy"]
    assert abs(u[1, dof] / full[1, dof] - 1) < 0.05
