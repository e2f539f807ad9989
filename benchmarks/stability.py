"""The stability of the paper's beam at 3 N on its converged branch (issue 14), against time
integration.

    .venv/bin/python benchmarks/stability.py --out docs/benchmarks_stability.md   (make bench-stability)

1. The scene's sweep (demos/beam2d.toml, 3 N) at H = 41, N = 1024 by the exact condensation with the
   event-accurate AFT (its peak has converged to 0.1 % from H = 21: docs/benchmarks_harmonics.md),
   with the stability of every point: Hill's method on the full model's HBM Jacobian at the point's
   full field (CondensedProblem.hill_matrices), its exponents near zero by shift-invert Arnoldi.
2. The branch in stretches of one stability.  From one point inside each stretch (stable: its
   middle; unstable: its largest real part), the implicit Newmark integration of
   demos/beam_timeint_check.py (its own contact law, no code shared with the AFT) starts from the
   orbit's state at t = 0 and runs ``--periods`` periods.  Per period, the first harmonic of the
   output (complex: amplitude and phase) is compared with the orbit's: e_k = |Y_k - Y| / |Y|.
   A point marked stable is confirmed when e stays below 1 % over every period.  A point marked
   unstable is confirmed when the integration leaves it: e passes 1 %, or its envelope grows at
   half Hill's largest real part or faster before it settles on a nearby attractor (a period-doubled
   orbit, a torus: envelope_growth); inconclusive where even Hill's rate could not have carried the
   first period's e to 1 % within the run; contradicted otherwise.
"""
from __future__ import annotations

import argparse
import datetime
import json
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OUTPUT = "b1.mid.uy"
STAY = 0.01  # a stable orbit is kept within 1 % (the bar)


def stretches(stable: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each run of equal stability along the branch."""
    edges = np.flatnonzero(stable[1:] != stable[:-1]) + 1
    starts = np.r_[0, edges]
    ends = np.r_[edges - 1, stable.size - 1]
    return list(zip(starts.tolist(), ends.tolist()))


def pick(frf, a: int, b: int) -> int:
    """The point checked in the stretch a..b: a stable one's middle, an unstable one's fastest growth."""
    if frf.info["arrays"]["stable"][a]:
        return (a + b) // 2
    return a + int(np.argmax(frf.info["arrays"]["floquet_max_real"][a:b + 1]))


def envelope_growth(e: np.ndarray, omega: float, start: int = 4) -> tuple[float | None, list[int]]:
    """1/s: how fast the departure grows before it settles: the slope of the log of its running
    maximum (which rides over the beating of a complex pair) from period ``start`` + 1 (after the
    start's transient) to the first period where it reaches half its largest value or 1 %, with that
    window (1-based periods); None where the window is shorter than 3 periods or e does not grow
    3-fold over it.  A departure that grows at about Hill's rate and then settles below 1 % has left
    the orbit for a nearby attractor (a period-doubled orbit, a torus)."""
    env = np.maximum.accumulate(e)
    top = min(0.5 * e.max(), STAY)
    end = int(np.argmax(env >= top)) if (env >= top).any() else e.size - 1
    if end - start < 3 or env[end] < 3 * env[start]:
        return None, [start + 1, end + 1]
    return float(np.log(env[end] / env[start]) / ((end - start) * 2 * np.pi / omega)), [start + 1, end + 1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "benchmarks_stability.md"))
    ap.add_argument("--harmonics", type=int, default=41)
    ap.add_argument("--samples", type=int, default=1024)
    ap.add_argument("--periods", type=int, default=150)
    ap.add_argument("--steps", type=int, default=2000, help="Newmark steps per period")
    args = ap.parse_args(argv)
    out = Path(args.out)
    img = out.parent / "img"
    img.mkdir(parents=True, exist_ok=True)
    sys.path.insert(0, str(ROOT / "benchmarks"))
    sys.path.insert(0, str(ROOT / "demos"))
    from beam_timeint_check import departure
    from bench import machine
    from harmonics import scene_at

    from jointfem.analysis.frf import compute_frf, create_problem
    from jointfem.analysis.stability import leading_exponent
    from jointfem.app import sweep_options
    from jointfem.contact.jenkins import SEPARATED
    from jointfem.plots import plot_branch, pyplot
    from jointfem.rom.reductors import build_rom
    from jointfem.scene import create_structure

    t0 = time.perf_counter()
    H, N = args.harmonics, args.samples
    scene = scene_at(H, N, "events")  # bench-harmonics' scene: the beam at its 3 N, event-accurate AFT
    structure = create_structure(scene)
    exact = build_rom(structure, "exact")
    print(f"stability: sweep at H = {H}, N = {N} with Hill's stability at every point", flush=True)
    frf = compute_frf(exact, sweep_options(scene, stability="on"))
    t_sweep = time.perf_counter() - t0
    a = frf.info["arrays"]
    stable, re = a["stable"], a["floquet_max_real"]
    amp = frf.amplitude(frf.outputs[OUTPUT])
    sep = (frf.states == SEPARATED).mean(axis=(1, 2))
    harmonics = sweep_options(scene).harmonics
    problem = create_problem(exact, harmonics)
    runs = []
    for lo, hi in stretches(stable):
        i = pick(frf, lo, hi)
        if sep[lo:hi + 1].max() == 0 and runs and runs[-1]["separated_share"] == 0:
            continue  # one stuck stretch is enough (the first)
        ts = time.perf_counter()
        print(f"stability: Newmark from point {i} ({frf.omega[i]:.4f} rad/s, "
              f"{'stable' if stable[i] else 'unstable'})", flush=True)
        e = departure(structure, problem.full_coefficients(frf.U[i], frf.omega[i]), float(frf.omega[i]), harmonics,
                      periods=args.periods, steps=args.steps, dof=structure.outputs[OUTPUT])
        lead = leading_exponent(problem, frf.U[i], frf.omega[i], problem.evaluate(frf.U[i], frf.omega[i]))
        runs.append({"stretch": [lo, hi], "index": i, "omega_rad_s": float(frf.omega[i]),
                     "leading_exponent": [lead.real, lead.imag],
                     "stretch_omega_rad_s": [float(frf.omega[lo:hi + 1].min()), float(frf.omega[lo:hi + 1].max())],
                     "amplitude_m": float(amp[i]), "separated_share": float(sep[i]),
                     "stable": bool(stable[i]), "floquet_max_real": float(re[i]),
                     "e_first": float(e[0]), "e_max": float(e.max()), "e_last": float(e[-1]),
                     "e": e.tolist(),
                     "seconds": time.perf_counter() - ts})
    for r in runs:
        r["hill_growth_over_run"] = r["leading_exponent"][0] * args.periods * 2 * np.pi / r["omega_rad_s"]
        r["growth_rate"], r["growth_window"] = envelope_growth(np.array(r["e"]), r["omega_rad_s"])
        if r["stable"]:
            r["verdict"] = "confirmed" if r["e_max"] < STAY else "contradicted"
        elif r["e_max"] > STAY or (r["growth_rate"] is not None and r["growth_rate"] >= 0.5 * r["leading_exponent"][0]):
            r["verdict"] = "confirmed"  # it leaves: past 1 %, or growing at Hill's rate to a nearby attractor
        elif r["hill_growth_over_run"] < np.log(STAY / max(r["e_first"], 1e-12)):
            r["verdict"] = "inconclusive"
        else:
            r["verdict"] = "contradicted"

    # pictures: the branch near the peak, dashed where unstable, and the deviations against time
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    plot_branch(ax, frf.omega, amp, stable, label=f"exact condensation, H = {H}")
    marks = {}
    for r in runs:
        key = (r["stable"], r["verdict"])
        label = f"{'stable' if r['stable'] else 'unstable'} by Hill, Newmark: {r['verdict']}"
        line, = ax.plot(r["omega_rad_s"], r["amplitude_m"], {"confirmed": "o", "inconclusive": "s"}.get(r["verdict"], "x"),
                        ms=6, color="C2" if r["stable"] else "C3", ls="none", label=None if key in marks else label)
        marks[key] = line
    top = amp.max()
    ax.set_xlim(frf.omega[amp > 0.85 * top].min() - 1, frf.omega[amp > 0.85 * top].max() + 1)
    ax.set_ylim(0.85 * top, 1.01 * top)
    ax.set_xlabel("omega [rad/s]")
    ax.set_ylabel(f"{OUTPUT} first-harmonic amplitude [m]")
    ax.set_title(f"beam at 3 N, H = {H}: Hill's stability (dashed: unstable), checked by Newmark from the orbit",
                 fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(img / "stability_beam.png", dpi=120)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for r in runs:
        ax.semilogy(np.arange(1, len(r["e"]) + 1), r["e"], "-" if r["stable"] else "--",
                    label=f"{r['omega_rad_s']:.2f} rad/s, {'stable' if r['stable'] else 'unstable'}")
    ax.axhline(STAY, color="k", lw=0.8)
    ax.set_xlabel("period")
    ax.set_ylabel("|Y_k - Y| / |Y| (first harmonic of the period)")
    ax.set_title("Newmark started on each orbit: distance from it", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(img / "stability_beam_deviation.png", dpi=120)
    plt.close(fig)

    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    m = machine()
    minutes = (time.perf_counter() - t0) / 60
    cmd = "python benchmarks/stability.py" + "".join(
        f" --{k} {v}" for k, v in (("harmonics", H), ("samples", N), ("periods", args.periods), ("steps", args.steps)))
    n_st, n_un = int(stable.sum()), int((~stable).sum())
    lines = [
        "# The beam's stability at a converged H, against time integration",
        "",
        f"Regenerated by `make bench-stability` (`{cmd}`) on "
        f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC at commit {commit}, {minutes:.0f} min on "
        f"{m.get('cores')} cores ({platform.processor() or platform.machine()}).",
        "",
        f"The sweep: demos/beam2d.toml at its 3 N, H = {H}, N = {N}, exact condensation with the event-accurate "
        f"AFT, {frf.omega.size} points in {t_sweep:.0f} s with Hill's stability of the full model "
        f"({structure.num_dofs * harmonics.num_hc} unknowns) at every point: {n_st} stable, {n_un} unstable, "
        f"{len(stretches(stable))} stretches.  Located peak: "
        f"{frf.info['peaks'][OUTPUT].amplitude:.6e} m at {frf.info['peaks'][OUTPUT].omega:.4f} rad/s.",
        "",
        "![branch](img/stability_beam.png)",
        "",
        f"Newmark (average acceleration, {args.steps} steps per period, {args.periods} periods, "
        "demos/beam_timeint_check.py's own contact law) from one point of each stretch that separates "
        "(and from one stuck point).  e: the first harmonic of the output over a period against the "
        "orbit's, |Y_k - Y| / |Y|; growth (of an unstable point): the slope of the log of e's running maximum "
        "from period 5 (after the start's transient) to where it reaches half its largest value or 1 % "
        "(envelope_growth), beside Hill's largest real part.",
        "",
        "| stretch omega [rad/s] | point omega [rad/s] | amplitude [m] | separated share | Hill | leading exponent "
        "[1/s] | e period 1 | e max | e last | growth [1/s] | Hill's growth over the run | Newmark |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        g = "-" if r["growth_rate"] is None or r["stable"] else f"{r['growth_rate']:+.1f}"
        sr, si = r["leading_exponent"]
        lines.append(f"| {r['stretch_omega_rad_s'][0]:.3f}-{r['stretch_omega_rad_s'][1]:.3f} | {r['omega_rad_s']:.4f} | "
                     f"{r['amplitude_m']:.5e} | {r['separated_share']:.3f} | "
                     f"{'stable' if r['stable'] else 'unstable'} | {sr:+.3f} {'+' if si >= 0 else '-'} {abs(si):.1f}i | "
                     f"{r['e_first']:.1e} | {r['e_max']:.1e} | {r['e_last']:.1e} | {g} | "
                     f"{'-' if r['stable'] else 'e^%.1f' % r['hill_growth_over_run']} | "
                     f"{r['verdict'] if r['verdict'] != 'contradicted' else '**contradicted**'} |")
    real = [r for r in runs if not r["stable"] and abs(r["leading_exponent"][1]) < 1e-6 * r["omega_rad_s"]]
    cplx = [r for r in runs if not r["stable"] and r not in real]

    def count(rs, verdict):
        return sum(r["verdict"] == verdict for r in rs)

    def listed(rs):
        return ", ".join(f"{r['leading_exponent'][0]:+.1f} {'+-' if r['leading_exponent'][1] else ''}"
                         f"{abs(r['leading_exponent'][1]):.1f}i at {r['omega_rad_s']:.3f} rad/s" for r in rs)

    stable_runs = [r for r in runs if r["stable"]]
    text = (f"Verdicts: **confirmed** (stable: e stays below 1 %; unstable: e passes 1 %, or grows at half "
            "Hill's rate or faster before it settles, on a nearby attractor), **inconclusive** (neither, where even "
            "Hill's growth over the run could not take the first period's e to 1 %), **contradicted** (the rest).  "
            "Of the {0} points marked stable, {1} are confirmed (largest e {2:.1e}).  "
            "Of those marked unstable, {3} are so by a real exponent (a fold's middle branch): {4} confirmed, "
            "their departures growing at ".format(len(stable_runs), count(stable_runs, "confirmed"),
                                                  max(r["e_max"] for r in stable_runs), len(real),
                                                  count(real, "confirmed"))
            + ", ".join(f"{r['growth_rate']:+.1f} 1/s where Hill says {r['leading_exponent'][0]:+.1f}" for r in real
                        if r["growth_rate"] is not None)
            + f".  {len(cplx)} are so by a complex pair ({listed(cplx)}): {count(cplx, 'confirmed')} confirmed, "
            f"{count(cplx, 'inconclusive')} inconclusive, {count(cplx, 'contradicted')} contradicted"
            + ("; their departures grow at " + ", ".join(
                f"{r['growth_rate']:+.1f} 1/s where Hill says {r['leading_exponent'][0]:+.1f}" for r in cplx
                if r["growth_rate"] is not None) if any(r["growth_rate"] is not None for r in cplx) else "")
            + ".")
    lines += ["", text]
    lines += ["", "![deviation](img/stability_beam_deviation.png)", ""]
    out.write_text("\n".join(lines) + "\n")
    out.with_suffix(".json").write_text(json.dumps({"command": cmd, "commit": commit, "runs": runs}, indent=1))
    print(out.read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
