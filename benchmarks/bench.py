"""Benchmarks (not tests): ``make bench`` regenerates docs/benchmarks.md (and
docs/benchmarks_offline.md, docs/img/pareto_*.png, docs/img/peer_frf.png) in one run.

1. AFT with its Jacobian for 1,000 3D pairs x 256 samples (H = 5), median of repeats.
2. The SDOF Jenkins sweep (demos/sdof_jenkins.toml) and the full-order jointed beam.
3. Speed against accuracy (``jointfem.analysis.compare``): every method at several basis sizes, on
   the jointed beam at separation (reference: full order) and on the 3D lap joint at separation
   (reference: the exact condensation), with a Pareto plot each.
4. Convergence in H (1..25) and N (2H+1..4096): the SDOF oscillator's peak.
5. The peer comparison with pyHarm (benchmarks/peer/), in pyHarm's own venv.
6. The continuum's offline stages, serial against 2 MPI ranks.

Each run records the machine and the software versions.  Times are medians of repeats.
"""
from __future__ import annotations

import argparse
import cProfile
import dataclasses
import os
import platform
import pstats
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "demos"))


def machine() -> dict:
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    from importlib.metadata import PackageNotFoundError, version

    import numba
    import scipy

    out = {"cores": os.cpu_count(), "cpu": cpu, "memory": _memory(), "os": platform.platform(),
           "python": platform.python_version(), "numpy": np.__version__, "scipy": scipy.__version__,
           "numba": numba.__version__, "numba_threads": numba.get_num_threads()}
    for pkg in ("fenics-dolfinx", "petsc4py", "slepc4py", "gmsh", "mpi4py", "pyvista", "vtk", "matplotlib"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            try:  # Debian's python3-* packages carry no pip metadata for some of these
                out[pkg] = __import__(pkg.replace("fenics-", "")).__version__
            except Exception:  # noqa: BLE001 - a version we cannot read is recorded as such
                out[pkg] = "not installed"
    out["jointfem commit"] = _commit()
    return out


def _commit() -> str:
    """HEAD's short hash ("unknown" without git)."""
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def _memory() -> str:
    try:
        kb = int(next(l for l in Path("/proc/meminfo").read_text().splitlines() if l.startswith("MemTotal")).split()[1])
        return f"{kb / 2**20:.1f} GiB"
    except (OSError, StopIteration, ValueError):
        return "unknown"


def median_time(fn, repeats: int) -> tuple[float, list[float]]:
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts), ts


def bench_aft(repeats: int) -> dict:
    from jointfem.contact.jenkins import JenkinsPairs, compute_aft
    from jointfem.harmonics import Harmonics

    rng = np.random.default_rng(0)
    h = Harmonics(5, 256)
    P = 1000
    out = {}
    for label, amp in (("mostly stuck", 0.2), ("heavy slip and separation", 0.7)):
        p = JenkinsPairs(kt=rng.uniform(1, 2, P), kn=rng.uniform(1, 3, P), mu=rng.uniform(0.2, 0.6, P),
                         N0=rng.uniform(0.5, 1.5, P), num_tangential=2, has_normal=True)
        G = rng.normal(size=(h.num_hc, P, 3)) * amp / (1 + h.orders)[:, None, None]
        r = compute_aft(p, G, h)  # compile / warm up
        shares = np.bincount(r.state_t.ravel(), minlength=3) / r.state_t.size
        t_jac, _ = median_time(lambda: compute_aft(p, G, h), repeats)
        t_res, _ = median_time(lambda: compute_aft(p, G, h, jacobian=False), repeats)
        out[label] = {"with_jacobian_s": t_jac, "residual_only_s": t_res, "stick_slip_sep_share": shares.tolist()}
    return out


def _profile_share(fn) -> tuple[float, dict]:
    """Run fn under cProfile; return (wall, share of cumulative time in AFT and in sparse LU)."""
    prof = cProfile.Profile()
    t = time.perf_counter()
    prof.enable()
    result = fn()
    prof.disable()
    wall = time.perf_counter() - t
    st = pstats.Stats(prof)
    cum = {}
    for (filename, _, name), (_, _, _, ct, _) in st.stats.items():
        if name == "compute_aft":
            cum["aft"] = cum.get("aft", 0.0) + ct
        if name in ("_solve", "_solve_with_sign") and filename.endswith("arclength.py"):
            cum["linear_solve"] = cum.get("linear_solve", 0.0) + ct
    total = st.total_tt
    return wall, {k: v / total for k, v in cum.items()}, result


def bench_frf(scene_path: Path, *, force_factor=None, H=None, N=None, repeats=3) -> dict:
    from jointfem.app import solve_scene
    from jointfem.scene import load_scene

    scene = load_scene(scene_path)
    if H is not None:
        scene = dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, harmonics=H, samples=N))
    if force_factor is not None:
        from jointed_beam_levels import separation_force

        f = force_factor * separation_force(scene)
        scene = dataclasses.replace(scene, model=dataclasses.replace(scene.model, force=f))
    solve_scene(scene)  # warm up
    walls, frf = [], None
    for _ in range(repeats):
        frf = solve_scene(scene).frf
        walls.append(frf.info["time_online_s"])
    _, shares, _ = _profile_share(lambda: solve_scene(scene))
    t = statistics.median(walls)
    return {"scene": str(scene_path.relative_to(ROOT)), "H": scene.solver.harmonics, "N": scene.solver.samples,
            "points": int(frf.num_points), "newton_iterations": int(frf.iterations.sum()),
            "continuation_s": t, "s_per_point": t / frf.num_points, "shares": shares,
            "unknowns": int(frf.info["num_unknowns"])}


BEAM_METHODS = ("cb:5", "cb:10", "cb:20", "rubin:10", "rubin:20", "penalty:5", "penalty:10", "penalty:20",
                "penalty:10:3")
LAP3D_METHODS = ("cb:10", "cb:20", "rubin:10", "penalty:5", "penalty:10", "penalty:20", "penalty:10:3")


def bench_roms(repeats: int, img: Path) -> dict:
    """The jointed beam at separation (3.0 N, H = 3, N = 1024), every method against full order."""
    from jointfem.app import sweep_options
    from jointfem.plots import plot_compare
    from jointfem.rom import RomOptions
    from jointfem.analysis.compare import chord_error_estimate, compare, parse_method
    from jointfem.scene import create_structure, load_scene

    scene = load_scene(ROOT / "demos" / "beam2d.toml")
    scene = dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, harmonics=3, samples=1024))
    structure = create_structure(scene)
    specs = [parse_method(m, RomOptions()) for m in BEAM_METHODS]
    # stability off for every method: the table compares the sweeps alone (the exact condensation
    # has its stability from the full model, which would time another method's work)
    results = compare(structure, specs, sweep_options(scene, stability="off", peak_share=0.0), output="b1.mid.uy", repeats=repeats,
                      progress=lambda m: print(f"bench: beam {m} ...", flush=True))
    plot_compare(results, "b1.mid.uy", img / "compare_frf_beam.png", img / "pareto_beam.png",
                 title="jointed beam, 3.0 N: error against online time")
    rows = _rows(results)
    chord = chord_error_estimate(results[0].frf, "b1.mid.uy")
    by = {r["method"]: r for r in rows}
    # where the time goes: residual evaluations per point and their cost, for penalty and CB
    from jointfem.analysis.frf import compute_frf
    from jointfem.rom import build_rom

    split = {}
    for label in ("cb:10", "penalty:10"):
        sp_ = parse_method(label, RomOptions())
        model = build_rom(structure, sp_.method, sp_.options)
        prof = cProfile.Profile()
        prof.enable()
        frf = compute_frf(model, sweep_options(scene, stability="off", peak_share=0.0))
        prof.disable()
        st = pstats.Stats(prof).stats
        ev = [v for (f, _, n), v in st.items() if n == "_evaluate" and f.endswith("residual.py")][0]
        aft = [v for (f, _, n), v in st.items() if n == "compute_aft"][0]
        lu = [v for (f, _, n), v in st.items() if n in ("_solve", "_solve_with_sign") and f.endswith("arclength.py")]
        calls, tt = sum(v[1] for v in lu), sum(v[3] for v in lu)
        split[label] = {"evaluations_per_point": ev[1] / frf.num_points, "ms_per_evaluation": 1e3 * ev[3] / ev[1],
                        "ms_aft_per_evaluation": 1e3 * aft[3] / aft[1], "ms_per_solve": 1e3 * tt / calls,
                        "solves_per_point": calls / frf.num_points}
    return {"rows": rows, "split": split, "chord": chord, "H": 3, "N": 1024, "repeats": repeats, "full_size": structure.num_dofs,
            "penalty_over_cb": by["penalty:10"]["online_s"] / by["cb:10"]["online_s"],
            "penalty_tvd_over_cb": by["penalty:10+3tvd"]["online_s"] / by["cb:10"]["online_s"],
            "per_point_penalty_over_cb": by["penalty:10"]["s_per_point"] / by["cb:10"]["s_per_point"]}


def _rows(results) -> list[dict]:
    rows = []
    for r in results:
        row = r.row()
        row["size"] = r.size_text
        row["iter_per_point"] = r.newton_iterations / max(r.num_points, 1)
        rows.append(row)
    return rows


def bench_lap3d(repeats: int, img: Path) -> dict:
    """The 3D lap joint at its separation level, every method against the exact condensation."""
    sys.path.insert(0, str(ROOT / "demos"))
    from lap3d_nonlinear import LEVELS, scene_for

    from jointfem.app import sweep_options
    from jointfem.plots import plot_compare
    from jointfem.rom import RomOptions
    from jointfem.analysis.compare import chord_error_estimate, compare, parse_method
    from jointfem.scene import create_structure

    lvl = [k for k in LEVELS if k.startswith("separation")][0]
    scene = scene_for(LEVELS[lvl])
    t0 = time.perf_counter()
    structure = create_structure(scene)
    t_model = time.perf_counter() - t0
    specs = [parse_method(m, RomOptions()) for m in LAP3D_METHODS]
    results = compare(structure, specs, sweep_options(scene, stability="off", peak_share=0.0), output="a_mid.uy", reference="exact",
                      repeats=repeats, reference_ds_max=0.03,
                      progress=lambda m: print(f"bench: lap3d {m} ...", flush=True))
    plot_compare(results, "a_mid.uy", img / "compare_frf_lap3d.png", img / "pareto_lap3d.png",
                 title="3D lap joint, 2 N: error against online time")
    return {"rows": _rows(results), "level": lvl, "ds_max": sweep_options(scene).continuation.ds_max, "chord": chord_error_estimate(results[0].frf, "a_mid.uy"), "dofs": structure.num_dofs, "pairs": structure.num_pairs,
            "model_s": t_model, "H": scene.solver.harmonics, "N": scene.solver.samples, "repeats": repeats,
            "full_size": structure.num_dofs}


def bench_convergence() -> dict:
    """The SDOF Jenkins oscillator (F = 0.5, stick-slip at the peak): the peak of the first
    harmonic (located to the Newton tolerance on a sweep with ds_max = 0.005: analysis.peaks), and the
    first harmonic at omega = 1.29, for H = 1..25 at N = 4096 and for N = 2H+1..4096 at H = 7,
    against H = 25, N = 16384."""
    from jointfem.continuation.arclength import ContinuationOptions
    from jointfem.analysis.frf import SweepOptions, compute_frf
    from jointfem.harmonics import Harmonics
    from jointfem.scene import create_structure, load_scene, parse_scene

    data = load_scene(ROOT / "demos" / "sdof_jenkins.toml").data
    data = {k: (dict(v) if isinstance(v, dict) else v) for k, v in data.items()}
    data["force"] = [dict(data["force"][0], amplitude=0.5)]
    s = create_structure(parse_scene(data, "sdof_jenkins.toml (F = 0.5)"))

    from jointfem.continuation.arclength import solve_newton
    from jointfem.hbm.problem import newton_system
    from jointfem.hbm.residual import HBMResidual

    def peak(H, N):
        t = time.perf_counter()
        h = Harmonics(H, N)
        frf = compute_frf(s, SweepOptions(1.1, 1.5, h, ContinuationOptions(ds_max=0.005), peak_share=0.0))
        w, a = frf.peak("m.x")
        # and at fixed omega = 1.29 (near the peak), by Newton from the nearest point
        r = HBMResidual(s, h)
        k = int(np.argmin(np.abs(frf.omega - 1.29)))
        U, _ = solve_newton(newton_system(r), frf.U[k], 1.29,
                            x_scale=1.0, r_scale=0.5)
        return w, a, h.amplitude(U.reshape(h.num_hc, 1)[:, 0], 1), time.perf_counter() - t, frf.num_points

    ref = peak(25, 16384)
    hs = [(H, 4096) for H in (1, 2, 3, 5, 7, 9, 11, 13, 15, 19, 25)]
    ns = [(7, N) for N in (15, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096)]
    rows = [(H, N, *peak(H, N)) for H, N in hs + ns]
    return {"ref": ref, "rows": rows}


def _rom_table(t: dict) -> list[str]:
    lines = ["| method | size | RR | offline [s] | online [s] | points | Newton it./point | s/point | peak amp err "
             "| peak freq err | curve err |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for i, r in enumerate(t["rows"]):
        ref = i == 0
        if r["failure"]:
            lines.append(f"| {r['method']} | {r['size']} | | {r['offline_s']:.2f} | stopped after {r['online_s']:.1f} s: "
                         f"{r['failure'][:120]} | | | | | | |")
            continue
        err = ("reference", "", "") if ref else (f"{r['peak_amp_err_pct']:+.4f} %", f"{r['peak_freq_err_pct']:+.5f} %",
                                                   f"{r['curve_err_pct']:.4f} %")
        lines.append(f"| {r['method']} | {r['size']} | {r['size_max'] / t['full_size']:.4f} | {r['offline_s']:.2f} | "
                     f"{r['online_s']:.2f} | {r['points']} | {r['iter_per_point']:.2f} | {r['s_per_point']:.4f} | "
                     f"{err[0]} | {err[1]} | {err[2]} |")
    return lines


# the benchmarks with a file and a make target of their own (listed in docs/benchmarks.md)
OTHER = [
    ("docs/benchmarks_corners.md", "make bench-corners", "the sweeps at strong separation of issue 14 (lap3d at 3 and "
     "5 N, penalty ROM and exact; lap2d full order; the beam at H = 5 to 15, N up to 4096): status, points, "
     "refused steps, time, largest accepted residual, located peak"),
    ("docs/benchmarks_offline.md", "make bench", "the offline stages of a lap joint of 100k DOFs and 525 pairs, "
     "replicated and distributed, 1 against 2 MPI ranks"),
    ("docs/benchmarks_scaling.md", "make bench-scaling", "the offline stages against DOFs and pairs, 1 and 2 ranks, "
     "fitted slopes and peak memory per rank, a 500k-DOF model (docs/scaling.md reads them)"),
    ("docs/benchmarks_scaling_distributed.md", "make bench-scaling-distributed", "the same for the distributed "
     "offline stage (nothing model-sized gathered), and a 525k-DOF model"),
    ("docs/benchmarks_online.md", "make bench-online", "one Newton iteration of the penalty ROM, CB and the exact "
     "condensation at a stick-slip state, against DOFs and pairs, fitted slopes"),
    ("docs/benchmarks_sweep500.md", "make bench-sweep500", "the penalty ROM's sweep of the 525-pair joint (100k DOFs) "
     "at a stick-slip level, against CB's cost per Newton iteration; also part of make bench"),
    ("docs/benchmarks_harmonics.md", "make bench-harmonics", "the beam at 3 N against the number of harmonics, H = 3 to 41"),
    ("docs/benchmarks_stability.md", "make bench-stability", "the beam's stability at a converged H, against time integration"),
    ("docs/benchmarks_peaks.md", "python benchmarks/peaks_cost.py", "the cost of located peaks and of stability"),
    ("docs/benchmarks_exact.md", "make bench-exact", "the exact condensation: sparse LU per harmonic and omega against one eigendecomposition"),
    ("docs/benchmarks_friction.md", "make bench-friction", "speed against accuracy where friction dominates"),
    ("docs/benchmarks_nma.md", "make bench-nma", "nonlinear modes (EPMC): validation and speed against accuracy; also part of make bench"),
    ("docs/benchmarks_preload.md", "make bench-preload", "the static preload: mesh convergence of the bolted lap joint and the Brake-Reuss beam"),
]


def other_benchmarks() -> list[str]:
    """The section of docs/benchmarks.md that lists the benchmarks with files of their own."""
    return ["## Other benchmarks", "", "Each has its own file and command (not rerun by `make bench` unless said):", ""] + [
        f"- [{path}]({Path(path).name}) (`{cmd}`): {what}." for path, cmd, what in OTHER] + [""]


def write_markdown(path: Path, m: dict, aft: dict, sdof: dict, beam: dict, command: str, roms: dict, lap: dict,
                   conv: dict, peer: list | None, wall: float):
    lines = ["# Benchmarks", "",
             f"Regenerated by `{command}` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, every table "
             f"and plot in this file from that one run ({wall / 60:.0f} min; docs/benchmarks_offline.md comes from the same "
             "run).  Times are medians of repeated runs in one process, after a warm-up run (numba compiles on "
             "first use), unless a table says otherwise; ratios are taken within the same run.  This machine's "
             "run-to-run timing noise is large: the same full-order beam sweep took 13.7, 17.2 and 20.9 s in three "
             "runs of make bench on 2026-11-30, so read times to about +-25 % and compare within one run.",
             "", "## Machine and software", "", "| item | value |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in m.items()]
    lines += [""] + other_benchmarks()
    lines += ["## AFT with exact Jacobian: 1,000 3D pairs (2 tangential + normal), N = 256, H = 5", "",
              "| case | stick / slip / separated share | residual only [ms] | with Jacobian [ms] | goal |",
              "|---|---|---|---|---|"]
    for label, r in aft.items():
        sh = " / ".join(f"{x:.2f}" for x in r["stick_slip_sep_share"])
        lines.append(f"| {label} | {sh} | {1e3 * r['residual_only_s']:.1f} | {1e3 * r['with_jacobian_s']:.1f} | 50 ms |")
    lines += ["", "## Frequency sweeps (full order)", "",
              "| scene | H | N | unknowns | points | Newton iterations | continuation [s] | s/point | AFT share | linear-solve share |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for r in (sdof, beam):
        lines.append(f"| {r['scene']}{r.get('label', '')} | {r['H']} | {r['N']} | {r['unknowns']} | {r['points']} | "
                     f"{r['newton_iterations']} | {r['continuation_s']:.2f} | {r['s_per_point']:.4f} | "
                     f"{100 * r['shares'].get('aft', 0):.0f} % | {100 * r['shares'].get('linear_solve', 0):.0f} % |")
    lines += ["", "Shares are of the profiled run's total time (cProfile adds overhead; the wall times above are "
              "unprofiled).", ""]
    lines += ["## Speed against accuracy", "",
              "`jointfem.analysis.compare` (the code behind `jointfem compare`): every method and basis size, with its "
              "size (a range when the penalty ROM's active set changes along the branch), RR = largest size / full "
              f"size, offline and online seconds (online: the whole continuation, median of {roms['repeats']} "
              "sweeps; the reference is swept once), Newton iterations per point, and errors of the output's first "
              "harmonic against the reference of the same run: peak amplitude and frequency (located to the Newton "
              "tolerance between the branch points: analysis.peaks) and the largest distance of the ROM's points from the reference curve, in % of "
              "the reference peak.  `cb:10` = Craig-Bampton with 10 fixed-interface modes, `penalty:10+3tvd` = the "
              "penalty ROM with 10 modes and 3 trial-vector derivatives.", "",
              f"### Jointed beam at separation (demos/beam2d.toml, 3.0 N, H = {roms['H']}, N = {roms['N']}, "
              f"{roms['full_size']} DOFs; reference: full order)", ""]
    lines += _rom_table(roms)
    lines += ["", f"The reference's own chord error (`chord_error_estimate`: how far the polyline through its "
              f"{roms['rows'][0]['points']} points may stray from its curve) is about {100 * roms['chord']:.3f} % of "
              "the peak: curve errors below that are not resolved.", "",
              "![Pareto: jointed beam](img/pareto_beam.png)", "",
              f"Penalty (10 modes) over CB (10 modes), online time: **{roms['penalty_over_cb']:.2f}**; with 3 TVDs: "
              f"{roms['penalty_tvd_over_cb']:.2f}; per point: {roms['per_point_penalty_over_cb']:.2f}.", "",
              "Where the time goes (one profiled run each; cProfile slows both alike):", "",
              "| method | residual evaluations per point | ms per evaluation | of which AFT [ms] | linear solves per "
              "point | ms per solve |", "|---|---|---|---|---|---|"]
    for label, v in roms["split"].items():
        lines.append(f"| {label} | {v['evaluations_per_point']:.1f} | {v['ms_per_evaluation']:.2f} | "
                     f"{v['ms_aft_per_evaluation']:.2f} | {v['solves_per_point']:.1f} | {v['ms_per_solve']:.2f} |")
    lines += ["", "On this 3-pair beam the AFT of the same 3 pairs at N = 1024 costs every method the same, so the "
              "penalty ROM's smaller unknown count buys less than on a large joint; its branch also takes more "
              "points (steps redone when the active set grows, and the corners of its separation).  Stability "
              "(Hill's method) is off for every method in these tables: it is not what is timed.", "",
              f"### 3D lap joint at separation (demos/lap3d.toml, {lap['level']}, 15 mm Q2 mesh, {lap['dofs']} DOFs, "
              f"{lap['pairs']} pairs, H = {lap['H']}, N = {lap['N']}; reference: the exact condensation)", "",
              f"The model (mesh, assembly, gather) took {lap['model_s']:.1f} s, outside the table.  The exact "
              "condensation solves the full model's equations (tests/test_continuum.py checks it against full order "
              "to 1e-8), here on its modal path (Rayleigh damping and at most 13000 DOFs: one eigendecomposition, offline; "
              "docs/theory.md).", ""]
    lines += _rom_table(lap)
    lines += ["", f"The reference is swept with ds_max = 0.03 (the ROMs with the scene's {lap['ds_max']}), so that "
              f"its polyline is dense: its chord error is about {100 * lap['chord']:.3f} % of the peak; curve errors "
              "below that are not resolved.", "",
              "![Pareto: 3D lap joint](img/pareto_lap3d.png)", ""]
    ref = conv["ref"]
    lines += ["## Convergence in H and N: SDOF Jenkins oscillator, F = 0.5 (stick-slip at the peak)", "",
              f"Reference: H = 25, N = 16384: peak {ref[1]:.8f} m at {ref[0]:.6f} rad/s; first harmonic at 1.29 rad/s "
              f"{ref[2]:.8f} m.  Peaks from sweeps with ds_max = 0.005, located to the Newton tolerance between "
              "the branch points (analysis.peaks); the value at 1.29 rad/s is a Newton solution at that omega.  Only odd harmonics are excited (the even ones vanish by symmetry), so an even H repeats the "
              "H - 1 row.  tests/test_extremes_systems.py asserts this convergence.", "",
              "| H | N | peak amp rel. err | peak freq rel. err | amp at 1.29 rad/s rel. err | points | sweep [s] |",
              "|---|---|---|---|---|---|---|"]
    for H, N, w, a, a129, t, n in conv["rows"]:
        lines.append(f"| {H} | {N} | {a / ref[1] - 1:+.2e} | {w / ref[0] - 1:+.2e} | {a129 / ref[2] - 1:+.2e} | {n} | "
                     f"{t:.2f} |")
    lines += ["", "## Peer comparison: pyHarm", ""]
    if peer is None:
        lines += ["Not run (`--no-peer`)."]
    else:
        import peer_compare as peer_mod

        lines += peer_mod.markdown(peer, "img/peer_frf.png")
        lines += ["", peer_notes(peer)]
    lines.append("")
    path.write_text("\n".join(lines))


def peer_notes(rows: list[dict]) -> str:
    """How to read the peer table; the numbers are this run's, the mechanisms were read in pyHarm
    1.2.2's source (Systems/System.py, Systems/ABCSystem.py, NonLinearSolver/NewtonRaphson.py,
    Elements/NodeToNodeElements/Jenkins.py and Penalty3D.py) and confirmed by the profile above."""
    by = {r["case"].split()[0]: r for r in rows}
    sd, sep, ch = by["SDOF"], by["2-DOF"], by["chain"]
    chq = ch["profile_p"]
    slow = [r["case"] for r in rows if r["speedup"] < 1.0]
    return f"""Reading the table:
* **Same curves.** The curve difference is measured at every pyHarm point, with jointfem solved by
  Newton at the same omega: at most {100 * max(r['curve_diff'] for r in rows):.2f} % of the peak. Peak
  amplitudes agree to {100 * max(abs(r['peak_amp_diff']) for r in rows):.3f} %; the peak frequencies differ by
  up to {100 * max(abs(r['peak_freq_diff']) for r in rows):.3f} %, which is where each code's points happen to
  fall (the peak is a parabola through the three highest points). What remains is bounded by the
  Newton tolerance (1e-6 of the force: pyHarm's plain Newton did not converge at 1e-8 at the first
  point of the separation case) and by the slider laws: pyHarm relaxes its slider over 3 sampled
  periods, jointfem solves for the periodic slider state.
* **Speed.** jointfem is faster on {'every system' if not slow else 'all but ' + ', '.join(slow)}:
  {sd['speedup']:.1f}x on the SDOF oscillator, {sep['speedup']:.0f}x on the 3D pair with separation and
  {ch['speedup']:.1f}x on the 20-slider chain (goal: 5x), and per point {sd['per_point_p'] / sd['per_point_j']:.1f}x,
  {sep['per_point_p'] / sep['per_point_j']:.0f}x and {ch['per_point_p'] / ch['per_point_j']:.0f}x.
* **Why.** pyHarm evaluates every element in a Python loop at every Newton iteration, the linear
  ones too (masses, springs, dampers: their Jacobian never changes), scatters each into a dense
  n x n array, and removes the grounded DOFs with a dense product P J P^T; Newton then solves
  densely (scipy.linalg.solve) and the predictor factors densely (QR). The profile splits this per
  system. On the chain ({ch['unknowns']} unknowns) the dense algebra grows as n^2 to n^3 while the
  work that matters, 20 sliders, grows as n: the global Jacobian, dense solves and QR take
  {100 * (chq['global_jacobian'] + chq['linear_solves'] + chq['predictor_qr']):.0f} % of pyHarm's time. jointfem assembles K, D, M once (sparse), evaluates all pairs in one compiled AFT
  kernel with the exact sparse Jacobian, and factors with a sparse LU. On the 3D pair, pyHarm takes
  {sep['points_p'] / sep['points_j']:.1f}x more points (its step rule works in raw units; larger ds_max made
  it skip the peak or turn back) and {sep['it_p'] / max(sep['it_j'], 1e-9):.1f}x more Newton iterations per point;
  its jax-differentiated Penalty3D Jacobian takes {100 * sep['profile_p']['friction_jacobians']:.0f} % of its
  time, the per-element loops {100 * sep['profile_p']['element_loops']:.0f} %.
* **What it would take pyHarm to match.** Assemble the linear part once, keep the Jacobian sparse
  (the grounded DOFs by index, not by a dense product), vectorise the friction elements over pairs,
  and scale its continuation's unknowns.
* **Settings.** Both sides start from the linear solution at the first frequency and stop past the
  last. pyHarm: NewtonRaphson (tol_residual = tol max|F| on the 2-norm), tangent predictor,
  arc-length corrector, ds_max from benchmarks/peer/cases.py (raw units). jointfem: its defaults
  (scaled arclength, ds_max = 0.1). The pyHarm venv runs numpy 2 with its own OpenBLAS, jointfem
  the system numpy 1.24 with Debian's OpenBLAS, so raw dense-algebra speed may differ too."""


def mpirun(ranks: int) -> list[str]:
    """The command prefix that runs a program on ``ranks`` MPI ranks on this machine (as root too)."""
    return ["mpirun", "--oversubscribe", "-n", str(ranks)] + (["--allow-run-as-root"] if os.geteuid() == 0 else [])


# issue 17's case: a lap joint of at least 100k DOFs and 500 pairs (m: size, size_normal, size_joint)
OFFLINE_CASE = (0.0061, 0.002, 0.0025)


OFFLINE_REPEATS = 3  # runs of each distributed configuration (alternated); the replicated stage runs once


def bench_offline(path: Path, case: tuple = OFFLINE_CASE, command: str = "python benchmarks/bench.py --offline-only",
                  repeats: int = OFFLINE_REPEATS) -> None:
    """Offline stages of the 3D lap joint (>= 100k DOFs, >= 500 pairs), serial and on 2 MPI ranks:
    replicated (once), distributed with the static modes by PETSc's MatMatSolve and by MUMPS called
    directly (``repeats`` runs each, alternated, medians) -> ``path``."""
    import json
    import subprocess
    import tempfile

    script = ROOT / "benchmarks" / "offline_stages.py"
    size, hn, hj = case
    configs = [("replicated", None, 1)] + [("distributed", solver, repeats) for solver in ("petsc", "direct")]
    runs: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        for rep in range(repeats):
            for kind, solver, count in configs:
                for ranks, prefix in ((1, []), (2, mpirun(2))):
                    if rep >= count:
                        continue
                    out = Path(tmp) / f"{kind}{solver}{ranks}_{rep}.json"
                    extra = [] if kind == "replicated" else ["--distributed", "--static-solver", solver]
                    r = subprocess.run(prefix + [sys.executable, str(script), "--size", str(size), "--size-normal", str(hn),
                                                 "--size-joint", str(hj), "--json", str(out)] + extra,
                                       cwd=ROOT, capture_output=True, text=True)
                    if r.returncode != 0:
                        raise RuntimeError(f"offline stages ({kind}, {solver}) on {ranks} rank(s) failed (exit "
                                           f"{r.returncode}):\n{(r.stdout + r.stderr)[-3000:]}")
                    runs.setdefault((kind, solver, ranks), []).append(json.loads(out.read_text()))
    cols = [(kind, solver, r) for kind, solver, _ in configs for r in (1, 2)]
    first = runs["replicated", None, 1][0]
    stages = list(first["stages_s"])

    def med(key, stage):
        return statistics.median(run["stages_s"].get(stage, float("nan")) for run in runs[key])

    def speedup(solver, stage):
        one, two = med(("distributed", solver, 1), stage), med(("distributed", solver, 2), stage)
        return f"{one / two:.2f}" if two > 0 else ""

    lines = ["# Continuum benchmarks: offline stages, replicated and distributed, 1 against 2 MPI ranks", "",
             f"Regenerated by `{command}` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} at commit "
             f"{_commit()} ({machine()['cpu']}, {machine().get('cores', '?')} cores): the replicated stage once on "
             f"1 and on 2 ranks, each distributed configuration {repeats} times on 1 and on 2 ranks, the runs "
             "alternated; the distributed columns are medians (per stage, so they need not add up to the "
             "median total).", "",
             f"3D lap joint (Q2 hexahedra, {size * 1e3:g} mm along x, {hn * 1e3:g} mm through the thickness, "
             f"{hj * 1e3:g} mm over the joint): {first['dofs']} DOFs, {first['pairs']} pairs, 20 modes, "
             f"{3 * first['pairs']} static modes.  Replicated: K and M gathered to every rank in canonical order, "
             "every solution column gathered to every rank (what `jointfem frf` does by default).  Distributed: "
             "jointfem.fem.distributed (`jointfem frf --offline distributed`): K, M, K_lin stay dolfinx's PETSc "
             "matrices, the modes and static modes stay in row blocks, only reduced data crosses.  Its "
             "projection takes T^T K_lin T from the gap rows (K_lin Psi = G^T Kc) and T^T M T by column blocks.  "
             "Its static modes K_lin^-1 G^T Kc: *MatMatSolve*, PETSc's MUMPS interface with distributed dense "
             "right-hand sides, 64 at a time, after SLEPc factorised K_lin for the modes through PETSc too (the "
             "path before jointfem.mumps; `--static-solver petsc`); *direct*, MUMPS called directly "
             "(jointfem.mumps: K_lin factorised once, the modes' shift-invert applies it, the static modes' "
             "right-hand sides go sparse to the host, two to six nonzeros each, their solution stays distributed "
             "and is sent to the rows' owners, 256 at a time; the default).  In the direct columns the eigen "
             "stage includes that one factorisation.", "",
             "| stage | replicated, 1 rank [s] | replicated, 2 ranks [s] | distributed, MatMatSolve, 1 rank [s] | "
             "distributed, MatMatSolve, 2 ranks [s] | speed-up | distributed, direct, 1 rank [s] | "
             "distributed, direct, 2 ranks [s] | speed-up |", "|---|---|---|---|---|---|---|---|---|"]
    for k in stages:  # the same stage names in every run (the static stage named by its count of solves)
        v = [med(key, k) for key in cols]
        lines.append(f"| {k} | " + " | ".join(f"{x:.2f}" for x in v[:4]) + f" | {speedup('petsc', k)} | "
                     + " | ".join(f"{x:.2f}" for x in v[4:]) + f" | {speedup('direct', k)} |")
    peak = [max(max(run["peak_gb_per_rank"].values()) for run in runs[key]) for key in cols]
    lines.append("| peak memory of the largest rank [GB] | " + " | ".join(f"{x:.2f}" for x in peak[:4]) + " | | "
                 + " | ".join(f"{x:.2f}" for x in peak[4:]) + " | |")
    totals = {key: [run["stages_s"]["offline_total"] for run in runs[key]] for key in runs}
    pairs = {solver: [a / b for a, b in zip(totals["distributed", solver, 1], totals["distributed", solver, 2])]
             for solver in ("petsc", "direct")}
    lines += ["", "Totals of every run [s]: " + "; ".join(
        f"{kind}{'' if solver is None else ', ' + ('MatMatSolve' if solver == 'petsc' else 'direct')}, {r} rank"
        f"{'s' if r > 1 else ''}: " + ", ".join(f"{t:.1f}" for t in totals[kind, solver, r]) for kind, solver, r in cols) + ".",
              "",
              "Speed-up = distributed on 1 rank / distributed on 2 ranks, of the medians; of each repeat's pair of "
              "runs: " + "; ".join(f"{'MatMatSolve' if solver == 'petsc' else 'direct'} "
                                    f"{min(v):.2f} to {max(v):.2f}" for solver, v in pairs.items())
              + " (this machine's timing noise is about +-30 %).  Distributed and direct on 2 ranks against "
              f"replicated on 1: {statistics.median(totals['replicated', None, 1]) / statistics.median(totals['distributed', 'direct', 2]):.2f} "
              "times as fast.", "",
              "Why the static solves by MatMatSolve do not speed up on 2 ranks (perf of one 2-rank run, "
              "100,548 DOFs, rank 0's samples over the whole run): at every call PETSc 3.18 builds and sorts a "
              "scatter of the whole distributed solution (PetscSortIntWithArray, PetscSortIntWithDataArray, "
              "PetscSFSetUpRanks, VecScatterCreate: 21 % of the samples), fresh memory is zeroed for each "
              "block (clear_page: 31 %, the largest single share), and the forward sweep visits every front of "
              "the dense right-hand sides.  Called directly, MUMPS visits only the fronts above the interface "
              "in the forward sweep of sparse right-hand sides, and the solution is moved once per block by "
              "one Alltoallv through buffers made once.  What is left does not halve on 2 ranks: MUMPS's solve "
              "phase itself (about 5-6 s on 1 rank with its two BLAS threads and on 2 ranks alike, over ICNTL(27) "
              "from -32 to 256) and first touches of the solution's fresh memory.", ""]
    path.write_text("\n".join(lines))


def _dirty() -> bool:
    """True if the work tree differs from HEAD (a measurement of uncommitted code says so)."""
    return bool(subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                               capture_output=True, text=True).stdout.strip())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "benchmarks.md"))
    ap.add_argument("--repeats", type=int, default=7, help="repeats of the AFT timing (sweeps: 3)")
    ap.add_argument("--offline-only", action="store_true", help="only the MPI offline-stage benchmark")
    ap.add_argument("--aft-only", action="store_true", help="only the AFT timing, printed as table rows")
    ap.add_argument("--offline-out", default=str(ROOT / "docs" / "benchmarks_offline.md"))
    ap.add_argument("--no-peer", action="store_true", help="skip the pyHarm comparison (it needs its own venv)")
    args = ap.parse_args(argv)
    command = "make bench" if os.environ.get("MAKELEVEL") else "python benchmarks/bench.py"
    if args.aft_only:
        print(f"AFT with exact Jacobian, 1,000 3D pairs, N = 256, H = 5, median of {args.repeats}, commit {_commit()}"
              f"{' + changes' if _dirty() else ''}")
        for label, r in bench_aft(args.repeats).items():
            share = " / ".join(f"{x:.2f}" for x in r["stick_slip_sep_share"])
            print(f"| {label} | {share} | {1e3 * r['residual_only_s']:.1f} | {1e3 * r['with_jacobian_s']:.1f} | 50 ms |")
        return 0
    if args.offline_only:
        bench_offline(Path(args.offline_out))
        print(Path(args.offline_out).read_text())
        return 0
    t_start = time.perf_counter()
    out = Path(args.out)
    img = out.parent / "img"
    img.mkdir(parents=True, exist_ok=True)
    sys.path.insert(0, str(ROOT / "benchmarks" / "peer"))
    m = machine()
    # first, while this process is small: the 2-rank run holds the dense static modes on each rank
    print("bench: offline stages (1 and 2 MPI ranks) ...", flush=True)
    bench_offline(Path(args.offline_out), command=command)
    print("bench: AFT ...", flush=True)
    aft = bench_aft(args.repeats)
    print("bench: full-order sweeps ...", flush=True)
    sdof = bench_frf(ROOT / "demos" / "sdof_jenkins.toml", repeats=3)
    beam = bench_frf(ROOT / "demos" / "beam2d.toml", force_factor=0.98, H=5, N=256, repeats=3)
    beam["label"] = " (stick-slip level, 0.98 F_sep)"
    roms = bench_roms(3, img)
    lap = bench_lap3d(3, img)
    print("bench: H and N convergence ...", flush=True)
    conv = bench_convergence()
    peer = None
    if not args.no_peer:
        import peer_compare as peer_mod

        peer = peer_mod.compare(repeats=3, plot=img / "peer_frf.png")
    write_markdown(out, m, aft, sdof, beam, command, roms, lap, conv, peer, time.perf_counter() - t_start)
    print(out.read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
