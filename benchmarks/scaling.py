"""Scaling laws of the offline stage (issue 17): time and peak memory per rank of each stage of the
3D lap joint against its DOFs (about 10k to 300k, about 140 pairs) and its pairs (about 25 to 1000,
about 100k DOFs), on 1 and 2 MPI ranks, with log-log slopes fitted per stage; and one model of
about 500k DOFs, for the peak memory.

    .venv/bin/python benchmarks/scaling.py --out docs/benchmarks_scaling.md [--quick] [--budget 1200]
    .venv/bin/python benchmarks/scaling.py --distributed --out docs/benchmarks_scaling_distributed.md

--distributed: the same runs of the distributed offline stage (offline_stages.py --distributed: K, M
and the static modes stay in row blocks, nothing model-sized gathered), its big model at 0.9 mm
(525k DOFs), and its picture docs/img/scaling_distributed.png.

Each point is one run of benchmarks/offline_stages.py (serial, then under mpirun -n 2), in its own
process, killed past ``--budget`` seconds (the row then says so).  Writes the Markdown table, a JSON
of every run next to it, and a log-log PNG (docs/img/scaling.png): the slopes from which to say
what a larger run would cost.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

# (series, size, size_normal, size_joint) in m: along x away from the joint, across the bars' height,
# over the joint along x and along z (the pairs: (0.06 / size_joint + 1) (0.05 / size_joint + 1))
DOFS = [("dofs", 0.02, 0.003, 0.005), ("dofs", 0.006, 0.003, 0.005), ("dofs", 0.003, 0.0015, 0.005),
        ("dofs", 0.0015, 0.001, 0.005)]
PAIRS = [("pairs", 0.00114, 0.002, 0.0125), ("pairs", 0.00264, 0.002, 0.005), ("pairs", 0.0061, 0.002, 0.0025),
         ("pairs", 0.0113, 0.002, 0.00175)]
# at least 500k DOFs: does the offline stage fit this machine's 24 GiB (issue 17)?
BIG = [("big", 0.00095, 0.001, 0.005)]
BIG_DISTRIBUTED = [("big", 0.0009, 0.001, 0.005)]  # 525,096 DOFs: past 500k
QUICK = [DOFS[0], ("pairs", 0.02, 0.003, 0.0125), ("pairs", 0.02, 0.003, 0.005)]


def run_json(cmd: list[str], budget: float, row: dict) -> dict:
    """Run ``cmd --json FILE`` in its own process, stopped past ``budget`` seconds: its JSON updated
    with ``row``, status "done" and the wall seconds, or ``row`` with the status saying why not."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "r.json"
        t0 = time.perf_counter()
        try:
            r = subprocess.run(cmd + ["--json", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=budget)
        except subprocess.TimeoutExpired:
            return {**row, "status": f"over the budget of {budget:g} s"}
        if r.returncode != 0 or not out.exists():
            return {**row, "status": failure(r.returncode, r.stdout + r.stderr)}
        res = json.loads(out.read_text())
    res.update(row, status="done", wall_s=time.perf_counter() - t0)
    return res


def run_one(case, ranks: int, budget: float, distributed: bool = False) -> dict:
    series, size, hn, hj = case
    cmd = [sys.executable, str(ROOT / "benchmarks" / "offline_stages.py"), "--size", str(size), "--size-normal",
           str(hn), "--size-joint", str(hj)] + (["--distributed"] if distributed else [])
    if ranks > 1:
        from bench import mpirun

        cmd = mpirun(ranks) + cmd
    return run_json(cmd, budget, {"series": series, "ranks": ranks, "case": list(case[1:])})


def failure(code: int, output: str) -> str:
    """One line (no table separators) for a run that failed."""
    if code in (137, -9) or "signal 9" in output:
        return "killed by signal 9 (exit 137): out of memory, if the kernel log names its OOM killer"
    tail = " / ".join(ln.strip() for ln in output.strip().splitlines()[-3:] if ln.strip("- "))
    return f"failed (exit {code}): {tail.replace('|', '/')}"


# the stages of offline_stages.py (in its JSON the eigen and static ones carry their counts: stage_time)
STAGES = ["mesh", "assembly", "gather", "contact", "eigen", "static", "projection", "offline_total"]


def stage_time(run, stage):
    for k, v in run["stages_s"].items():
        if k == stage or k.startswith(stage + "_"):
            return v
    return None


def slope(x, y):
    """The least-squares slope of log y against log x (None with fewer than 2 positive points)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = (x > 0) & (y > 0)
    if ok.sum() < 2:
        return None
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])


def fits(runs):
    """{(series, ranks): {stage or 'peak_gb': slope}} against DOFs (series dofs) or pairs (series pairs)."""
    out = {}
    for series, var in (("dofs", "dofs"), ("pairs", "pairs")):
        for ranks in (1, 2):
            rs = [r for r in runs if r["series"] == series and r["ranks"] == ranks and r["status"] == "done"]
            if len(rs) < 2:
                continue
            x = [r[var] for r in rs]
            f = {st: slope(x, [stage_time(r, st) or 0.0 for r in rs]) for st in STAGES}
            f["peak_gb"] = slope(x, [max(r["peak_gb_per_rank"].values()) for r in rs])
            out[(series, ranks)] = f
    return out


def plot(runs, path: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    for ax, (series, var, what) in zip(axes, (("dofs", "dofs", "time"), ("pairs", "pairs", "time"),
                                              ("dofs", "dofs", "memory"))):
        for ranks, ls in ((1, "-"), (2, "--")):
            rs = sorted((r for r in runs if r["series"] == series and r["ranks"] == ranks and r["status"] == "done"),
                        key=lambda r: r[var])
            if not rs:
                continue
            x = [r[var] for r in rs]
            if what == "memory":
                y = [max(r["peak_gb_per_rank"].values()) for r in rs]
                s = slope(x, y)
                ax.loglog(x, y, "o" + ls, label=f"{ranks} rank(s), slope {float('nan') if s is None else s:.2f}")
                continue
            for st, c in (("assembly", "C0"), ("eigen", "C1"), ("static", "C2"), ("projection", "C3"),
                          ("offline_total", "k")):
                y = [stage_time(r, st) or np.nan for r in rs]
                s = slope(x, y)
                ax.loglog(x, y, "o" + ls, color=c, label=f"{st}, {ranks} rank(s): {s:.2f}" if s is not None else None)
        ax.set_xlabel("DOFs" if var == "dofs" else "contact pairs")
        ax.set_ylabel("peak memory of the largest rank [GB]" if what == "memory" else "time [s]")
        ax.set_title({"time": f"offline stages against {var}", "memory": "peak memory per rank"}[what])
    save_loglog(fig, axes, path, fontsize=7)


def save_loglog(fig, axes, path: Path, *, fontsize: int):
    """Grid and legend on each axes, then the figure to ``path`` (its folder made)."""
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=fontsize)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)


def table(runs, fitted, command: str, distributed: bool = False) -> str:
    from bench import _commit, machine

    m = machine()
    kind = ("the distributed offline stage (jointfem.fem.distributed: K, M and the static modes in row blocks, "
            "only reduced data gathered; gather is therefore 0, contact includes K_lin)" if distributed else
            "the replicated offline stage (K and M gathered to every rank in canonical order)")
    lines = ["# Offline-stage scaling (issue 17)" + (", distributed" if distributed else ""), "",
             f"Of {kind}.", "",
             f"Regenerated by `{command}` on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} at commit "
             f"{_commit()}, one run each ({m['cpu']}, {m.get('cores', '?')} cores). 3D lap joint, Q2 hexahedra, "
             "20 modes; static modes: one MUMPS solve per contact component; projection: the penalty ROM's "
             "[modes, static modes]^T (K_lin, M) [modes, static modes]. Peak: the largest rank's resident memory "
             "(getrusage), GB.", "",
             "| series | ranks | DOFs | pairs | mesh | assembly | gather | contact | eigen | static | projection "
             "| total [s] | peak [GB] | status |", "|" + "---|" * 14]
    for r in runs:
        if r["status"] != "done":
            lines.append(f"| {r['series']} | {r['ranks']} | | | | | | | | | | | | {r['status']} (sizes {r['case']}) |")
            continue
        t = [stage_time(r, st) for st in STAGES]
        lines.append(f"| {r['series']} | {r['ranks']} | {r['dofs']} | {r['pairs']} | "
                     + " | ".join(f"{v:.2f}" for v in t) + f" | {max(r['peak_gb_per_rank'].values()):.2f} | done |")
    lines += ["", "Fitted log-log slopes (time or peak memory ~ DOFs^a in the DOF series, ~ pairs^a in the pair "
              "series; the pair series also changes the DOFs a little):", "",
              "| series | ranks | " + " | ".join(STAGES) + " | peak memory |", "|" + "---|" * 11]
    for (series, ranks), f in fitted.items():
        lines.append(f"| {series} | {ranks} | " + " | ".join("" if f[st] is None else f"{f[st]:.2f}"
                                                           for st in STAGES + ["peak_gb"]) + " |")
    lines += ["", f"![scaling](img/{'scaling_distributed' if distributed else 'scaling'}.png)", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "benchmarks_scaling.md"))
    ap.add_argument("--quick", action="store_true", help="three small points only (a check of the script)")
    ap.add_argument("--budget", type=float, default=1200.0, help="seconds per run before it is stopped")
    ap.add_argument("--ranks", default="1,2")
    ap.add_argument("--distributed", action="store_true", help="the distributed offline stage")
    args = ap.parse_args(argv)
    out = Path(args.out)
    cases = QUICK if args.quick else DOFS + PAIRS + (BIG_DISTRIBUTED if args.distributed else BIG)
    runs = []
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm is in the venv
        tqdm = None
    todo = [(c, int(k)) for c in cases for k in args.ranks.split(",")]
    bar = tqdm(total=len(todo), desc="offline scaling") if tqdm else None
    for case, ranks in todo:
        runs.append(run_one(case, ranks, args.budget, args.distributed))
        if bar:
            bar.update()
            bar.set_postfix_str(f"{runs[-1].get('dofs', '?')} DOFs, {ranks} rank(s): {runs[-1]['status']}")
    if bar:
        bar.close()
    out.with_suffix(".json").write_text(json.dumps(runs, indent=1))
    fitted = fits(runs)
    plot(runs, out.parent / "img" / ("scaling_distributed.png" if args.distributed else "scaling.png"))
    command = "python benchmarks/scaling.py " + " ".join(argv if argv is not None else sys.argv[1:])
    out.write_text(table(runs, fitted, command.strip(), args.distributed))
    print(out.read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
