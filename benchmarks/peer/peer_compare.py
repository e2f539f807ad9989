"""Peer comparison: the three systems of benchmarks/peer/cases.py swept by jointfem (this venv) and
by pyHarm (its own venv, benchmarks/peer/.venv-pyharm, made by benchmarks/peer/setup.sh), with
the same H, N and Newton tolerance.  For each: the peak amplitude and frequency of the output's
first harmonic (parabola through the three highest points), the largest difference between the
curves (at every pyHarm point, jointfem solved at the same omega, over jointfem's peak), the point counts and the
median wall time of the whole sweep after one warm-up run (numba and jax compile on first use).

    python benchmarks/peer/peer_compare.py --out /tmp/peer.md       # alone; make bench includes it
"""
from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from cases import CASES  # noqa: E402

PEER_PY = HERE / ".venv-pyharm" / "bin" / "python"


def ensure_peer_venv() -> None:
    if not PEER_PY.exists():
        subprocess.run(["bash", str(HERE / "setup.sh")], check=True)


def lumped_spec(case: dict):
    from jointfem.models.lumped import ForceSpec, JenkinsSpec, LinkSpec, LumpedSpec, MassSpec

    return LumpedSpec(
        masses=tuple(MassSpec(n, 1.0, tuple(ax)) for n, ax in case["dofs"].items()),
        springs=tuple(LinkSpec(a, b, v) for a, b, v in case["springs"]),
        dampers=tuple(LinkSpec(a, b, v) for a, b, v in case["dampers"]),
        jenkins=tuple(JenkinsSpec(p["node"], "ground", tuple(p["tangential"]), p["normal"], kt=p["kt"], kn=p["kn"],
                                  mu=p["mu"], N0=p["N0"]) for p in case["jenkins"]),
        forces=tuple(ForceSpec(d, a) for d, a in case["forces"]), outputs=(case["output"],))


def run_jointfem(case: dict, repeats: int) -> dict:
    from jointfem.continuation.arclength import ContinuationOptions, NewtonOptions
    from jointfem.analysis.frf import SweepOptions, compute_frf
    from jointfem.harmonics import Harmonics
    from jointfem.models.lumped import create_lumped

    tol = case["tol"]
    opts = SweepOptions(*case["omega"], Harmonics(case["H"], case["N"]),
                        ContinuationOptions(newton=NewtonOptions(tol=tol, relaxed_kink_tol=max(1e-6, tol))))

    def sweep():
        return compute_frf(create_lumped(lumped_spec(case)), opts)  # the model is built inside the timing

    t = time.perf_counter()
    frf = sweep()
    warm = time.perf_counter() - t
    walls = []
    for _ in range(repeats):
        t = time.perf_counter()
        frf = sweep()
        walls.append(time.perf_counter() - t)
    return {"omega": frf.omega, "amp": frf.amplitude(frf.outputs[case["output"]]), "points": len(frf.omega),
            "iterations": int(frf.iterations.sum()), "median_s": statistics.median(walls), "warmup_s": warm,
            "unknowns": int(frf.U.shape[1]), "frf": frf}


def jointfem_at(case: dict, frf, omegas: np.ndarray) -> np.ndarray:
    """jointfem's amplitude at the given frequencies, each by Newton at fixed omega started from
    the nearest point of its own branch: the curves are compared point by point, free of any
    interpolation between points."""
    from jointfem.continuation.arclength import NewtonOptions, solve_newton
    from jointfem.hbm.forced import compute_scales
    from jointfem.hbm.problem import newton_system
    from jointfem.harmonics import Harmonics
    from jointfem.hbm.residual import HBMResidual
    from jointfem.models.lumped import create_lumped

    s = create_lumped(lumped_spec(case))
    h = Harmonics(case["H"], case["N"])
    r = HBMResidual(s, h)
    scale = np.tile(compute_scales(s, *case["omega"]), h.num_hc)
    fmax = max(abs(a) for _, a in case["forces"])
    out = s.outputs[case["output"]]
    amps = []
    for w in omegas:
        k = int(np.argmin(np.abs(frf.omega - w)))
        U, _ = solve_newton(newton_system(r), frf.U[k], float(w),
                            x_scale=scale, r_scale=fmax, options=NewtonOptions(tol=case["tol"]))
        amps.append(h.amplitude(U.reshape(h.num_hc, -1)[:, out], 1))
    return np.array(amps)


def run_pyharm(name: str, repeats: int) -> dict:
    ensure_peer_venv()
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "r.json"
        r = subprocess.run([str(PEER_PY), str(HERE / "run_pyharm.py"), name, "--repeats", str(repeats), "--out",
                            str(out)], capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(f"pyHarm run of {name} failed:\n{r.stderr[-3000:]}")
        res = json.loads(out.read_text())
    res["omega"], res["amp"] = np.array(res["omega"]), np.array(res["amp"])
    return res


def compare(names=("sdof", "separation", "chain"), repeats: int = 3, plot: Path | None = None) -> list[dict]:
    from jointfem.results import parabola_peak

    rows = []
    curves = []
    for name in names:
        case = CASES[name]()
        print(f"peer: {name} (jointfem) ...", flush=True)
        j = run_jointfem(case, repeats)
        print(f"peer: {name} (pyHarm) ...", flush=True)
        p = run_pyharm(name, repeats)
        wj, aj = parabola_peak(j["omega"], j["amp"])
        wp, ap = parabola_peak(p["omega"], p["amp"])
        diff = np.abs(jointfem_at(case, j["frf"], p["omega"]) - p["amp"]).max() / aj
        rows.append({"case": case["name"], "H": case["H"], "N": case["N"], "tol": case["tol"],
                     "unknowns": j["unknowns"], "peak_amp_diff": ap / aj - 1, "peak_freq_diff": wp / wj - 1,
                     "curve_diff": diff, "points_j": j["points"], "points_p": p["points"],
                     "time_j": j["median_s"], "time_p": p["median_s"],
                     "it_j": j["iterations"] / j["points"], "it_p": float(np.mean(p["iterations"])),
                     "per_point_j": j["median_s"] / j["points"], "per_point_p": p["median_s"] / p["points"], "warm_j": j["warmup_s"],
                     "warm_p": p["warmup_s"], "speedup": p["median_s"] / j["median_s"],
                     "pyharm": p["pyharm"], "profile_p": p["profile"], "peer_versions": {k: p[k] for k in ("numpy", "scipy", "numba", "jax")}})
        curves.append((case["name"], j, p))
    if plot is not None:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axs = plt.subplots(1, len(curves), figsize=(5 * len(curves), 3.8))
        for ax, (title, j, p) in zip(np.atleast_1d(axs), curves):
            ax.plot(p["omega"], p["amp"], "-", color="0.6", lw=3, label=f"pyHarm ({p['points']} points)")
            ax.plot(j["omega"], j["amp"], ".-", color="C0", ms=3, lw=1, label=f"jointfem ({j['points']} points)")
            ax.set_xlabel("omega [rad/s]")
            ax.set_ylabel("first-harmonic amplitude [m]")
            ax.set_title(title, fontsize=9)
            ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(plot, dpi=110)
        plt.close(fig)
    return rows


def markdown(rows: list[dict], figure: str | None = None) -> list[str]:
    r0 = rows[0]
    v = r0["peer_versions"]
    lines = [f"pyHarm {r0['pyharm']} (pyharm-os from PyPI, in benchmarks/peer/.venv-pyharm: numpy {v['numpy']}, "
             f"scipy {v['scipy']}, numba {v['numba']}, jax {v['jax']}), driven through its input dictionary by "
             "benchmarks/peer/run_pyharm.py; the systems are in benchmarks/peer/cases.py.  Wall time = the whole "
             "sweep (model set-up included), median of the repeats after one warm-up run in the same process; "
             "both sides use their own step control.", "",
             "| system | H | N | tol | unknowns | peak amp diff | peak freq diff | curve diff | points (jointfem / pyHarm) "
             "| Newton it./point (jointfem / pyHarm) | jointfem [s] | pyHarm [s] | pyHarm / jointfem | ms/point (jointfem / pyHarm) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['case']} | {r['H']} | {r['N']} | {r['tol']:.0e} | {r['unknowns']} | "
                     f"{100 * r['peak_amp_diff']:+.3f} % | {100 * r['peak_freq_diff']:+.4f} % | "
                     f"{100 * r['curve_diff']:.2f} % | {r['points_j']} / {r['points_p']} | {r['it_j']:.1f} / {r['it_p']:.1f} | "
                     f"{r['time_j']:.2f} | "
                     f"{r['time_p']:.2f} | **{r['speedup']:.1f}** | {1e3 * r['per_point_j']:.1f} / "
                     f"{1e3 * r['per_point_p']:.1f} |")
    lines += ["", "Where pyHarm's time goes (one further, profiled sweep of each system, shares of its total; the "
              "element loops overlap the global Jacobian, which contains their Jacobian half, and the friction "
              "elements' Jacobians are part of the loops):", "",
              "| system | global Jacobian (System.Jacobian) | per-element loops (residual and Jacobian) | friction "
              "elements' Jacobians | dense linear solves | predictor's dense QR |", "|---|---|---|---|---|---|"]
    for r in rows:
        q = r["profile_p"]
        lines.append(f"| {r['case']} | {100 * q['global_jacobian']:.0f} % | {100 * q['element_loops']:.0f} % | "
                     f"{100 * q['friction_jacobians']:.0f} % | {100 * q['linear_solves']:.0f} % | "
                     f"{100 * q['predictor_qr']:.0f} % |")
    if figure:
        lines += ["", f"![jointfem against pyHarm]({figure})"]
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cases", default="sdof,separation,chain")
    args = ap.parse_args(argv)
    out = Path(args.out)
    fig = out.with_name("peer_frf.png")
    rows = compare(tuple(args.cases.split(",")), args.repeats, fig)
    out.write_text("\n".join(markdown(rows, fig.name)) + "\n")
    print(out.read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
