"""Nonlinear modes (analysis.nma, EPMC): the describing function's closed form, the Jacobian by
central differences, the forced FRF's peaks on the backbone, the penalty ROM's backbone, and the
command line with its [nma] table."""
from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from conftest import ROOT, sdof

from jointfem.analysis.frf import SweepOptions, compute_frf, create_problem
from jointfem.analysis.nma import (CondensedModalProblem, ModalProblem, NmaError, NmaOptions, compute_backbone,
                                  modal_problem, synthesize_frf)
from jointfem.cli import main
from jointfem.harmonics import Harmonics
from jointfem.models.lumped import ForceSpec, JenkinsSpec, LinkSpec, LumpedSpec, MassSpec, create_lumped
from jointfem.models.structure import with_event_aft
from jointfem.rom import RomOptions, build_rom
from jointfem.scene import SceneError, load_scene


def jenkins_describing(a):
    """The SDOF Jenkins oscillator's nonlinear mode at H = 1 (m = k = kt = Fs = 1, no damper), from
    the describing function of the slider (stuck below a = Fs/kt = 1): omega^2 = k + K_eq(a), and
    zeta = W / (2 pi a^2 omega^2), W = 4 Fs (a - Fs/kt) the energy dissipated per cycle."""
    a = np.asarray(a, float)
    slip = a > 1.0
    phi = np.arccos(np.clip(1.0 - 2.0 / np.where(slip, a, 1.0), -1.0, 1.0))
    keq = np.where(slip, (phi - 0.5 * np.sin(2.0 * phi)) / np.pi, 1.0)
    W = np.where(slip, 4.0 * (a - 1.0), 0.0)
    w = np.sqrt(1.0 + keq)
    return w, W / (2.0 * np.pi * a**2 * w**2), W


def sdof_structure(F=0.0, c=0.0):
    return with_event_aft(create_lumped(sdof(F, c=c)))


def test_closed_form_at_one_harmonic():
    """H = 1 is the describing function: with the event-accurate AFT (exact to 1e-13 on this law)
    the backbone matches it to 1e-9 in omega and zeta over stuck, microslip and gross slip; the
    self-excitation's energy equals the slider's own dissipation (no damper)."""
    bb = compute_backbone(sdof_structure(), NmaOptions(amplitude_start=0.1, amplitude_end=10.0,
                                                       harmonics=Harmonics(1, 64)))
    assert bb.info["status"] == "complete" and bb.amplitude[-1] >= 10.0
    assert np.count_nonzero(bb.amplitude > 1.05) > 10  # well into slip
    w, z, W = jenkins_describing(bb.amplitude)
    assert np.abs(bb.omega - w).max() < 1e-9
    assert np.abs(bb.zeta - z).max() < 1e-9
    E, Ej = bb.info["arrays"]["energy_J"], bb.info["arrays"]["joint_energy_J"]
    assert np.abs(E - W).max() <= 1e-8 * W.max()
    assert np.abs(Ej - W).max() <= 1e-8 * W.max()
    # the amplitude is the output's first harmonic, and the phase is fixed there
    assert np.allclose(bb.output_amplitude("m.x"), bb.amplitude, rtol=1e-12)


HARMONIC_TABLE = {}


@pytest.mark.parametrize("H", [1, 3, 5, 7])
def test_harmonics_converge(H):
    """H = 1, 3, 5, 7 at the amplitudes 2, 5 and 20 (microslip to gross slip): the change from
    H = 5 to H = 7 is below 1e-3 in omega and 2e-3 in zeta (relative), ten times less than from
    H = 1 to H = 3 (docs/nma.md has the table)."""
    amps = np.array([2.0, 5.0, 20.0])
    bb = compute_backbone(sdof_structure(), NmaOptions(amplitude_start=0.5, amplitude_end=25.0,
                                                       harmonics=Harmonics(H, 64), at=tuple(amps)))
    at = [bb.info["at"][a] for a in amps]
    HARMONIC_TABLE[H] = (np.array([p["omega_rad_s"] for p in at]), np.array([p["zeta"] for p in at]))
    if H == 1:
        w, z, _ = jenkins_describing(amps)
        assert np.allclose(HARMONIC_TABLE[1][0], w, rtol=1e-9) and np.allclose(HARMONIC_TABLE[1][1], z, rtol=1e-8)
    if H == 7 and all(k in HARMONIC_TABLE for k in (1, 3, 5)):
        d13 = [np.abs(HARMONIC_TABLE[3][i] / HARMONIC_TABLE[1][i] - 1).max() for i in (0, 1)]
        d57 = [np.abs(HARMONIC_TABLE[7][i] / HARMONIC_TABLE[5][i] - 1).max() for i in (0, 1)]
        assert d57[0] < 1e-3 and d57[1] < 2e-3
        assert d57[0] < 0.1 * d13[0] and d57[1] < 0.1 * d13[1]


def chain(F=0.3, static=0.5, cubic=True, outputs=("a.x", "b.x")):
    """A 2-DOF chain: mass a (x, z) on a Jenkins pair with a normal axis to ground (preload 1 N),
    a cubic spring between a.x and b.x, a damper, and a static force on b.x."""
    return LumpedSpec(
        masses=(MassSpec("a", 1.0, ("x", "z")), MassSpec("b", 0.5, ("x",))),
        springs=(LinkSpec("a.x", "ground", 1.0), LinkSpec("a.z", "ground", 3.0), LinkSpec("a.x", "b.x", 2.0)),
        dampers=(LinkSpec("b.x", "ground", 0.05),),
        jenkins=(JenkinsSpec("a", "ground", ("x",), "z", kt=1.5, kn=4.0, mu=0.4, N0=1.0),),
        cubic=(LinkSpec("a.x", "b.x", 0.7),) if cubic else (),
        forces=(ForceSpec("b.x", F, static=static),), outputs=outputs)


def test_jacobian_by_central_differences():
    """dR/dx (the omega and xi columns included) and dR/dlam of the EPMC residual against central
    differences, at a slipping, lifting point with a static force, on the sampled law."""
    s = create_lumped(chain())
    p = ModalProblem(create_problem(s, Harmonics(3, 128)), 1, "b.x")
    errors = fd_errors(p)
    assert errors[0] < 1e-6 and errors[1] < 1e-6


def fd_errors(p) -> tuple[float, float]:
    """(dR/dx, dR/dlam) of an EPMC problem against central differences, relative to the largest
    entry, at a slipping, lifting point (x perturbed from the linear mode, xi = 0.2, a = 1.5)."""
    rng = np.random.default_rng(3)
    x = p.initial_guess(0.0)
    x[:p.nc] += 0.3 * rng.standard_normal(p.nc) * np.abs(x[:p.nc]).max()
    x[p.nc + 1] = 0.2
    lam = math.log10(1.5)
    ev = p.evaluate(x, lam)
    J = ev.J.toarray() if hasattr(ev.J, "toarray") else ev.J
    Jfd = np.empty_like(J)
    for j in range(x.size):
        e = np.zeros(x.size)
        e[j] = 1e-6 * max(1.0, abs(x[j]))
        Jfd[:, j] = (p.evaluate(x + e, lam, jacobian=False).R - p.evaluate(x - e, lam, jacobian=False).R) / (2 * e[j])
    d = (p.evaluate(x, lam + 1e-6, jacobian=False).R - p.evaluate(x, lam - 1e-6, jacobian=False).R) / 2e-6
    return (float(np.abs(J - Jfd).max() / np.abs(J).max()),
            float(np.abs(ev.dR_dlam - d).max() / np.abs(ev.dR_dlam).max()))


@pytest.mark.parametrize("F", [0.1, 0.2, 0.3])
def test_forced_peak_lies_on_the_backbone(F):
    """The SDOF oscillator with light damping (c = 0.02) at three levels: the forced sweep's located
    peak lies on the backbone within 0.1 % in omega, and the single-mode synthesis from the backbone
    finds the peak amplitude within 2 % (measured: 1.3e-4, 2.4e-4 and 4.2e-4 in omega; 5.4e-4,
    8.2e-4 and 2.3e-4 in amplitude; docs/benchmarks_nma.md)."""
    h = Harmonics(5, 64)
    bb = compute_backbone(sdof_structure(1.0, c=0.02), NmaOptions(amplitude_start=0.1, amplitude_end=30.0,
                                                                  harmonics=h))
    frf = compute_frf(sdof_structure(F, c=0.02), SweepOptions(0.5, 2.5, harmonics=h))
    pk = frf.info["peaks"]["m.x"]
    assert pk.located and not pk.edge
    w_bb = np.interp(np.log(pk.amplitude), np.log(bb.amplitude), bb.omega)
    assert abs(w_bb / pk.omega - 1) < 1e-3
    syn = synthesize_frf(bb, F)
    assert abs(syn["peak_amplitude"] / pk.amplitude - 1) < 0.02


def test_penalty_rom_backbone_resizes_and_matches_full_order():
    """On the 2-DOF chain with every mode kept, the penalty ROM is the full model: its backbone
    equals full order's, while its size follows the pair's activity along the amplitude.  (Without
    the cubic spring: the penalty ROM gives a spring of zero stuck stiffness an internal variable
    with a zero pivot.)"""
    s = create_lumped(chain(cubic=False))
    at = (0.05, 0.5, 1.0, 2.0)
    opts = NmaOptions(amplitude_start=1e-2, amplitude_end=3.0, output="a.x", harmonics=Harmonics(3, 128), at=at)
    full = compute_backbone(s, opts)
    pen = compute_backbone(build_rom(s, "penalty", RomOptions(modes=3, tvd=0)), opts)
    sizes = pen.info["arrays"]["rom_size"]
    assert sizes.min() == 3 and sizes.max() == 4  # stuck at small amplitude; the tangential component active at large
    assert full.zeta.max() > 3 * full.zeta[0]  # friction damping dominates at the large amplitudes
    for a in at:
        f, p = full.info["at"][a], pen.info["at"][a]
        assert abs(p["omega_rad_s"] / f["omega_rad_s"] - 1) < 1e-8 and abs(p["zeta"] / f["zeta"] - 1) < 1e-7, a


def exact_chain():
    # the amplitude is measured at b.x: an output on a DOF that is also a gap (a.x, its pair to
    # ground) would make the condensation's receptance singular
    return create_lumped(chain(static=0.0, cubic=False, outputs=("b.x",)))


@pytest.mark.parametrize("excitation", ["all", "fundamental"])
def test_exact_condensation_jacobian_by_central_differences(excitation):
    """The EPMC inside the condensation (xi in the dynamic stiffness): dR/dx with the omega and xi
    columns, and dR/dlam, against central differences at a slipping, lifting point (measured
    7e-11 and 2e-10 of the largest entry)."""
    p = modal_problem(create_problem(build_rom(exact_chain(), "exact", RomOptions()), Harmonics(3, 128)), 1, "b.x",
                      excitation=excitation)
    assert isinstance(p, CondensedModalProblem)
    errors = fd_errors(p)
    assert errors[0] < 1e-8 and errors[1] < 1e-8


def test_exact_condensation_backbone_equals_full_order():
    """The condensation is exact, and so is its EPMC: the backbone through stuck, microslip and
    lift-off equals full order's, in omega, zeta, the energy per cycle and the modal terms, which
    the condensation takes from the full field it recovers (measured 2e-10 and 1.4e-9 at a = 0.5,
    1e-12 elsewhere)."""
    s = exact_chain()
    at = (0.05, 0.5, 1.0, 2.0)
    opts = NmaOptions(amplitude_start=1e-2, amplitude_end=3.0, output="b.x", harmonics=Harmonics(3, 128), at=at)
    full = compute_backbone(s, opts)
    ex = compute_backbone(build_rom(s, "exact", RomOptions()), opts)
    assert ex.info["status"] == "complete" and full.zeta.max() > 3 * full.zeta[0]
    for a in at:
        f, e = full.info["at"][a], ex.info["at"][a]
        assert abs(e["omega_rad_s"] / f["omega_rad_s"] - 1) < 1e-8 and abs(e["zeta"] / f["zeta"] - 1) < 1e-7, a
        # the full field's energy (harmonics 1 to 3) and modal mass, recovered from the gaps
        assert abs(e["energy_J"] / f["energy_J"] - 1) < 1e-7 and abs(e["modal_mass_kg"] / f["modal_mass_kg"] - 1) < 1e-8, a
    f_f, f_e = full.info["arrays"]["modal_force_N"][0], ex.info["arrays"]["modal_force_N"][0]
    assert abs(f_e - f_f) < 1e-10 * abs(f_f)


def test_exact_condensation_recovers_an_output_that_is_a_gap():
    """The SDOF oscillator's output m.x is its pair's gap to ground: the condensation recovers it
    from the gap instead of retaining it twice (which made the receptance singular), and its
    forced sweep and backbone equal full order's."""
    s = sdof_structure(0.2, c=0.02)
    ex = build_rom(s, "exact", RomOptions())
    p = create_problem(ex, Harmonics(3, 64))
    assert p.layout.num_coords == 1 and np.ndim(p.layout.outputs["m.x"]) == 1
    h = Harmonics(3, 64)
    # peaks to omega_rtol (peak_share = 0): the same top whatever points each branch has
    pk_f = compute_frf(s, SweepOptions(0.5, 2.5, harmonics=h, peak_share=0.0)).info["peaks"]["m.x"]
    pk_e = compute_frf(ex, SweepOptions(0.5, 2.5, harmonics=h, peak_share=0.0)).info["peaks"]["m.x"]
    assert abs(pk_e.omega / pk_f.omega - 1) < 1e-8 and abs(pk_e.amplitude / pk_f.amplitude - 1) < 1e-8
    opts = NmaOptions(amplitude_start=0.1, amplitude_end=10.0, harmonics=h, at=(0.5, 2.0, 8.0))
    bf, be = compute_backbone(s, opts), compute_backbone(ex, opts)
    for a in opts.at:
        assert abs(be.info["at"][a]["zeta"] / bf.info["at"][a]["zeta"] - 1) < 1e-8
        assert abs(be.info["at"][a]["omega_rad_s"] / bf.info["at"][a]["omega_rad_s"] - 1) < 1e-8


def test_output_at_a_node_of_the_mode_is_refused():
    s = create_lumped(chain(outputs=("a.x", "a.z")))  # mode 1 of the chain moves x only: a.z is a node of it
    with pytest.raises(NmaError, match="does not move in mode 1"):
        ModalProblem(create_problem(s, Harmonics(3, 64)), 1, "a.z")


SCENE = (ROOT / "demos" / "sdof_jenkins.toml").read_text()


@pytest.mark.parametrize("table, key", [
    ("[nma]\namplitude_range = [1.0, 0.1]\n", "nma.amplitude_range"),
    ("[nma]\namplitude_range = [0.0, 1.0]\n", "nma.amplitude_range"),
    ("[nma]\namplitude_range = 1.0\n", "nma.amplitude_range"),
    ("[nma]\nmode = 1\n", "nma.amplitude_range"),
    ("[nma]\namplitude_range = [0.1, 1.0]\nmode = 0\n", "nma.mode"),
    ("[nma]\namplitude_range = [0.1, 1.0]\nmodes = 1\n", "nma.modes"),
    ("[nma]\namplitude_range = [0.1, 1.0]\noutput = \"m.y\"\n", "nma.output"),
    ("[nma]\namplitude_range = [0.1, 1.0]\nmode = 2\n", "nma.mode"),
    ("", "[nma]"),
])
def test_bad_nma_tables(tmp_path, capsys, table, key):
    """One line naming the file and the key, exit 2, nothing written."""
    base = SCENE.split("[nma]")[0]
    path = tmp_path / "s.toml"
    path.write_text(base + table)
    out = tmp_path / "out"
    assert main(["nma", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    # (a key given names its value, a key missing says so: "nma.amplitude_range: required key is missing")
    assert len(err.splitlines()) == 1 and (f"{key} =" in err or f"{key}: " in err) and "s.toml" in err
    assert not out.exists()


def test_cli_writes_a_backbone_folder(tmp_path, capsys):
    out, frf = tmp_path / "nma", tmp_path / "frf"
    assert main(["frf", str(ROOT / "demos" / "sdof_jenkins.toml"), "--out", str(frf), "--quiet",
                 "--harmonics", "3", "--samples", "64"]) == 0
    assert main(["nma", str(ROOT / "demos" / "sdof_jenkins.toml"), "--out", str(out), "--quiet",
                 "--harmonics", "3", "--samples", "64", "--frf", str(frf)]) == 0
    for f in ("backbone.csv", "branch.npz", "summary.json", "backbone.png", "frf_synthesized.png"):
        assert (out / f).is_file(), f
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "complete" and summary["analysis"] == "nma"
    tab = np.genfromtxt(out / "backbone.csv", delimiter=",", names=True)
    assert np.allclose(tab["freq_Hz"], tab["omega_rad_s"] / (2 * np.pi))
    assert tab["amplitude_m"][0] == pytest.approx(0.1) and tab["amplitude_m"][-1] >= 30.0
    # stuck below Fs/kt = 1 m: the linear mode, sqrt(2) rad/s and c / (2 sqrt(2)) = 0.00707
    stuck = tab["amplitude_m"] < 0.99
    assert np.allclose(tab["omega_rad_s"][stuck], math.sqrt(2), rtol=1e-10)
    assert np.allclose(tab["damping_ratio"][stuck], 0.02 / (2 * math.sqrt(2)), rtol=1e-8)
    # `jointfem plot` reads a backbone's folder as a sweep's
    assert main(["plot", str(out), "--quiet"]) == 0
    assert (out / "states_branch.png").is_file()


def test_cli_keeps_an_incomplete_backbone(tmp_path, capsys):
    out = tmp_path / "nma"
    assert main(["nma", str(ROOT / "demos" / "sdof_jenkins.toml"), "--out", str(out), "--quiet",
                 "--set", "solver.max_points=5"]) == 3
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "incomplete" and summary["num_points"] == 5
    assert "amplitude" in summary["stop_reason"] and "lam" not in summary["stop_reason"]
    assert "incomplete" in capsys.readouterr().err


def test_fundamental_self_excitation_balances_the_joint_energy():
    """self-excitation on the fundamental only: the energy it puts in per cycle is still the slider's
    own dissipation (no damper; to 1e-5: the pair's energy is the loop summed over the N = 64 samples,
    6e-7 off for either variant), and at H = 5 the backbone stays within 1e-3 of the classic EPMC's
    on this oscillator without internal resonance (measured: 1.4e-4 in omega, 2.3e-3 in zeta)."""
    opts = NmaOptions(amplitude_start=0.5, amplitude_end=20.0, harmonics=Harmonics(5, 64), at=(2.0, 10.0))
    fund = compute_backbone(sdof_structure(), replace(opts, excitation="fundamental"))
    full = compute_backbone(sdof_structure(), opts)
    E, Ej = fund.info["arrays"]["energy_J"], fund.info["arrays"]["joint_energy_J"]
    assert np.abs(E - Ej).max() <= 1e-5 * Ej.max()
    for a in (2.0, 10.0):
        f, g = fund.info["at"][a], full.info["at"][a]
        assert abs(f["omega_rad_s"] / g["omega_rad_s"] - 1) < 1e-3 and abs(f["zeta"] / g["zeta"] - 1) < 1e-2


def test_compare_backbones_from_the_command_line(tmp_path):
    """`compare --analysis nma`: the penalty ROM of the SDOF oscillator (its one mode and the slider's
    internal variable: the full model) has the full model's backbone at every compared amplitude."""
    out = tmp_path / "cmp"
    assert main(["compare", str(ROOT / "demos" / "sdof_jenkins.toml"), "--analysis", "nma", "--methods",
                 "penalty:1:0", "--out", str(out), "--quiet", "--harmonics", "3", "--samples", "64"]) == 0
    rows = np.genfromtxt(out / "compare.csv", delimiter=",", names=True, dtype=None, encoding=None)
    pen = rows[rows["method"] == "penalty:1"][0]
    assert pen["amplitudes_compared"] == 12 and pen["size_min"] == 1 and pen["size_max"] == 2
    assert pen["omega_rel_err"] < 1e-9 and pen["zeta_rel_err"] < 1e-8
    assert (out / "compare_backbone.png").is_file() and "omega rel err" in (out / "compare.md").read_text()


def test_beam_forced_peaks_lie_on_the_backbone():
    """The paper's beam with the friction-dominated joint (demos/beam2d_friction.toml, H = 3, N = 256),
    mode 2: forced sweeps at 0.7, 1.0 and 1.4 N (stick-slip) peak on the backbone within 0.1 % in
    omega, and the single-mode synthesis finds their peak amplitudes within 2 % (measured: 1.8e-5,
    8.9e-6, 1.0e-4 in omega; 1.4e-3, 4.6e-5, 4.2e-4 in amplitude; docs/benchmarks_nma.md)."""
    from jointfem import app

    scene = app.override(load_scene(ROOT / "demos" / "beam2d_friction.toml"),
                         ["solver.harmonics=3", "solver.samples=256"])
    from jointfem.scene import create_structure

    bb = compute_backbone(create_structure(scene), app.nma_options(scene))
    assert bb.info["status"] == "complete" and bb.zeta.max() > 1.4 * bb.zeta[0]  # friction damping shows
    out = bb.output
    for F in (0.7, 1.0, 1.4):
        frf = compute_frf(create_structure(app.override(scene, [f"force.amplitude={F}"])),
                          app.sweep_options(scene, stability="off"))
        pk = frf.info["peaks"][out]
        assert pk.located and not pk.edge
        w_bb = np.interp(np.log(pk.amplitude), np.log(bb.amplitude), bb.omega)
        assert abs(w_bb / pk.omega - 1) < 1e-3
        assert abs(synthesize_frf(bb, F / 1.4)["peak_amplitude"] / pk.amplitude - 1) < 0.02


@pytest.mark.parametrize("args, key", [(["--mode", "0"], "mode = 0"), (["--frf", "/nonexistent"], "frf = ")])
def test_bad_nma_arguments(tmp_path, capsys, args, key):
    """A mode below 1 and an --frf folder without a sweep: one line, exit 2, nothing written."""
    out = tmp_path / "out"
    assert main(["nma", str(ROOT / "demos" / "sdof_jenkins.toml"), "--out", str(out), "--quiet"] + args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and key in err
    assert not out.exists()


def test_synthesis_reports_the_largest_peak_and_says_when_it_is_detached():
    """Issue 50, item 4: summary.json's synthesized_peak was the first place where the two
    branches meet, while the picture drew a larger, detached part (beam mode 2: 1.10e-4 against
    about 2.8e-4 m).  A backbone whose damping ratio rises and falls again, omega = 1 rad/s, m = 1,
    modal force 1: an amplitude a is reachable when 1 / a^2 >= 4 zeta^2 (1 - zeta^2), i.e. below
    a* = 1 / (2 zeta sqrt(1 - zeta^2)).  zeta = 0.2 up to a = 2, 0.5 from 3 to 5, 0.1 after: a* is
    2.55 at 0.2 (not reached: the first part ends where zeta jumps), 1.15 at 0.5 (none), and
    5.03 at 0.1 (crossing beyond a = 5)."""
    from jointfem.analysis.nma import Backbone

    a = np.linspace(0.5, 8.0, 301)
    zeta = np.where(a <= 2.0, 0.2, np.where(a <= 5.0, 0.5, 0.1))
    n = a.size
    bb = Backbone(output="m.x", mode=1, amplitude=a, omega=np.ones(n), xi=2.0 * zeta, U=np.zeros((n, 3)),
                  states=np.zeros((n, 4, 0), np.int8), harmonics=Harmonics(1, 4), outputs={"m.x": 0},
                  info={"arrays": {"modal_mass_kg": np.ones(n), "modal_force_N": np.ones(n)}})
    syn = synthesize_frf(bb)
    assert syn["detached"]
    # the first part ends where zeta jumps to 0.5 (between 2.0 and 2.025); the detached part's
    # peak is where 1/a^2 = 4 (0.01)(0.99): a = 5.0252, between two points 0.025 apart
    assert 2.0 <= syn["main_peak_amplitude"] <= 2.03
    assert syn["peak_amplitude"] == pytest.approx(1.0 / (2 * 0.1 * np.sqrt(0.99)), abs=0.03)
    assert np.nanmax(np.where(np.isfinite(syn["omega"][0]), a, np.nan)) <= syn["peak_amplitude"]
    assert not syn["beyond_backbone"]
    # a backbone that ends inside the detached part (at a = 5.025): the foot of that part (about 5.0)
    # is no peak; the response goes on beyond the backbone, whose end is then the largest amplitude
    cut = a <= 5.03
    part = Backbone(output="m.x", mode=1, amplitude=a[cut], omega=np.ones(cut.sum()), xi=2.0 * zeta[cut],
                    U=np.zeros((cut.sum(), 3)), states=np.zeros((cut.sum(), 4, 0), np.int8), harmonics=Harmonics(1, 4),
                    outputs={"m.x": 0}, info={"arrays": {"modal_mass_kg": np.ones(cut.sum()),
                                                         "modal_force_N": np.ones(cut.sum())}})
    syn = synthesize_frf(part)
    assert syn["beyond_backbone"] and syn["detached"] and syn["peak_amplitude"] == a[cut][-1]
    assert 2.0 <= syn["main_peak_amplitude"] <= 2.03
