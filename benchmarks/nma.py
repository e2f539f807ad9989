"""Nonlinear modes (issue 15): validation and speed against accuracy of `jointfem nma` (EPMC).

    .venv/bin/python benchmarks/nma.py --out docs/benchmarks_nma.md      (make bench-nma)

1. The SDOF Jenkins oscillator (m = k = kt = Fs = 1): the backbone at H = 1 against the describing
   function's closed form, and its harmonic convergence (H = 1 to 9) at three amplitudes, each
   solved at that amplitude exactly (NmaOptions.at).
2. The backbone meets the FRF: forced sweeps (c = 0.02) at three levels, their located peaks
   against the backbone at the same amplitude, and the single-mode synthesis's peak.
3. The paper's beam with the friction-dominated joint (demos/beam2d_friction.toml), mode 2: the
   penalty ROM's and Craig-Bampton's backbones against full order, and forced sweeps at three
   levels against the backbone.
4. The 3D lap joint at 1 MPa (demos/lap3d_friction.toml), mode 2: the penalty ROM and CB against
   the exact condensation, the dissipation per cycle against amplitude (log-log, its microslip
   slope against the cubic law) on the scene's mesh and on a refined one (more pairs), and the
   same for the lap joint held by one bolt (demos/lap3d_bolted.toml, the static preload).
"""
from __future__ import annotations

import argparse
import datetime
import math
import platform
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def commit() -> str:
    r = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=ROOT, capture_output=True, text=True)
    return r.stdout.strip()


def md_table(header, rows) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def timed(f, *a, **k):
    t = time.perf_counter()
    r = f(*a, **k)
    return r, time.perf_counter() - t


def sdof_part(lines):
    from conftest import sdof
    from test_nma import jenkins_describing

    from jointfem.analysis.frf import SweepOptions, compute_frf
    from jointfem.analysis.nma import NmaOptions, compute_backbone, synthesize_frf
    from jointfem.harmonics import Harmonics
    from jointfem.models.lumped import create_lumped
    from jointfem.models.structure import with_event_aft

    def s(F=0.0, c=0.0):
        return with_event_aft(create_lumped(sdof(F, c=c)))

    amps = (2.0, 5.0, 20.0)
    bb = compute_backbone(s(), NmaOptions(amplitude_start=0.1, amplitude_end=25.0, harmonics=Harmonics(1, 64)))
    w, z, _ = jenkins_describing(bb.amplitude)
    lines += ["## 1. SDOF Jenkins oscillator (m = k = kt = Fs = 1, no damper)", "",
              f"At H = 1 (event-accurate AFT, N = 64), over {bb.num_points} points from 0.1 to 25 m: largest "
              f"|omega - omega_DF| = {np.abs(bb.omega - w).max():.1e} rad/s, |zeta - zeta_DF| = "
              f"{np.abs(bb.zeta - z).max():.1e} (describing function: omega^2 = k + K_eq(a), zeta = W / (2 pi a^2 "
              f"omega^2), W = 4 Fs (a - Fs/kt)).", "",
              "Harmonic convergence, each amplitude solved exactly (relative change against the row above):", ""]
    rows, prev = [], None
    for H in (1, 3, 5, 7, 9):
        b = compute_backbone(s(), NmaOptions(amplitude_start=0.5, amplitude_end=25.0, harmonics=Harmonics(H, 64),
                                             at=amps))
        cur = [(b.info["at"][a]["omega_rad_s"], b.info["at"][a]["zeta"]) for a in amps]
        cells = [f"{H}"]
        for i, (wi, zi) in enumerate(cur):
            d = "" if prev is None else f" ({wi / prev[i][0] - 1:+.1e}, {zi / prev[i][1] - 1:+.1e})"
            cells.append(f"{wi:.7f}, {zi:.6f}{d}")
        rows.append(cells)
        prev = cur
    lines += [md_table(["H"] + [f"a = {a:g} m: omega [rad/s], zeta" for a in amps], rows), ""]

    lines += ["## 2. The backbone meets the FRF (SDOF, c = 0.02, H = 5, events N = 64)", ""]
    h = Harmonics(5, 64)
    rows = []
    for exc in ("all", "fundamental"):
        bb, t_bb = timed(compute_backbone, s(1.0, 0.02), NmaOptions(amplitude_start=0.1, amplitude_end=30.0,
                                                                      harmonics=h, excitation=exc))
        for F in (0.1, 0.2, 0.3):
            frf = compute_frf(s(F, 0.02), SweepOptions(0.5, 2.5, harmonics=h, peak_share=0.0))
            pk = frf.info["peaks"]["m.x"]
            wb = np.interp(np.log(pk.amplitude), np.log(bb.amplitude), bb.omega)
            syn = synthesize_frf(bb, F)
            rows.append([exc, f"{F:g}", f"{pk.omega:.6f}", f"{pk.amplitude:.6f}", f"{wb / pk.omega - 1:+.2e}",
                         f"{syn['peak_amplitude'] / pk.amplitude - 1:+.2e}", f"{syn['peak_omega'] / pk.omega - 1:+.2e}"])
    lines += [md_table(["self-excitation", "F [N]", "forced peak omega", "forced peak amp [m]",
                        "backbone omega at that amp (rel)", "synthesised peak amp (rel)", "synthesised peak omega (rel)"],
                       rows), "",
              "The synthesised peak's omega carries the viscous model of single-mode theory, Omega = omega sqrt(1 - "
              "2 zeta^2) at the top; friction damping does not scale with Omega, and the forced peak lies on the "
              "backbone itself.", ""]


def scene_backbones(lines, scene_path: Path, mode: int, amps, at, methods, title: str, *, excitation="all",
                    levels=(), max_points=3000, reference="full", sets=()):
    from jointfem import app
    from jointfem.analysis.compare import parse_method
    from jointfem.analysis.frf import compute_frf
    from jointfem.analysis.nma import NmaIncomplete, NmaOptions, compute_backbone, synthesize_frf
    from jointfem.harmonics import Harmonics
    from jointfem.rom import RomOptions, build_rom
    from jointfem.scene import create_structure, load_scene

    scene = app.override(load_scene(scene_path), list(sets))
    s = create_structure(scene)
    h = Harmonics(scene.solver.harmonics, scene.solver.samples)
    out = next(iter(s.outputs))
    cont = replace(app.sweep_options(scene, stability="off", peak_share=0.0).continuation, max_points=max_points)
    opts = NmaOptions(mode=mode, amplitude_start=amps[0], amplitude_end=amps[1], output=out, harmonics=h,
                      continuation=cont, at=tuple(at), excitation=excitation)
    res = {}
    for m in [reference] + list(methods):
        spec = parse_method(m, RomOptions())
        if spec.label in res:
            continue
        t0 = time.perf_counter()
        model = s if spec.method == "full" else build_rom(s, spec.method, spec.options)
        off = time.perf_counter() - t0
        try:
            bb, t = timed(compute_backbone, model, opts)
        except NmaIncomplete as exc:
            bb, t = exc.backbone, float("nan")
        res[spec.label] = (bb, off, t)
        print(f"{title}: {spec.label}: {bb.num_points} points, {t:.1f} s", file=sys.stderr)
    ref = res[parse_method(reference, RomOptions()).label][0]
    rows = []
    for label, (bb, off, t) in res.items():
        ew = [abs(bb.info["at"][a]["omega_rad_s"] / ref.info["at"][a]["omega_rad_s"] - 1)
              for a in at if a in bb.info["at"] and a in ref.info["at"]]
        ez = [abs(bb.info["at"][a]["zeta"] / ref.info["at"][a]["zeta"] - 1)
              for a in at if a in bb.info["at"] and a in ref.info["at"]]
        sz = bb.info["arrays"]["rom_size"]
        rows.append([label, f"{sz.min()}" if sz.min() == sz.max() else f"{sz.min()}-{sz.max()}",
                     bb.info["status"], bb.num_points, f"{off:.2f}", f"{t:.1f}",
                     f"{max(ew):.2e}" if ew else "n/a", f"{max(ez):.2e}" if ez else "n/a",
                     f"{bb.zeta.max():.4f}", f"{bb.info['arrays']['harmonic_error'].max():.3f}"])
    lines += [f"## {title}", "",
              f"Scene {scene_path.relative_to(ROOT)}{' with ' + ', '.join(sets) if sets else ''}: {s.num_dofs} DOFs, "
              f"{s.num_pairs} pairs, H = {h.H}, N = {h.N}; mode {mode}, amplitude {amps[0]:g} to {amps[1]:g} m at {out}, "
              f"self-excitation {excitation}.  Errors against {reference} at the amplitudes {', '.join(f'{a:g}' for a in at)} m "
              f"(each solved there exactly), largest over them.", "",
              md_table(["method", "size", "status", "points", "offline s", "online s", "omega err", "zeta err",
                        "zeta max", "harmonic est. max"], rows), ""]
    if levels:
        rows = []
        for F in levels:
            sF = create_structure(app.override(scene, [f"force.amplitude={F}"] + list(sets)))
            frf, t = timed(compute_frf, sF, app.sweep_options(app.override(scene, list(sets)), stability="off", peak_share=0.0))
            pk = frf.info["peaks"][out]
            wb = np.interp(np.log(pk.amplitude), np.log(ref.amplitude), ref.omega)
            syn = synthesize_frf(ref, F / app.scene_force_amplitudes(scene)[0])
            rows.append([f"{F:g}", f"{pk.omega:.4f}", f"{pk.amplitude:.4e}", f"{wb / pk.omega - 1:+.2e}",
                         f"{syn['peak_amplitude'] / pk.amplitude - 1:+.2e}", f"{t:.1f}"])
        lines += [f"Forced sweeps (full order) against the {reference} backbone:", "",
                  md_table(["F [N]", "peak omega [rad/s]", "peak amp [m]", "backbone omega at that amp (rel)",
                            "synthesised peak amp (rel)", "sweep s"], rows), ""]
    return res


def dissipation_shape(bb):
    """Where the joint goes from stuck to gross slip along a backbone: the last stuck and the first
    slipping point of the branch (the onset lies between), the amplitudes at which the share of slipping pair-samples reaches 10 % and 50 %
    (interpolated in log a), the log-log slope of W (the joints' dissipation per cycle) over the
    last decade of amplitude, how much the pairs' tangential amplitudes differ at the first
    slipping point (max / min - 1), and the log-log slope of W over the microslip range (from where
    2 % of the pair-samples slip to 10 % short of the knee, the steepest rise of W; nan where
    fewer than three points lie there: slip then starts at the knee; the cubic law says 3)."""
    W = bb.info["arrays"]["joint_energy_J"]
    slip = (bb.states == 1).mean(axis=(1, 2))
    first = int(np.flatnonzero(W > 0)[0])
    la = np.log(bb.amplitude)

    def at_share(x):
        k = np.flatnonzero(slip >= x)
        if not k.size or k[0] == 0:
            return float("nan")
        i = k[0]
        t = (x - slip[i - 1]) / (slip[i] - slip[i - 1])
        return float(np.exp(la[i - 1] + t * (la[i] - la[i - 1])))

    tail = bb.amplitude >= bb.amplitude[-1] / 10
    slope = float(np.polyfit(la[tail], np.log(W[tail]), 1)[0])
    ta = bb.info["arrays"]["pair_tangential_amp_m"][first]
    # microslip: from where 2 % of the pair-samples slip up to the knee, the steepest step of log W
    # (where the last pairs break loose), short of it by 10 % in amplitude; least squares in log-log
    pos = np.flatnonzero(W > 0)
    steps = np.diff(np.log(W[pos])) / np.maximum(np.diff(la[pos]), 1e-300)
    knee = float(bb.amplitude[pos[1:][int(np.argmax(steps))]]) if steps.size else float("nan")
    micro = (W > 0) & (slip >= 0.02) & (bb.amplitude <= knee / 1.1)
    micro_slope = float(np.polyfit(la[micro], np.log(W[micro]), 1)[0]) if micro.sum() >= 3 else float("nan")
    return ((float(bb.amplitude[max(first - 1, 0)]), float(bb.amplitude[first])), at_share(0.1), at_share(0.5), slope,
            float(ta.max() / ta.min() - 1), micro_slope)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="docs/benchmarks_nma.md")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    lines = []
    sdof_part(lines)
    scene_backbones(lines, ROOT / "demos" / "beam2d_friction.toml", 2, (1e-6, 2.5e-4), (5e-5, 1e-4, 1.5e-4, 2e-4),
                    ["penalty:10:3", "cb:10"], "3. The paper's beam, friction-dominated joint, mode 2",
                    levels=(0.7, 1.0, 1.4), sets=("solver.harmonics=3", "solver.samples=256"))
    # the reference is the exact condensation's EPMC (about 3 s per point here; full order, the same
    # equations, costs about 45 s per point: a 25k-unknown sparse LU per Newton iteration)
    res = scene_backbones(lines, ROOT / "demos" / "lap3d_friction.toml", 2, (3e-5, 3e-3),
                          (1e-4, 2e-4, 5e-4, 1e-3, 2e-3), ["penalty:40:10", "penalty:10:3", "penalty:20:5", "cb:20",
                                                           "cb:40"],
                          "4. The 3D lap joint at 1 MPa, mode 2", excitation="fundamental", reference="exact")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    rows = []
    for label, (bb, _, _) in res.items():
        W = bb.info["arrays"]["joint_energy_J"]
        ax.loglog(bb.amplitude[W > 0], W[W > 0], label=f"{label} ({bb.states.shape[2]} pairs)")
        a0, a10, a50, tail, spread, micro = dissipation_shape(bb)
        rows.append([label, "uniform 1 MPa", f"0.015 ({bb.states.shape[2]} pairs)", f"{a0[0]:.3e} to {a0[1]:.3e}",
                     f"{a10:.3e}", f"{a50:.3e}", f"{a50 / a0[1]:.2f}", f"{micro:.1f}", f"{tail:.2f}", f"{spread:.1%}"])
    fine = scene_backbones(lines, ROOT / "demos" / "lap3d_friction.toml", 2, (3e-5, 3e-3), (1e-4, 5e-4, 1e-3),
                           [], "4b. The same on a refined mesh (penalty ROMs only)", excitation="fundamental",
                           reference="penalty:20:5", sets=("mesh.size=0.0075",))
    for label, (bb, _, _) in fine.items():
        W = bb.info["arrays"]["joint_energy_J"]
        ax.loglog(bb.amplitude[W > 0], W[W > 0], "--", label=f"{label}, mesh 7.5 mm ({bb.states.shape[2]} pairs)")
        a0, a10, a50, tail, spread, micro = dissipation_shape(bb)
        rows.append([label, "uniform 1 MPa", f"0.0075 ({bb.states.shape[2]} pairs)", f"{a0[0]:.3e} to {a0[1]:.3e}",
                     f"{a10:.3e}", f"{a50:.3e}", f"{a50 / a0[1]:.2f}", f"{micro:.1f}", f"{tail:.2f}", f"{spread:.1%}"])
    # the same joint held by one bolt, its pressure from the static contact solve (0.76 to 1.20 MPa)
    # and with stiff contact (kt = kn = 1e14 N/m^3): the bodies, not the contact springs, then set the
    # tractions, and the bolt's pressure leaves the interface's rim open (docs/benchmarks_preload.md)
    for k, amps in (("2e11", (3e-5, 3e-3)), ("1e14", (3e-6, 3e-3))):
        for size, style in (("0.015", "-."), ("0.0075", ":")):
            sets = (f"mesh.size={size}", f"contact.kt={k}", f"contact.kn={k}", f"nma.amplitude_range=[{amps[0]},{amps[1]}]")
            bolted = scene_backbones(lines, ROOT / "demos" / "lap3d_bolted.toml", 2, amps, (1e-4, 5e-4, 1e-3),
                                     [], f"4b. The bolted lap joint (static preload), kt = kn = {k} N/m^3, mesh {size} m",
                                     excitation="fundamental", reference="penalty:20:5", sets=sets)
            for label, (bb, _, _) in bolted.items():
                W = bb.info["arrays"]["joint_energy_J"]
                ax.loglog(bb.amplitude[W > 0], W[W > 0], style, label=f"{label}, bolted, k = {k}, mesh {size} m "
                                                                   f"({bb.states.shape[2]} pairs)")
                a0, a10, a50, tail, spread, micro = dissipation_shape(bb)
                rows.append([label, f"one bolt, static, k = {k}", f"{size} ({bb.states.shape[2]} pairs)",
                             f"{a0[0]:.3e} to {a0[1]:.3e}", f"{a10:.3e}", f"{a50:.3e}", f"{a50 / a0[1]:.2f}",
                             f"{micro:.1f}", f"{tail:.2f}", f"{spread:.1%}"])
    ax.set_xlabel("first-harmonic amplitude at a_mid.uy [m]")
    ax.set_ylabel("joint dissipation per cycle [J]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    img = ROOT / "docs" / "img" / "nma_dissipation_lap3d.png"
    fig.savefig(img, dpi=110)
    lines += ["## 4c. Dissipation per cycle against amplitude (3D lap joint)", "",
              "Where the joint goes from stuck to gross slip: the onset a0 between the branch's last stuck and "
              "first slipping point (the continuation's steps, not a located onset), the "
              "amplitudes at which 10 % and 50 % of the pair-samples slip, and the log-log slope of the "
              "dissipation over the last decade (gross slip: W grows like a).  The cubic law of microslip "
              "(Mindlin; Goodman) needs a pressure that falls to zero at the contact's edge, so that slip "
              "spreads inward as the amplitude grows.  This scene's preload is uniform and its pairs move almost "
              "alike (their tangential amplitudes differ by the spread below at the onset), so they start to "
              "slip nearly together: the microslip range spans a factor a50 / a0 in amplitude, across which W "
              "rises by many decades, and no power law can be fitted there.  The bolted rows take the pressure "
              "from the static contact solve instead (one bolt, 750 N).  With the scene's contact springs (kt = kn = "
              "2e11 N/m^3, much softer than the plates) each pair's tangential force follows its own nearly uniform "
              "relative displacement, every pair stays closed, and slip still starts at the knee: no microslip "
              "range.  With stiff contact (1e14 N/m^3) the plates set the tractions, the bolt's pressure leaves the "
              "interface's rim open, and slip spreads from the rim inward over a decade of amplitude before the "
              "knee: that is the regime of Mindlin's and Goodman's cubic law.  On 81 pairs the slope there is the "
              "column below (near 3); on 25 pairs the steepest rise of W is the first slip itself (a few pairs at "
              "the rim breaking loose at once), so the rule finds no range before it: the cubic law shows only "
              "once the rim is resolved by enough pairs.  The slope is a least-squares fit over the points the "
              "continuation placed there, not over a located range.", "",
              md_table(["method", "preload", "mesh size [m] (pairs)", "a0 between [m]", "a at 10 % slip [m]",
                        "a at 50 % slip [m]", "a50 / a0 (first slipping)", "slope of W, microslip (cubic law: 3)",
                        "slope of W, last decade", "tangential amplitude spread at a0"], rows), "",
              f"![dissipation](img/{img.name})", ""]
    head = [f"# Nonlinear modes (EPMC): validation and speed against accuracy", "",
            f"Regenerated by `make bench-nma` (`python benchmarks/nma.py`) on "
            f"{datetime.datetime.utcnow():%Y-%m-%d %H:%M} UTC at commit {commit()}, "
            f"{(time.perf_counter() - t0) / 60:.0f} min on {__import__('os').cpu_count()} cores ({platform.machine()}).", ""]
    Path(args.out).write_text("\n".join(head + lines) + "\n")
    print(f"wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
