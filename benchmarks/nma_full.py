"""The 3D lap joint's backbone at full order against the exact condensation's (issue 15): the
condensed EPMC is the reference of `make bench-nma`; this checks it against the full-order EPMC
on the same equations (25k unknowns at H = 3, 35 to 60 s per point and more than 67 points: some
hours on 2 cores; the condensation takes about 3 minutes).

    .venv/bin/python benchmarks/nma_full.py --out docs/benchmarks_nma_full.md
"""
from __future__ import annotations

import argparse
import datetime
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
AT = (1e-4, 2e-4, 5e-4, 1e-3, 2e-3)


def main(argv=None):
    from jointfem import app
    from jointfem.analysis.nma import NmaIncomplete, compute_backbone
    from jointfem.rom import RomOptions, build_rom
    from jointfem.scene import create_structure, load_scene

    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="docs/benchmarks_nma_full.md")
    args = ap.parse_args(argv)
    scene = load_scene(ROOT / "demos" / "lap3d_friction.toml")
    s = create_structure(scene)
    opts = replace(app.nma_options(scene), at=AT)
    # no time limit: full order needs more than the scene's hour (it stopped at 1.8e-4 m after 67
    # points and 3600 s on 2 shared cores, 2026-12-02)
    opts = replace(opts, continuation=replace(opts.continuation, time_limit=None))
    res = {}
    for label in ("exact", "full"):
        t0 = time.perf_counter()
        model = s if label == "full" else build_rom(s, "exact", RomOptions())
        start = time.perf_counter()

        def progress(point, label=label, start=start):
            print(f"{label}: {time.perf_counter() - start:7.1f} s, log10 a = {point.lam:.4f}", file=sys.stderr)

        try:
            bb = compute_backbone(model, opts, callback=progress)
        except NmaIncomplete as exc:
            bb = exc.backbone
        res[label] = (bb, time.perf_counter() - t0)
    ex, full = res["exact"][0], res["full"][0]
    rows = []
    for a in AT:
        e, f = ex.info["at"].get(a), full.info["at"].get(a)
        if e and f:
            rows.append(f"| {a:g} | {f['omega_rad_s']:.6f} | {e['omega_rad_s'] / f['omega_rad_s'] - 1:+.2e} | "
                        f"{f['zeta']:.6f} | {e['zeta'] / f['zeta'] - 1:+.2e} | {e['energy_J'] / f['energy_J'] - 1:+.2e} |")
    commit = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    lines = ["# The 3D lap joint's nonlinear mode: full order against the exact condensation", "",
             f"Made by `python benchmarks/nma_full.py` on {datetime.datetime.utcnow():%Y-%m-%d %H:%M} UTC at commit "
             f"{commit}.  demos/lap3d_friction.toml, mode 2, self-excitation fundamental, H = {opts.harmonics.H}, "
             f"N = {opts.harmonics.N}; each amplitude solved there exactly.", "",
             f"| method | unknowns | points | status | time [s] |", "|---|---|---|---|---|"]
    for label, (bb, t) in res.items():
        lines.append(f"| {label} | {bb.info['num_unknowns']} | {bb.num_points} | {bb.info['status']} | {t:.0f} |")
    lines += ["", "| amplitude [m] | omega full [rad/s] | exact rel. | zeta full | exact rel. | energy per cycle, exact rel. |",
              "|---|---|---|---|---|---|"] + rows + [""]
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
