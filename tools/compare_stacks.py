"""The same numbers on Debian 12's and Debian 13's FEniCSx stacks (issue 20).

    python tools/compare_stacks.py run --out results/stack_bookworm.json     # on each stack
    python tools/compare_stacks.py compare results/stack_bookworm.json results/stack_trixie.json

``run`` builds the demos' continuum models on the stack it runs on (gmsh, dolfinx assembly,
SLEPc/MUMPS or the dense solvers, whichever the model's size picks) and writes to JSON:

* lap2d (demos/lap2d.toml, 2D plane stress, exact condensation on the gaps) and lap3d
  (demos/lap3d.toml, 3D, the penalty ROM with 10 modes, as README's command runs it): the
  first-harmonic amplitude of every output at a fixed grid of omegas across each scene's range,
  each point solved by Newton from the stuck linear solution there (so both stacks solve the same
  problems at the same omegas);
  then the arclength sweep over the first quarter of the range (points, omegas, amplitudes);
* brb (demos/brb.toml at demos/brb.py's --quick mesh: the static preload of the three bolts,
  the supports): the 10 lowest stuck natural frequencies (six rigid-body modes on the supports,
  then the elastic ones), and the same for the full mesh with ``--full-brb``.

Round-off sets the floor: the two stacks assemble K with different generated kernels (FFCx 0.5 and
0.9), whose entries differ by about 1e-15 of K's largest; perturbing K's entries at random by 1e-15
of themselves moves lap3d's grid amplitudes by 6e-9 to 1.0e-8 of their peak (measured on Debian 12:
mode 1's w^2 is 1e-7 of the elements' stiffness scale, and the resonance, Q about 100, amplifies it).
``matrices`` writes lap3d's assembled K, M, D (with the gap rows and force, to check that the DOFs
are the same) on one stack, and ``swap`` solves lap3d's grid on another with them: measured,
Debian 12 with Debian 13's matrices agrees with Debian 13 to 5.1e-10 (1.9e-8 with its own), so the
stacks' difference is the assembly's last bits, not SLEPc, LAPACK, numpy or the HBM.

    python tools/compare_stacks.py matrices --out /tmp/lap3d_trixie             # on one stack (a folder)
    python tools/compare_stacks.py swap --matrices /tmp/lap3d_trixie --out /tmp/swap.json  # on the other
    python tools/compare_stacks.py compare /tmp/swap.json docs/stacks/trixie.json --only lap3d

``compare`` prints the largest differences and exits 1 where one exceeds its bound: the grid
amplitudes relative to each output's largest amplitude on the grid (--sweep-tol, 1e-8), the
elastic natural frequencies relative to themselves (--modes-tol, 1e-8; the rigid-body ones on the
supports are reported: see BRB_RIGID).  The arclength sweeps are
reported, not judged: the continuation's steps depend on the Newton iterations of each point.
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SWEEP_TOL = 1e-8
MODES_TOL = 1e-8
BRB_QUICK = ["mesh.size=0.0254", "mesh.size_normal=0.0127"]  # demos/brb.py's QUICK mesh (33 pairs)
# The BRB's six lowest modes are rigid-body modes on its soft supports (1-6 Hz, demos/brb.py's MODE = 7
# is the first bending).  Their w^2 is 1e-10 of the elements' stiffness scale, so round-off in K
# decides their last digits: perturbing K's entries at random by 1e-15 of themselves moves them by up
# to 7e-7 (and SLEPc against dense LAPACK on one stack by up to 3e-7), measured on the quick mesh on
# Debian 12.  They are reported, not judged; the elastic modes are judged at MODES_TOL.
BRB_RIGID = 6
LAP3D = ("demos/lap3d.toml", "penalty", 10, 33)  # scene, method, modes, grid omegas


def _stack() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    out = {"python": platform.python_version()}
    try:
        out["release"] = next(line.split("=", 1)[1].strip().strip('"') for line in
                              Path("/etc/os-release").read_text().splitlines() if line.startswith("VERSION_CODENAME="))
    except (OSError, StopIteration):
        out["release"] = "unknown"
    for pkg in ("fenics-dolfinx", "petsc4py", "slepc4py", "numpy", "scipy", "gmsh", "mpi4py"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            try:
                out[pkg] = __import__(pkg.replace("fenics-", "")).__version__
            except Exception:  # noqa: BLE001 - a version we cannot read is recorded as such
                out[pkg] = "unknown"
    return out


def _save_matrices(structure, folder: Path) -> None:
    """The assembled model of a case into ``folder``: K, M, D and every contact group's gap rows G
    (scipy.sparse.save_npz), and the force (force.npz)."""
    import scipy.sparse as sp

    folder.mkdir(parents=True, exist_ok=True)
    G = sp.vstack([g.gap for g in structure.contacts])
    for name, A in (("K", structure.K), ("M", structure.M), ("D", structure.D), ("G", G)):
        sp.save_npz(folder / f"{name}.npz", sp.csr_matrix(A))
    np.savez(folder / "force.npz", fc=structure.fc, fs=structure.fs)


def _swap_matrices(structure, folder: Path):
    """``structure`` with K, M and D assembled on another stack (``_save_matrices``), after checking
    that the two are the same problem: the same DOFs in the same order (the gap rows, which say which
    DOFs meet, and the force equal to 1e-14), so only the assembled matrices differ."""
    import dataclasses

    import scipy.sparse as sp

    load = {name: sp.load_npz(folder / f"{name}.npz").tocsr() for name in "KMDG"}
    z = np.load(folder / "force.npz")
    G, Gz = sp.vstack([g.gap for g in structure.contacts]).tocsr(), load["G"]
    same = (Gz.shape == G.shape and abs(Gz - G).max() <= 1e-14 * abs(G).max()
            and np.allclose(z["fc"], structure.fc, rtol=0, atol=1e-14 * np.abs(structure.fc).max())
            and np.allclose(z["fs"], structure.fs, rtol=0, atol=1e-14 * max(np.abs(structure.fs).max(), 1.0)))
    if not same:
        raise SystemExit(f"compare_stacks: {folder}: not the same DOFs, pairs or force as this stack's model "
                         "(the meshes number their nodes differently?): cannot swap the matrices")
    return dataclasses.replace(structure, K=load["K"], M=load["M"], D=load["D"])


def _grid_and_sweep(scene_file: str, method: str, modes: int, num: int, sets=(), *, matrices: Path | None = None,
                    sweep: bool = True) -> dict:
    """The grid of fixed-omega solutions and the arclength sweep of a scene.  ``matrices``: solve
    with K, M, D from that folder (``save_matrices`` on another stack)."""
    from jointfem import app
    from jointfem.analysis.frf import solve_at
    from jointfem.harmonics import Harmonics
    from jointfem.rom import RomOptions, build_rom
    from jointfem.scene import create_structure, load_scene

    scene = app.override(load_scene(ROOT / scene_file), list(sets))
    t0 = time.perf_counter()
    structure = create_structure(scene)
    if matrices is not None:
        structure = _swap_matrices(structure, matrices)
    model = build_rom(structure, method, RomOptions(modes=modes)) if method != "full" else structure
    s = scene.solver
    h = Harmonics(s.harmonics, s.samples)
    grid = np.linspace(s.omega_start, s.omega_end, num)
    amps = {}
    iters = []
    for w in grid:  # each from the stuck linear solution (a fold lies inside lap2d's range at 3 N)
        sol = solve_at(model, float(w), h)
        iters.append(sol.iterations)
        for k, v in sol.amplitudes.items():
            amps.setdefault(k, []).append(v)
    t1 = time.perf_counter()
    out = {"scene": scene_file, "sets": list(sets), "method": method, "modes": modes, "dofs": structure.num_dofs,
           "pairs": structure.num_pairs, "harmonics": s.harmonics, "samples": s.samples,
           "grid": {"omega": grid.tolist(), "amplitude": amps, "iterations": iters},
           "matrices_from": str(matrices) if matrices is not None else None}
    if not sweep:
        return out | {"seconds": {"grid": t1 - t0}}
    # the arclength sweep over the first quarter of the range, as `jointfem frf` runs it
    quarter = s.omega_start + 0.25 * (s.omega_end - s.omega_start)
    short = app.override(scene, list(sets) + [f"solver.omega_range=[{s.omega_start!r}, {quarter!r}]"])
    sol = app.solve_scene(short, method=method, rom_options=RomOptions(modes=modes), stability="off")
    frf = sol.frf
    arc = {"omega": frf.omega.tolist(),
             "amplitude": {k: frf.amplitude(d).tolist() for k, d in frf.outputs.items()},
             "iterations": np.asarray(frf.iterations).tolist()}
    return out | {"sweep": arc, "seconds": {"grid": t1 - t0, "sweep": time.perf_counter() - t1}}


def _brb_modes(sets) -> dict:
    from jointfem import app
    from jointfem.linalg import backend, eigen
    from jointfem.scene import create_structure, load_scene

    t0 = time.perf_counter()
    scene = app.override(load_scene(ROOT / "demos" / "brb.toml"), list(sets))
    structure = create_structure(scene)
    w2, _ = eigen(structure.K_lin, structure.M, 10, what="BRB stuck modes")
    return {"scene": "demos/brb.toml", "sets": list(sets), "dofs": structure.num_dofs, "pairs": structure.num_pairs,
            "backend": backend(structure.num_dofs), "pairs_closed": structure.info.get("pairs_closed"),
            "frequency_hz": (np.sqrt(w2) / 2 / np.pi).tolist(), "seconds": time.perf_counter() - t0}


def run(out: Path, full_brb: bool) -> dict:
    t0 = time.perf_counter()
    data = {"stack": _stack(), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
    data["lap2d"] = _grid_and_sweep("demos/lap2d.toml", "exact", 0, 26)
    print(f"compare_stacks: lap2d done ({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    with tempfile.TemporaryDirectory() as tmp:  # the scene writes its mesh file: not into the repo
        data["lap3d"] = _grid_and_sweep(*LAP3D, [f"mesh.file='{tmp}/lap3d.msh'"])
    print(f"compare_stacks: lap3d done ({time.perf_counter() - t0:.0f} s)", file=sys.stderr, flush=True)
    data["brb"] = _brb_modes(BRB_QUICK)
    if full_brb:
        data["brb_full"] = _brb_modes([])
    data["seconds"] = time.perf_counter() - t0
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(data, indent=1))
    print(f"compare_stacks: wrote {out} ({data['seconds']:.0f} s)", file=sys.stderr)
    return data


def save_matrices(out: Path) -> None:
    """lap3d's assembled model on this stack, for ``swap`` on another."""
    from jointfem import app
    from jointfem.scene import create_structure, load_scene

    with tempfile.TemporaryDirectory() as tmp:
        scene = app.override(load_scene(ROOT / LAP3D[0]), [f"mesh.file='{tmp}/lap3d.msh'"])
        out.parent.mkdir(parents=True, exist_ok=True)
        _save_matrices(create_structure(scene), out)
    print(f"compare_stacks: wrote {out}", file=sys.stderr)


def swap(matrices: Path, out: Path) -> dict:
    """lap3d's grid on this stack with K, M and D assembled on another (``matrices``
    there): with the other stack's JSON, ``compare --only lap3d`` then says how much of the stacks'
    difference is the assembly (FFCx's kernels) and how much the rest (SLEPc, LAPACK, numpy, the HBM)."""
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        data = {"stack": _stack(), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
                "lap3d": _grid_and_sweep(*LAP3D, [f"mesh.file='{tmp}/lap3d.msh'"], matrices=matrices, sweep=False)}
    data["seconds"] = time.perf_counter() - t0
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(data, indent=1))
    print(f"compare_stacks: wrote {out} ({data['seconds']:.0f} s)", file=sys.stderr)
    return data


def compare(a: dict, b: dict, sweep_tol: float = SWEEP_TOL, modes_tol: float = MODES_TOL,
            only: tuple[str, ...] = ("lap2d", "lap3d", "brb", "brb_full")) -> tuple[list[str], bool]:
    """Lines of a report and whether every judged difference (of the cases in ``only``) is within its bound."""
    ok = True
    lines = [f"A: {a['stack']}", f"B: {b['stack']}"]
    for case in (c for c in ("lap2d", "lap3d") if c in only):
        if case not in a or case not in b:
            lines.append(f"{case}: missing in {'A' if case not in a else 'B'}")
            ok = False
            continue
        ga, gb = a[case]["grid"], b[case]["grid"]
        if ga["omega"] != gb["omega"] or a[case]["dofs"] != b[case]["dofs"]:
            lines.append(f"{case}: not the same problem (DOFs {a[case]['dofs']} / {b[case]['dofs']}, or the omegas)")
            ok = False
            continue
        for name in ga["amplitude"]:
            x, y = np.array(ga["amplitude"][name]), np.array(gb["amplitude"][name])
            d = float(np.abs(x - y).max() / np.abs(x).max())
            good = d <= sweep_tol
            ok &= good
            lines.append(f"{case} {name}: grid of {x.size} omegas, largest |A - B| / max|A| = {d:.2e} "
                         f"({'within' if good else 'OVER'} {sweep_tol:g}); peak on the grid {x.max():.6e} m")
        if "sweep" not in a[case] or "sweep" not in b[case]:
            continue
        sa, sb = a[case]["sweep"], b[case]["sweep"]
        n = min(len(sa["omega"]), len(sb["omega"]))
        dw = float(np.abs(np.array(sa["omega"][:n]) - np.array(sb["omega"][:n])).max()) if n else float("nan")
        lines.append(f"{case} arclength sweep: {len(sa['omega'])} / {len(sb['omega'])} points, same iterations: "
                     f"{sa['iterations'] == sb['iterations']}, largest omega difference of the first {n}: {dw:.2e} rad/s")
        for name in sa["amplitude"]:
            x, y = np.array(sa["amplitude"][name][:n]), np.array(sb["amplitude"][name][:n])
            lines.append(f"{case} arclength sweep {name}: largest |A - B| / max|A| = "
                         f"{float(np.abs(x - y).max() / np.abs(x).max()):.2e} (reported, not judged)")
    for case in (c for c in ("brb", "brb_full") if c in only):
        if case not in a or case not in b:
            if case == "brb":
                lines.append("brb: missing")
                ok = False
            continue
        fa, fb = np.array(a[case]["frequency_hz"]), np.array(b[case]["frequency_hz"])
        if fa.size != fb.size or a[case]["dofs"] != b[case]["dofs"]:
            lines.append(f"{case}: not the same problem (DOFs {a[case]['dofs']} / {b[case]['dofs']})")
            ok = False
            continue
        rel = np.abs(fa / fb - 1)
        elastic = rel[BRB_RIGID:]
        good = bool(elastic.max() <= modes_tol)
        ok &= good
        lines.append(f"{case}: {fa.size - BRB_RIGID} elastic frequencies ({fa[BRB_RIGID]:.3f} .. {fa[-1]:.3f} Hz, "
                     f"{a[case]['dofs']} DOFs, {a[case]['backend']}), largest |fA / fB - 1| = {elastic.max():.2e} "
                     f"({'within' if good else 'OVER'} {modes_tol:g}): " + " ".join(f"{r:.1e}" for r in elastic))
        lines.append(f"{case}: the {BRB_RIGID} rigid-body modes on the supports ({fa[0]:.3f} .. {fa[BRB_RIGID - 1]:.3f} Hz), "
                     f"largest |fA / fB - 1| = {rel[:BRB_RIGID].max():.2e} (reported, not judged: round-off in K "
                     f"alone moves them by up to 7e-7, see BRB_RIGID): " + " ".join(f"{r:.1e}" for r in rel[:BRB_RIGID]))
    return lines, ok


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="compute this stack's numbers")
    r.add_argument("--out", required=True, type=Path)
    r.add_argument("--full-brb", action="store_true", help="also the full BRB mesh (217 pairs; minutes)")
    m = sub.add_parser("matrices", help="write lap3d's K, M, D (and its gap rows and force) into a folder")
    m.add_argument("--out", required=True, type=Path)
    w = sub.add_parser("swap", help="lap3d's grid here with K, M, D from another stack's `matrices`")
    w.add_argument("--matrices", required=True, type=Path)
    w.add_argument("--out", required=True, type=Path)
    c = sub.add_parser("compare", help="compare two stacks' JSON files")
    c.add_argument("a", type=Path)
    c.add_argument("b", type=Path)
    c.add_argument("--sweep-tol", type=float, default=SWEEP_TOL)
    c.add_argument("--modes-tol", type=float, default=MODES_TOL)
    c.add_argument("--only", nargs="+", default=["lap2d", "lap3d", "brb", "brb_full"],
                   choices=["lap2d", "lap3d", "brb", "brb_full"], help="judge these cases only")
    args = ap.parse_args(argv)
    if args.cmd == "run":
        run(args.out, args.full_brb)
        return 0
    if args.cmd == "matrices":
        save_matrices(args.out)
        return 0
    if args.cmd == "swap":
        swap(args.matrices, args.out)
        return 0
    try:
        a, b = (json.loads(p.read_text()) for p in (args.a, args.b))
    except (OSError, ValueError) as exc:
        print(f"compare_stacks: cannot read the two JSON files: {exc}", file=sys.stderr)
        return 2
    lines, ok = compare(a, b, args.sweep_tol, args.modes_tol, tuple(args.only))
    print("\n".join(lines))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
