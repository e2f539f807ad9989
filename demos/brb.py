"""The Brake-Reuss beam swept (issue 16) -> docs/brb.md and docs/img/brb_*.png.

    python demos/brb.py --out docs              # make brb (about 9 min on 2 cores)
    python demos/brb.py --quick --out DIR       # the test's setting: a coarse mesh, about 2 min
    python demos/brb.py --measured LTW_Mode1Trimmed_27Sept2021.mat --out DIR   # beside measured data

demos/brb.toml: free-free on two soft supports, three bolts preloading the lap through a static
contact solve, 217 contact pairs.  In one run:

1. the static contact state: equilibrium, closed and open pairs, the pressure map;
2. the stuck modes (six rigid-body modes on the supports, then the first bending);
3. the mode-1 backbone (EPMC) with the penalty ROM, solved again by the exact condensation at
   chosen amplitudes, from the ROM's solution there;
4. the forced response at three force levels with the penalty ROM, and at each the exact
   condensation's peak, located by a bounded search on omega (each value a solved point);
5. the middle level's peak at H = 3 and H = 5;
6. the model beside the published data (cited in the text), with what it can and cannot show.
Pictures: the pressure map, the contact states and the deformed shape at each level's peak, the
backbone beside Porter & Brake's simulated one.

Every number is computed here, in one run.  The published data it stands beside (docs/brb.md)
are cited there; nothing is fitted to them.  ``--measured`` puts a measured mode-1 backbone beside
the model (table and plot): the file Porter & Brake's code reads (tmd-lab/microslip-rough-contact,
README: EXPERIMENTAL_DATA/LTW_Mode1Trimmed_27Sept2021.mat, downloaded from Rice University's Box,
not in that repository; its struct BB with Qaccel [m/s^2], Wmean [Hz] and Zmean [fraction of
critical], as its scripts PLOTS/elastic_bb.m and EXPERIMENTAL_DATA/ltw_trim_bb.m read them), or a
CSV with the columns accel_m_s2, freq_Hz, zeta.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from jointfem import app  # noqa: E402
from jointfem.analysis.nma import compute_backbone, modal_problem  # noqa: E402
from jointfem.analysis.peaks import output_amplitude  # noqa: E402
from jointfem.continuation.arclength import ConvergenceError, NewtonOptions, solve_newton  # noqa: E402
from jointfem.contact.jenkins import SEPARATED, SLIP  # noqa: E402
from jointfem.hbm.condensed import CondensedProblem  # noqa: E402
from jointfem.hbm.problem import newton_system  # noqa: E402
from jointfem.linalg import eigen  # noqa: E402
from jointfem.rom import RomOptions, build_rom  # noqa: E402
from jointfem.scene import create_structure, load_scene  # noqa: E402

SCENE = ROOT / "demos" / "brb.toml"
OUTPUT = "tip.uy"
MODE = 7  # the first bending: modes 1-6 are the rigid-body modes on the supports
ROM = RomOptions(modes=12)  # the 6 rigid-body modes and the first 6 elastic ones
LEVELS = (0.02, 0.5, 5.0)  # N at the shaker
AMPLITUDES = (1e-6, 1e-5, 5e-5)  # m at the tip, where the backbone is solved exactly too
QUICK = ["mesh.size=0.0254", "mesh.size_normal=0.0127", "solver.omega_range=[1060.0, 1160.0]"]  # 33 pairs,
# 2790 DOFs, mode 1 at 181 Hz (a coarser mesh of the lap: stiffer)

# Porter & Brake, MSSP 192 (2023) 110210: their simulated mode-1 backbone of the BRB with a flat
# interface (rough-contact model, not a measurement), from tmdsimpy's
# examples/structures/results/brb_epmc_flat.yaml (MIT): acceleration amplitude (m/s^2),
# frequency (rad/s), damping ratio; every third row, and the row at 13.1 m/s^2.
P23_FLAT = np.array([
    [1.091128e-01, 1058.7313, 8.7277e-04], [1.960770e-01, 1058.7234, 8.8128e-04],
    [5.207401e-01, 1058.6429, 9.2879e-04], [1.382239e+00, 1058.2881, 1.1480e-03],
    [3.658748e+00, 1056.5337, 2.1137e-03], [9.562898e+00, 1048.7789, 6.1510e-03],
    [1.310783e+01, 1043.9292, 7.9000e-03],
    [2.438184e+01, 1030.6579, 1.2197e-02], [5.415628e+01, 996.9370, 2.6307e-02],
    [6.531470e+01, 984.4111, 3.0630e-02]])


def md_table(header, rows) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def commit() -> str:
    try:
        rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                             check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                               capture_output=True, text=True).stdout.strip()
        return rev + ("-dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def gaps_of(rom, U_rom: np.ndarray, exact: CondensedProblem, nh: int) -> np.ndarray:
    """The exact condensation's coefficients (retained coordinates y = C u, per harmonic) of a
    ROM solution U_rom (ROM coordinates per harmonic): its guess from the ROM."""
    q = rom.T.shape[1]
    u = (rom.T @ U_rom.reshape(nh, q).T)  # (n, nh)
    return (exact.C @ u).T.ravel()


# ---- 1. the static state -------------------------------------------------------------------

def static_state(lines, scene, structure, img: Path):
    info = structure.info
    g = structure.contacts[0]
    N0, area = g.pairs.N0, g.areas
    closed = N0 > 0
    bolts = scene.model.bolts
    total = sum(b.force for b in bolts)
    eq = abs(N0[closed].sum() - total) / total
    lines += ["## 1. The static contact state", "",
              f"{structure.num_dofs} DOFs, {structure.num_pairs} node-to-node pairs over the "
              f"{info['contact_area_m2'] * 1e4:.2f} cm^2 lap, three bolts of "
              f"{', '.join(f'{b.force:g}' for b in bolts)} N on {bolts[0].radius * 2e3:g} mm washers; "
              f"kn = {scene.model.kn:g} N/m^3, no friction in the static solve beyond the stuck tangential "
              f"springs (the loading path: the bolts tighten together and nothing slips).", "",
              md_table(["quantity", "value"], [
                  ["pairs closed / open", f"{int(closed.sum())} / {int((~closed).sum())}"],
                  ["closed area", f"{area[closed].sum() * 1e4:.3f} cm^2 of {area.sum() * 1e4:.3f}"],
                  ["sum of N0 against the bolt forces (relative)", f"{eq:.1e}"],
                  ["peak pressure (N0 over nodal area)", f"{(N0 / area).max() / 1e6:.1f} MPa"],
                  ["mean pressure over the closed area", f"{N0[closed].sum() / area[closed].sum() / 1e6:.1f} MPa"],
                  ["largest static gap of an open pair", f"{info['largest_static_gap_m'] * 1e6:.2f} um"],
                  ["active-set iterations", f"{info['static_iterations']}"],
                  ["largest static abs(f_t) / (mu N0)", f"{info['static_tangential_use_max']:.3g}"],
              ]), "",
              "The static tangential forces are not carried into the dynamics (each slider starts unloaded); "
              "the last row says how far the stuck loading path leaves some pairs beyond their friction limit "
              "(those at the rim of the contact, where N0 falls to zero).", ""]
    plt = pyplot()
    xy = structure.pair_coords
    fig, ax = plt.subplots(figsize=(9, 2.6))
    sc = ax.scatter(xy[closed, 0] * 1e3, xy[closed, 2] * 1e3, c=(N0 / area)[closed] / 1e6, cmap="viridis", s=40)
    ax.scatter(xy[~closed, 0] * 1e3, xy[~closed, 2] * 1e3, marker="x", c="0.5", s=25, label="open")
    for b in bolts:
        ax.add_patch(plt.Circle((b.x * 1e3, b.z * 1e3), b.radius * 1e3, fill=False, ls="--", color="k"))
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("z [mm]")
    fig.colorbar(sc, ax=ax, label="contact pressure [MPa]")
    ax.legend(loc="upper right", fontsize=7)
    ax.set_title("BRB: static contact pressure (dashed: washers)", fontsize=9)
    fig.tight_layout()
    fig.savefig(img / "brb_pressure.png", dpi=130)
    plt.close(fig)
    lines += ["![pressure](img/brb_pressure.png)", ""]
    return eq


def pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


# ---- 2. the stuck modes --------------------------------------------------------------------

def stuck_modes(lines, structure):
    w2, Phi = eigen(structure.K_lin, structure.M, 10, what="BRB stuck modes")
    comp = np.array([n.rsplit(".", 1)[1] for n in structure.dof_names])
    rows = []
    for j in range(10):
        e = {c: float((Phi[comp == c, j] ** 2).sum()) for c in ("ux", "uy", "uz")}
        rows.append([j + 1, f"{np.sqrt(w2[j]) / 2 / np.pi:.3f}", max(e, key=e.get),
                     "rigid body on the supports" if j < 6 else ("first bending across the joint (mode 1 of the "
                                                                  "literature)" if j == MODE - 1 else "")])
    f1 = np.sqrt(w2[MODE - 1]) / 2 / np.pi
    lines += ["## 2. Stuck modes", "",
              "Every closed pair stuck (its kt, kn), the open ones without springs, the supports' springs:", "",
              md_table(["mode", "f [Hz]", "dominant", ""], rows), ""]
    return f1, float(np.sqrt(w2[5]) / 2 / np.pi)


# ---- 3. the backbone -----------------------------------------------------------------------

def backbone(lines, scene, structure, amplitudes, img: Path, measured: dict | None = None):
    opts = dataclasses.replace(app.nma_options(scene, mode=MODE), at=tuple(amplitudes))
    t0 = time.perf_counter()
    rom = build_rom(structure, "penalty", ROM)
    t_off = time.perf_counter() - t0
    t0 = time.perf_counter()
    bb = compute_backbone(rom, opts)
    t_rom = time.perf_counter() - t0
    h = opts.harmonics
    exact = CondensedProblem(structure, h)
    mp = modal_problem(exact, MODE, OUTPUT, excitation=opts.excitation)
    rows, errs = [], []
    for a in amplitudes:
        if a not in bb.info["at"]:
            raise RuntimeError(f"the penalty ROM's backbone did not reach {a:g} m")
        r = bb.info["at"][a]
        k = int(np.argmin(np.abs(np.log(bb.amplitude / a))))  # the nearest point: the exact's guess
        x = np.zeros(mp.num_coefficients)
        x[:mp.nc] = gaps_of(rom, bb.U[k] / bb.amplitude[k], exact, h.num_hc)
        x[mp.nc], x[mp.nc + 1] = bb.omega[k], bb.xi[k]
        lam = float(np.log10(a))
        sc = mp.scales(lam, lam + 0.1)
        t0 = time.perf_counter()
        # 1e-7: the condensed EPMC's residual stalls between 1e-8 and 4e-8 on the 217 pairs (its S = R^-1 on
        # 651 gaps carries that round-off); 1e-7 of the residual moves omega and zeta by far less than the
        # ROM's errors below
        x, it = solve_newton(newton_system(mp), x, lam, x_scale=sc.x, r_scale=sc.r,
                             options=NewtonOptions(tol=max(1e-7, mp.tol_floor), max_iter=15))
        t_ex = time.perf_counter() - t0
        w, xi = float(x[mp.nc]), float(x[mp.nc + 1])
        z = xi / (2 * w)
        ew, ez = r["omega_rad_s"] / w - 1, r["zeta"] / z - 1
        errs.append((abs(ew), abs(ez)))
        rows.append([f"{a:g}", f"{a * w * w:.2f}", f"{r['omega_rad_s'] / 2 / np.pi:.4f}", f"{w / 2 / np.pi:.4f}",
                     f"{ew:+.1e}", f"{100 * r['zeta']:.4f}", f"{100 * z:.4f}", f"{ez:+.1e}", f"{it}", f"{t_ex:.0f}"])
        print(f"brb: backbone at {a:g} m: ROM {r['omega_rad_s']:.4f} rad/s zeta {r['zeta']:.5f}, exact {w:.4f}, "
              f"{z:.5f} ({it} iterations, {t_ex:.0f} s)", file=sys.stderr, flush=True)
    acc = bb.amplitude * bb.omega ** 2
    sizes = bb.info["arrays"]["rom_size"]
    lines += ["## 3. Mode 1 backbone (EPMC)", "",
              f"Penalty ROM ({ROM.modes} modes, no TVD: {sizes.min()} to {sizes.max()} ROM coordinates, "
              f"{bb.info['num_unknowns']} unknowns at most), H = {h.H}, N = {h.N}, from "
              f"{bb.amplitude[0]:g} to {bb.amplitude[-1]:.3g} m at the tip ({bb.num_points} points, offline "
              f"{t_off:.1f} s, online {t_rom:.1f} s).  Linear: {bb.info['linear_omega_rad_s'] / 2 / np.pi:.3f} Hz, "
              f"zeta {100 * bb.info['linear_zeta']:.4f} %.  At the amplitudes below each is solved exactly: the ROM "
              f"by Newton from its nearest point, the exact condensation ({exact.num_unknowns + 2} unknowns) by "
              f"Newton from the ROM's solution mapped to the gaps.", "",
              md_table(["tip amp [m]", "tip accel [m/s^2]", "f ROM [Hz]", "f exact [Hz]", "rel err", "zeta ROM [%]",
                        "zeta exact [%]", "rel err", "exact iterations", "exact s"], rows), "",
              f"Along the ROM's branch: frequency {bb.omega[0] / 2 / np.pi:.3f} to {bb.omega[-1] / 2 / np.pi:.3f} Hz "
              f"({bb.omega[-1] / bb.omega[0] - 1:+.2%}), damping {100 * bb.zeta[0]:.3f} to {100 * bb.zeta[-1]:.3f} %, "
              f"tip acceleration {acc[0]:.3g} to {acc[-1]:.3g} m/s^2.  The harmonic truncation estimate reaches "
              f"{bb.info['arrays']['harmonic_error'].max():.2f} (section 5).", ""]
    plt = pyplot()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.8))
    a1.semilogx(acc, bb.omega / 2 / np.pi, "o-", ms=3, label="jointfem, penalty ROM")
    a2.loglog(acc, 100 * bb.zeta, "o-", ms=3, label="jointfem, penalty ROM")
    ex = [(float(r[1]), float(r[3]), float(r[6])) for r in rows]
    a1.semilogx([e[0] for e in ex], [e[1] for e in ex], "ks", mfc="none", ms=8, label="jointfem, exact condensation")
    a2.loglog([e[0] for e in ex], [e[2] for e in ex], "ks", mfc="none", ms=8, label="jointfem, exact condensation")
    a1.semilogx(P23_FLAT[:, 0], P23_FLAT[:, 1] / 2 / np.pi, "--", c="C3", label="Porter & Brake 2023, simulated (flat)")
    a2.loglog(P23_FLAT[:, 0], 100 * P23_FLAT[:, 2], "--", c="C3", label="Porter & Brake 2023, simulated (flat)")
    if measured is None:
        a1.axhspan(175.5, 180.0, color="0.85", label="measured range (axes of P23's figure)")
    else:
        name = Path(measured["source"]).name
        a1.semilogx(measured["accel"], measured["freq_Hz"], "x", c="k", ms=4, label=f"measured ({name})")
        a2.loglog(measured["accel"], 100 * measured["zeta"], "x", c="k", ms=4, label=f"measured ({name})")
    for ax, yl in ((a1, "frequency [Hz]"), (a2, "damping ratio [%]")):
        ax.set_xlabel("tip acceleration amplitude [m/s^2]")
        ax.set_ylabel(yl)
        ax.grid(True, which="both", alpha=0.3)
    a1.legend(fontsize=7)
    fig.suptitle("BRB mode 1 backbone", fontsize=10)
    fig.tight_layout()
    fig.savefig(img / "brb_backbone.png", dpi=130)
    plt.close(fig)
    lines += ["![backbone](img/brb_backbone.png)", ""]
    return bb, errs, t_off, t_rom


# ---- a measured backbone (--measured) -------------------------------------------------------

MEASURED_FIELDS = ("Qaccel", "Wmean", "Zmean")  # BB's fields: m/s^2, Hz, fraction of critical
MEASURED_COLUMNS = ("accel_m_s2", "freq_Hz", "zeta")


class MeasuredDataError(ValueError):
    """A measured backbone file that cannot be used, with the file, the key and the value."""


def load_measured(path: Path) -> dict:
    """{"accel", "freq_Hz", "zeta"} (sorted by acceleration) from a .mat file's struct BB (fields
    MEASURED_FIELDS) or a CSV (columns MEASURED_COLUMNS); MeasuredDataError naming the file, the key
    and the value where it cannot be used.  Called before any model is built."""
    path = Path(path)
    if not path.is_file():
        raise MeasuredDataError(f"{path}: no such file")
    if path.suffix.lower() == ".mat":
        import scipy.io

        try:
            data = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)
        except NotImplementedError as exc:  # MATLAB v7.3 (HDF5)
            raise MeasuredDataError(f"{path}: a MATLAB v7.3 file, which scipy cannot read: save BB with "
                                    f"save(file, 'BB', '-v7')") from exc
        except Exception as exc:
            raise MeasuredDataError(f"{path}: not a MATLAB file scipy can read ({exc})") from exc
        if "BB" not in data:
            raise MeasuredDataError(f"{path}: no variable BB (found: {', '.join(k for k in data if not k.startswith('__'))})")
        bb = data["BB"]
        fields = bb.__dict__ if isinstance(bb, scipy.io.matlab.mat_struct) else {}
        cols = []
        for key in MEASURED_FIELDS:
            if key not in fields:
                raise MeasuredDataError(f"{path}: BB has no field {key} (BB is {type(bb).__name__}"
                                        f"{' with ' + ', '.join(k for k in fields if k != '_fieldnames') if fields else ''})")
            cols.append(np.atleast_1d(np.asarray(fields[key], dtype=float)).ravel())
        keys = [f"BB.{k}" for k in MEASURED_FIELDS]
    else:
        import csv

        with open(path, newline="") as fh:
            rows = list(csv.DictReader(fh))
        missing = [k for k in MEASURED_COLUMNS if not rows or k not in rows[0]]
        if missing:
            raise MeasuredDataError(f"{path}: column {missing[0]} missing (expected {', '.join(MEASURED_COLUMNS)})")
        cols = []
        for key in MEASURED_COLUMNS:
            try:
                cols.append(np.array([float(r[key]) for r in rows]))
            except ValueError as exc:
                raise MeasuredDataError(f"{path}: column {key}: {exc}") from exc
        keys = list(MEASURED_COLUMNS)
    if len({c.size for c in cols}) != 1 or cols[0].size < 2:
        raise MeasuredDataError(f"{path}: {', '.join(keys)} must have the same length, at least 2 "
                                f"(lengths {', '.join(str(c.size) for c in cols)})")
    for key, c in zip(keys, cols):
        bad = ~np.isfinite(c) | (c <= 0)
        if bad.any():
            raise MeasuredDataError(f"{path}: {key}[{int(np.argmax(bad))}] = {c[bad][0]!r}: must be finite and positive")
    order = np.argsort(cols[0])
    return {"accel": cols[0][order], "freq_Hz": cols[1][order], "zeta": cols[2][order], "source": str(path)}


# ---- 4. the forced response ----------------------------------------------------------------

def exact_peak(structure, frf, rom, peak, h, rel=0.004):
    """The exact condensation's largest tip amplitude near the ROM's peak: Brent's bounded search on
    omega, every value a Newton solution (started as ``guesses`` says).  Returns (omega, amplitude,
    exact amplitude at the ROM's peak omega, solves, seconds)."""
    from scipy.optimize import minimize_scalar

    t0 = time.perf_counter()
    problem = CondensedProblem(structure, h)
    sc = problem.scales(peak.omega * (1 - rel), peak.omega * (1 + rel))
    opts = NewtonOptions(tol=max(1e-10, problem.tol_floor), max_iter=30)
    out = problem.layout.outputs[OUTPUT]
    solved = {}  # omega -> x

    def guesses(w):
        """Newton's starts at w, best first: the nearest exact solution, the ROM's nearest point
        mapped to the gaps, the stuck linear response (a kink between w and a start can stall
        Newton from it)."""
        if solved:
            yield solved[min(solved, key=lambda v: abs(v - w))]
        k = int(np.argmin(np.abs(frf.omega - w)))
        yield gaps_of(rom, frf.U[k], problem, h.num_hc)
        yield problem.initial_guess(w)

    def neg_amp(w):
        last = None
        for x0 in guesses(w):
            try:
                x, _ = solve_newton(newton_system(problem), x0, float(w), x_scale=sc.x, r_scale=sc.r, options=opts)
                break
            except ConvergenceError as exc:
                last = exc
        else:
            raise last
        solved[float(w)] = x
        return -output_amplitude(x, out, h)

    at_rom = -neg_amp(peak.omega)  # the exact amplitude at the ROM's peak frequency
    lo, hi = peak.omega * (1 - rel), peak.omega * (1 + rel)
    for _ in range(4):  # a peak found at an end of the window: the window moves on, centred there
        res = minimize_scalar(neg_amp, bounds=(lo, hi), method="bounded", options={"xatol": 1e-3})
        if min(res.x - lo, hi - res.x) > 0.05 * (hi - lo):
            return float(res.x), float(-res.fun), at_rom, len(solved), time.perf_counter() - t0
        lo, hi = res.x - 0.5 * (hi - lo), res.x + 0.5 * (hi - lo)
    raise RuntimeError(f"the exact peak near {peak.omega:.4f} rad/s lies beyond {lo:.4f} .. {hi:.4f} rad/s")


def forced(lines, scene, work: Path, levels, img: Path, sets=()):
    rows, pics, errs, curves = [], [], [], []
    for F in levels:
        sc_F = app.override(scene, list(sets) + [f"force.amplitude={F}"])
        t0 = time.perf_counter()
        sol = app.solve_scene(sc_F, method="penalty", rom_options=ROM, stability="off")
        t_rom = time.perf_counter() - t0
        frf = sol.frf
        curves.append((F, frf))
        folder = work / f"frf_{F:g}N"
        app.write_frf(sol, sc_F, folder, method="penalty", rom_options=ROM, plots=True)
        peak = frf.info["peaks"][OUTPUT]
        w_ex, a_ex, a_same, n_ex, t_ex = exact_peak(sol.structure, frf, sol.rom, peak, frf.harmonics)
        ew, ea, es = peak.omega / w_ex - 1, peak.amplitude / a_ex - 1, peak.amplitude / a_same - 1
        errs.append((abs(ew), abs(ea), abs(es)))
        k = int(np.argmin(np.abs(frf.omega - peak.omega)))
        closed = sol.structure.contacts[0].pairs.N0 > 0
        st = frf.states[k][:, closed]
        slip = float(np.mean(np.any(st == SLIP, axis=0)))
        sep = float(np.mean(np.any(st == SEPARATED, axis=0)))
        sizes = frf.info["arrays"]["rom_size"]
        rows.append([f"{F:g}", f"{peak.omega / 2 / np.pi:.4f}", f"{peak.amplitude:.4e}", f"{w_ex / 2 / np.pi:.4f}",
                     f"{a_ex:.4e}", f"{ew:+.1e}", f"{ea:+.1e}", f"{es:+.1e}", f"{peak.amplitude * peak.omega ** 2:.2f}",
                     f"{100 * slip:.0f} / {100 * sep:.0f}", f"{sizes.min()}-{sizes.max()}", f"{frf.num_points}",
                     f"{t_rom:.0f}", f"{n_ex}", f"{t_ex:.0f}"])
        print(f"brb: {F:g} N: ROM peak {peak.omega:.4f} rad/s {peak.amplitude:.5e} m; exact {w_ex:.4f} {a_ex:.5e} "
              f"({n_ex} solves, {t_ex:.0f} s)", file=sys.stderr, flush=True)
        for name in ("interface", "shape"):
            for p in sorted(folder.glob(f"{name}_*.png")):
                dst = img / f"brb_{name}_{F:g}N.png"
                shutil.copyfile(p, dst)
                pics.append((F, name, dst.name))
    lines += ["## 4. Forced response at three levels", "",
              f"The shaker's force at x = 0.24 m (cosine, N), the tip's first-harmonic amplitude. Penalty ROM "
              f"({ROM.modes} modes) swept over the scene's range; its peak located to the solver's tolerance. The "
              f"exact condensation's peak: Brent's bounded search on omega within 0.4 % of the ROM's (to 1e-3 rad/s), "
              f"every value a Newton solution; and the exact amplitude at the ROM's peak frequency.  A share of pairs is of "
              f"those closed at rest that slip (or separate) at some sample of the period.", "",
              md_table(["F [N]", "ROM peak [Hz]", "ROM amp [m]", "exact peak [Hz]", "exact amp [m]", "err f", "err amp",
                        "err amp at the ROM's peak f", "tip accel [m/s^2]",
                        "closed pairs slipping / separating at the peak [%]", "ROM size", "points",
                        "ROM sweep s", "exact solves", "exact s"], rows), "",
              "![levels](img/brb_levels.png)", ""]
    for F in levels:
        mine = [p for p in pics if p[0] == F]
        if mine:
            lines += [f"At {F:g} N, at the peak: " + ", ".join(f"![{n}](img/{f})" for _, n, f in mine), ""]
    plot_levels(curves, img)
    return rows, errs


def plot_levels(curves, img: Path):
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    for F, frf in curves:
        ax.plot(frf.omega / 2 / np.pi, frf.amplitude(frf.outputs[OUTPUT]) / F, label=f"{F:g} N")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("tip amplitude / force [m/N]")
    ax.set_yscale("log")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("BRB: receptance of the tip at three force levels (penalty ROM)", fontsize=9)
    fig.tight_layout()
    fig.savefig(img / "brb_levels.png", dpi=130)
    plt.close(fig)


# ---- 5. harmonics, and the published data ------------------------------------------------

def harmonics_check(lines, scene, sets, F):
    """The middle level's peak at H = 3 and H = 5 (the penalty ROM): what truncation costs."""
    rows, peaks = [], []
    for H in (3, 5):
        sc = app.override(scene, list(sets) + [f"force.amplitude={F}", f"solver.harmonics={H}"])
        t0 = time.perf_counter()
        sol = app.solve_scene(sc, method="penalty", rom_options=ROM, stability="off")
        pk = sol.frf.info["peaks"][OUTPUT]
        peaks.append(pk)
        he = sol.frf.info["arrays"]["harmonic_error"]
        rows.append([H, sol.frf.harmonics.N, f"{pk.omega / 2 / np.pi:.4f}", f"{pk.amplitude:.5e}", f"{he.max():.3f}",
                     f"{time.perf_counter() - t0:.0f}"])
    dw, da = peaks[0].omega / peaks[1].omega - 1, peaks[0].amplitude / peaks[1].amplitude - 1
    lines += ["## 5. Harmonic truncation", "",
              f"The {F:g} N level's peak with the penalty ROM at H = 3 (the scene's) and H = 5:", "",
              md_table(["H", "N", "peak [Hz]", "tip amp [m]", "truncation estimate, largest", "s"], rows), "",
              f"H = 3 against H = 5: frequency {dw:+.1e}, amplitude {da:+.1e}.  The truncation estimate is the "
              f"contact forces' share in the top two harmonics, summed over the pairs (analysis.convergence); "
              f"sections 3 and 4 are at H = 3, so their ROM errors are measured against the exact condensation "
              f"at the same H, and their distance from the converged response is of the order of this change.", ""]
    return dw, da


def published(lines, bb, f1, measured: dict | None = None):
    """The model beside the published BRB data (typed here with their sources; nothing fitted), and
    beside a measured backbone where one is given (``load_measured``)."""
    acc = bb.amplitude * bb.omega ** 2
    f = bb.omega / 2 / np.pi

    def at(a, y, x=acc):
        return float(np.interp(np.log(a), np.log(x), y)) if x[0] <= a <= x[-1] else float("nan")
    p_acc, p_f, p_z = P23_FLAT[:, 0], P23_FLAT[:, 1] / 2 / np.pi, P23_FLAT[:, 2]
    if measured is not None:
        measured_section(lines, acc, f, bb.zeta, measured)
        return
    rows = [["low-amplitude mode 1 frequency [Hz]", "175.5 - 180 (the frequency axis of P23's plot of the "
             "measured backbone; the data were not reachable)", "168.50 (P23, flat interface), 180.63 (P23, "
             "measured mesoscale topology)", f"{f1:.2f} stuck; {f[0]:.2f} at {acc[0]:.2g} m/s^2"],
            ["low-amplitude damping ratio [%]", "0.087 (tmdsimpy's BRB example, \"taken from experiments\")",
             "0.087 (the same value, put in as modal damping)", f"{100 * bb.info['linear_zeta']:.3f} linear; "
             f"{100 * bb.zeta[0]:.3f} at {acc[0]:.2g} m/s^2"],
            ["frequency change from the lowest amplitude to 13 m/s^2 (the top of the trimmed measurements)",
             "within the 175.5 - 180 Hz axis (at most -2.5 %)", f"{at(13.0, p_f, p_acc) / p_f[0] - 1:+.2%} (P23, flat)",
             f"{at(13.0, f) / f[0] - 1:+.2%}"],
            ["damping ratio at 13 m/s^2 [%]", "below about 1 (the damping axis of P23's plot runs to 1 %)",
             f"{100 * at(13.0, p_z, p_acc):.2f} (P23, flat)", f"{100 * at(13.0, bb.zeta):.3f}"]]
    lines += ["## 6. Beside the published data", "",
              "Sources: [P23] J.H. Porter, M.R.W. Brake, Towards a predictive, physics-based friction model for "
              "the dynamics of jointed structures, MSSP 192 (2023) 110210, doi:10.1016/j.ymssp.2023.110210, and its "
              "code (tmd-lab/microslip-rough-contact; tmd-lab/tmdsimpy examples/structures, MIT), which give the "
              "bolt preloads used here, the low-amplitude damping and their simulated backbones; [B21] N.N. Balaji, "
              "T. Dreher, M. Krack, M.R.W. Brake, Reduced order modeling for the dynamics of jointed structures "
              "through hyper-reduced interface representation, MSSP 149 (2021) 107249, "
              "doi:10.1016/j.ymssp.2020.107249, for mu = 0.2 and the order of the contact stiffness.  The "
              "acceleration amplitude is the tip's, as in P23's plots.", "",
              md_table(["quantity", "measured (published)", "simulated by others", "this model (sections 2, 3)"], rows),
              "",
              f"What this can and cannot show.  The measured backbone of P23 (their figure of mode 1, from Rice "
              f"University's tests) was not reachable as numbers: only the ranges of its plot's axes are known "
              f"to us, and they are marked as such.  Porter & Brake's code reads those data from EXPERIMENTAL_DATA/LTW_Mode1Trimmed_27Sept2021.mat (tmd-lab/microslip-rough-contact's README: a download from Rice University's Box, not in the repository); with that file, `python demos/brb.py --measured LTW_Mode1Trimmed_27Sept2021.mat` puts it beside the model point by point.  The comparison is therefore one of orders: the model's "
              f"low-amplitude frequency, {f[0]:.1f} Hz, lies {f[0] / 177.75 - 1:+.1%} from the middle of the "
              f"measured band and {f[0] / 168.50 - 1:+.1%} from P23's flat-interface model; its damping starts at "
              f"{100 * bb.zeta[0]:.3f} % (the measured 0.087 % is put in, not predicted) and reaches "
              f"{100 * at(13.0, bb.zeta):.2f} % at 13 m/s^2, where P23's flat model reaches "
              f"{100 * at(13.0, p_z, p_acc):.2f} %.  The friction coefficient (mu = 0.2, B21's Jenkins value, which "
              f"they mark unknown) and the contact stiffness (1e13 N/m^3, B21's order) are inputs, not fitted; P23 "
              f"use a rough-contact law with plasticity and mu = 0.03 on a measured surface, which a Jenkins "
              f"element with a uniform mu does not represent.  "
              "The stuck frequency depends on the mesh by a few per cent (docs/benchmarks_preload.md, make "
              "bench-preload), more than the penalty ROM's error against the exact condensation "
              "(sections 3 and 4): the mesh, not the reduction, limits this comparison.  The bolts' own mass and "
              "stiffness and the holes are not modelled, nor is the interface's initial topology: the scene can "
              "take one ([contact.gap], a crown or a measured table), but P23's measured surface is not in hand.", "",
              "A measured data set that is reachable but does not fit: mattiacenedese/BRBtesting (GPL-3.0; Chen et "
              "al., MSSP 166 (2022) 108401) holds stepped-sine responses of a free-free Brake-Reuss beam at 4 force "
              "and 8 response levels, and hammer impacts.  Its impacts put the first two modes at 80.5 and 297.7 Hz "
              "(this model's: about 171 and 225 Hz, their ratio 1.3 against 3.7), so that beam's geometry or "
              "suspension is not this scene's, and it is not compared here.", ""]


def measured_section(lines, acc, f, zeta, m: dict) -> None:
    """Section 6 with a measured backbone: the model's at the measured accelerations (log-interpolated
    along its branch; only where the branch covers them), with the differences."""
    ma, mf, mz = m["accel"], m["freq_Hz"], m["zeta"]
    inside = np.flatnonzero((ma >= acc[0]) & (ma <= acc[-1]))
    pick = inside[np.unique(np.linspace(0, inside.size - 1, min(12, inside.size)).round().astype(int))] \
        if inside.size else inside
    rows = []
    for i in pick:
        fm = float(np.interp(np.log(ma[i]), np.log(acc), f))
        zm = float(np.interp(np.log(ma[i]), np.log(acc), zeta))
        rows.append([f"{ma[i]:.3g}", f"{mf[i]:.3f}", f"{fm:.3f}", f"{fm / mf[i] - 1:+.2%}", f"{100 * mz[i]:.4f}",
                     f"{100 * zm:.4f}", f"{zm / mz[i]:.2f}"])
    name = Path(m["source"]).name
    lines += ["## 6. Beside the measured backbone", "",
              f"Measured: {name} ({ma.size} points, tip acceleration {ma[0]:.3g} to {ma[-1]:.3g} m/s^2, frequency "
              f"{mf.min():.2f} to {mf.max():.2f} Hz, damping ratio {100 * mz.min():.3f} to {100 * mz.max():.3f} %), "
              f"read by `demos/brb.py --measured` (the fields of Porter & Brake's BB struct, or a CSV).  The model's "
              f"branch covers {acc[0]:.3g} to {acc[-1]:.3g} m/s^2: {inside.size} of the measured points lie in it, "
              f"{len(rows)} of them below.  Nothing is fitted: mu and the contact stiffness are the scene's inputs.", ""]
    if rows:
        lines += [md_table(["tip accel [m/s^2]", "f measured [Hz]", "f model [Hz]", "f model / measured - 1",
                            "zeta measured [%]", "zeta model [%]", "zeta model / measured"], rows), ""]
    else:
        lines += ["No measured point lies within the model's branch: nothing to compare.", ""]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs")
    ap.add_argument("--work", default=None, help="result folders of the sweeps (default results/brb)")
    ap.add_argument("--quick", action="store_true", help="a coarse mesh (33 pairs): the test's setting")
    ap.add_argument("--measured", default=None,
                    help="a measured mode-1 backbone to stand beside the model: a .mat with struct BB (Qaccel m/s^2, "
                         "Wmean Hz, Zmean fraction of critical) or a CSV (accel_m_s2, freq_Hz, zeta)")
    args = ap.parse_args(argv)
    try:
        measured = None if args.measured is None else load_measured(Path(args.measured))
    except MeasuredDataError as exc:  # before any model is built
        print(f"brb: error: {exc}", file=sys.stderr)
        return 2
    t_start = time.perf_counter()
    out = Path(args.out)
    img = out / "img"
    img.mkdir(parents=True, exist_ok=True)
    work = Path(args.work or ROOT / "results" / "brb")
    work.mkdir(parents=True, exist_ok=True)
    sets = QUICK if args.quick else []
    scene = app.override(load_scene(SCENE), sets)
    t0 = time.perf_counter()
    structure = create_structure(scene)
    t_build = time.perf_counter() - t0
    cmd = "`python demos/brb.py --quick`" if args.quick else "`python demos/brb.py --out docs` (`make brb`)"
    if measured is not None:
        cmd = cmd.replace("`python demos/brb.py", f"`python demos/brb.py --measured {args.measured}")
    lines = ["# The Brake-Reuss beam, swept", "",
             f"Generated by {cmd} at commit {commit()} on {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} "
             f"({platform.machine()}, 2 cores); every number below comes from that one run.  Scene "
             f"demos/brb.toml{' with ' + ', '.join(sets) if sets else ''}: its comments give the source of each "
             f"input.  Model build (mesh, assembly, static preload): {t_build:.1f} s.", ""]
    eq = static_state(lines, scene, structure, img)
    f1, f_rb = stuck_modes(lines, structure)
    print(f"brb: {structure.num_pairs} pairs, equilibrium {eq:.1e}, mode 1 stuck {f1:.3f} Hz", file=sys.stderr,
          flush=True)
    bb, bb_errs, _, _ = backbone(lines, scene, structure, (3e-5, 1e-4) if args.quick else AMPLITUDES, img, measured)
    rows, frf_errs = forced(lines, scene, work, LEVELS, img, sets)
    dw, da = harmonics_check(lines, scene, sets, LEVELS[1])
    published(lines, bb, f1, measured)
    summary = {"pairs": structure.num_pairs, "dofs": structure.num_dofs, "equilibrium_rel": eq,
               "stuck_mode1_Hz": f1, "highest_rigid_Hz": f_rb,
               "backbone_err_omega_max": max(e[0] for e in bb_errs), "backbone_err_zeta_max": max(e[1] for e in bb_errs),
               "frf_err_omega_max": max(e[0] for e in frf_errs), "frf_err_amp_max": max(e[1] for e in frf_errs),
               "frf_err_amp_same_omega_max": max(e[2] for e in frf_errs),
               "backbone_f_Hz": [float(bb.omega[0] / 2 / np.pi), float(bb.omega[-1] / 2 / np.pi)],
               "backbone_zeta": [float(bb.zeta[0]), float(bb.zeta[-1])], "harmonics_3_vs_5": [dw, da],
               "wall_s": time.perf_counter() - t_start}
    lines += [f"Total run time: {summary['wall_s']:.0f} s.", ""]
    name = "brb_quick.md" if args.quick else "brb.md"
    tmp = out / (name + ".tmp")
    tmp.write_text("\n".join(lines) + "\n")
    tmp.replace(out / name)
    (work / "brb_summary.json").write_text(json.dumps(summary, indent=1))
    print(f"wrote {out / name} ({summary['wall_s']:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
