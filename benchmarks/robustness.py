"""Does a sweep that completes on one machine complete on another (issue 52)?

The strong-separation sweeps of tests/test_corners.py (the 9-pair 3D lap joint at 3 N by the
penalty ROM and by the exact condensation, the 2D lap joint at full order; H = 3, N = 256), each
run under several OpenBLAS core types (the kernels another CPU family would take) and with K's
entries changed at random by up to 1e-15 of themselves (seeds), each in a process of its own.
Per run: status, points, leaps (the continuation's last resort before a stop), the located peaks;
then per sweep the spread of each peak over the runs.  Writes a Markdown table.

    .venv/bin/python benchmarks/robustness.py --out docs/benchmarks_robustness.md --jobs 2
    .venv/bin/python benchmarks/robustness.py --cases lap3d-penalty --cores Haswell --seeds 3   (printed)

A core type the host's OpenBLAS cannot run is reported as such by OpenBLAS at start-up; Haswell,
SkylakeX and Sandybridge run on any AVX-512 x86 host, Haswell and Sandybridge on any AVX2 one.
"""
from __future__ import annotations

import argparse
import copy
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# (id, demo, force N, method, samples N, [mesh] size m): tests/test_corners.py's LAPS
CASES = {
    "lap3d-penalty": ("lap3d", 3.0, "penalty", 256, 0.03),
    "lap3d-exact": ("lap3d", 3.0, "exact", 256, 0.03),
    "lap2d-full": ("lap2d", 3.0, "full", 256, 0.03),
}


def run_one(case: str, seed: int | None) -> dict:
    """One sweep in this process (OPENBLAS_CORETYPE was set before numpy was imported)."""
    import ctypes.util

    import numpy as np
    from dataclasses import replace

    from jointfem.analysis.frf import SweepIncomplete, compute_frf
    from jointfem.app import override_harmonics, sweep_options
    from jointfem.rom.common import RomOptions
    from jointfem.rom.reductors import build_rom
    from jointfem.scene import create_structure, load_scene, parse_scene

    name, force, method, N, size = CASES[case]
    data = copy.deepcopy(load_scene(ROOT / "demos" / f"{name}.toml").data)
    data["force"]["amplitude"] = force
    data["mesh"].pop("file", None)
    data["mesh"]["size"] = size
    scene = override_harmonics(parse_scene(data, f"{name}_robustness.toml"), 3, N)
    s = create_structure(scene)
    if seed is not None:
        K = s.K.tocsr()
        E = K.copy()
        E.data = E.data * np.random.default_rng(seed).uniform(-1e-15, 1e-15, E.data.size)
        s = replace(s, K=(K + 0.5 * (E + E.T)).tocsr())
    model = s if method == "full" else build_rom(s, method, RomOptions(modes=10))
    t0 = time.perf_counter()
    try:
        frf = compute_frf(model, sweep_options(scene, stability="off"))
        why = ""
    except SweepIncomplete as exc:
        frf, why = exc.frf, str(exc)
    core = ""
    try:
        import ctypes
        lib = ctypes.CDLL(ctypes.util.find_library("openblas") or "libopenblas.so.0")
        lib.openblas_get_corename.restype = ctypes.c_char_p
        core = lib.openblas_get_corename().decode()
    except (OSError, AttributeError):
        pass
    info = frf.info
    return {"case": case, "seed": seed, "core": core, "status": info["status"], "why": why[:300],
            "points": len(frf.omega), "omega_last": float(frf.omega[-1]),
            "stats": {k: int(v) for k, v in (info.get("continuation") or {}).items()},
            "residual_max": float(np.max(info["arrays"]["residual"])),
            "peaks": {k: {"omega": float(p.omega), "amplitude": float(p.amplitude), "located": bool(p.located)}
                      for k, p in (info.get("peaks") or {}).items()},
            "seconds": time.perf_counter() - t0}


def spawn(case: str, core: str | None, seed: int | None, threads: str | None) -> dict:
    env = dict(os.environ)
    for key, value in (("OPENBLAS_CORETYPE", core), ("OPENBLAS_NUM_THREADS", threads)):
        if value is None:
            env.pop(key, None)
        else:
            env[key] = value
    with tempfile.NamedTemporaryFile(suffix=".json") as f:
        cmd = [sys.executable, __file__, "--one", case, "--json", f.name] + ([] if seed is None else ["--seed", str(seed)])
        r = subprocess.run(cmd, env=env, capture_output=True, text=True)
        if r.returncode != 0:
            return {"case": case, "seed": seed, "core": core or "", "status": "error", "why": r.stderr[-300:],
                    "points": 0, "peaks": {}, "stats": {}, "seconds": 0.0}
        row = json.loads(Path(f.name).read_text())
    row["core_asked"] = core or "host"
    return row


def table(rows: list[dict], cmd: str) -> str:
    lines = [f"# Robustness of the strong-separation sweeps to round-off (issue 52)", "",
             f"Measured {datetime.date.today()} on {platform.node() or 'this machine'} ({platform.processor() or platform.machine()}), "
             f"`{cmd}`. Each run in its own process; K perturbed by up to 1e-15 of its entries where a seed is given.", "",
             "| sweep | core type | seed | status | points | leaps | largest residual | peak omega (rad/s) | peak amplitude (m) | s |",
             "| --- | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in rows:
        pk = next(iter(sorted(r["peaks"].items())), (None, None))[1]
        lines.append(f"| {r['case']} | {r.get('core_asked', '')} ({r['core']}) | {r['seed'] if r['seed'] is not None else '-'} | "
                     f"{r['status']} | {r['points']} | {r['stats'].get('leaps', '-')} | "
                     f"{r.get('residual_max', float('nan')):.1e} | "
                     + (f"{pk['omega']:.6f} | {pk['amplitude']:.6e}" if pk else "- | -") + f" | {r['seconds']:.0f} |")
    lines += ["", "Spread of each located peak over the runs that completed, relative to its smallest value:", "",
              "| sweep | output | runs complete | omega spread | amplitude spread |", "| --- | --- | ---: | ---: | ---: |"]
    for case in dict.fromkeys(r["case"] for r in rows):
        done = [r for r in rows if r["case"] == case and r["status"] == "complete"]
        total = sum(r["case"] == case for r in rows)
        for out in sorted(done[0]["peaks"]) if done else []:
            w = [r["peaks"][out]["omega"] for r in done]
            a = [r["peaks"][out]["amplitude"] for r in done]
            lines.append(f"| {case} | {out} | {len(done)} of {total} | {(max(w) - min(w)) / min(w):.1e} | "
                         f"{(max(a) - min(a)) / min(a):.1e} |")
    stopped = [r for r in rows if r["status"] != "complete"]
    if stopped:
        lines += ["", "Runs that did not complete:", ""] + [f"- {r['case']}, {r.get('core_asked')}, seed {r['seed']}: {r['why']}"
                                                           for r in stopped]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path)
    ap.add_argument("--cases", nargs="*", default=list(CASES), choices=list(CASES))
    ap.add_argument("--cores", nargs="*", default=["host", "Haswell", "SkylakeX"])
    ap.add_argument("--seeds", type=int, default=5, help="perturbed runs per core type (seeds 1..n), besides the unperturbed one")
    ap.add_argument("--threads", default="1", help="OPENBLAS_NUM_THREADS for every run (default 1: runs side by side "
                    "with spinning BLAS threads slowed each other several times over)")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--one", choices=list(CASES), help=argparse.SUPPRESS)
    ap.add_argument("--seed", type=int, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--json", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        args.json.write_text(json.dumps(run_one(args.one, args.seed)))
        return 0
    jobs = [(c, None if core == "host" else core, seed) for c in args.cases for core in args.cores
            for seed in [None, *range(1, args.seeds + 1)]]
    def one(job):
        r = spawn(job[0], job[1], job[2], args.threads)
        print(r["case"], r.get("core_asked"), r["seed"], r["status"], r["points"], r["stats"].get("leaps"),
              {k: (round(p["omega"], 6), p["amplitude"]) for k, p in r["peaks"].items()}, f"{r['seconds']:.0f} s", flush=True)
        return r

    with ThreadPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(one, jobs))
    cmd = "python benchmarks/robustness.py " + " ".join(sys.argv[1:] if argv is None else argv)
    cmd += f" (OPENBLAS_NUM_THREADS={args.threads})"
    text = table(rows, cmd)
    if args.out:
        args.out.write_text(text)
    else:
        print(text)
    return 0 if all(r["status"] == "complete" for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
