"""Validation of the continuum models (issue 4) -> docs/validation.md.

    python demos/validation.py --out docs            # make validate
    python demos/validation.py --quick --out DIR     # the test's setting: about 25 s

1. Mesh convergence of the single bar (cantilever and clamped-clamped) against Euler-Bernoulli.
2. The 3D lap joint against the beam2d model of the same joint, stuck: first 5 frequencies.
3. The Brake-Reuss-like beam: stuck first bending frequency, free-free, against 168-170 Hz.
4. Offline stage times of the 3D lap joint (mesh, assembly, gather, eigen, static modes).
(5. A pointer to docs/brb.md, the Brake-Reuss beam swept beside the published data: make brb.)

Every number is computed by this script in one run; nothing is typed in.  The script checks
itself on what its text claims: the Q2 bar within 2.5 % of Euler-Bernoulli, converging from
above; the continuum's first bending within 2.5 % of beam2d's, rising with the contact
stiffness; the Brake-Reuss models below the monolithic bar, ordered by their joint's stiffness.

``--quick`` checks the same on less: the four cheapest bar meshes (no 5400- to 19800-DOF
ones), and the Brake-Reuss beam with 12.7 mm elements along it (16230 DOFs instead of 57402).
"""
from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from jointfem import linalg  # noqa: E402
from jointfem.fem.continuum import Bolt, ContinuumSpec, create_continuum  # noqa: E402
from jointfem.models.beam2d import Beam2DSpec, create_beam2d  # noqa: E402

E, RHO, H, L = 2.1e11, 7850.0, 0.006, 0.3
BETA = {"cantilever": np.array([1.8751040687, 4.6940911330, 7.8547574382]),
        "clamped-clamped": np.array([4.7300407449, 7.8532046241, 10.9956078380])}
# (dim, degree, element size along, through the thickness) of the single bar
BAR_MESHES = [(3, 1, 0.01, 0.003), (3, 1, 0.005, 0.0015), (3, 2, 0.02, 0.006), (3, 2, 0.01, 0.006),
              (3, 2, 0.005, 0.003), (2, 2, 0.01, 0.006), (2, 2, 0.0025, 0.0015)]
BAR_MESHES_QUICK = [(3, 1, 0.01, 0.003), (3, 2, 0.02, 0.006), (3, 2, 0.01, 0.006), (2, 2, 0.01, 0.006)]


def classify(structure, num):
    """Frequencies (Hz) and dominant displacement component of the first ``num`` modes."""
    w2, Phi = linalg.eigen(structure.K_lin, structure.M, num, sigma=-1e3)
    comp = np.array([n.rsplit(".", 1)[1] for n in structure.dof_names])
    kinds = []
    for j in range(num):
        e = {c: float((Phi[comp == c, j] ** 2).sum()) for c in ("ux", "uy", "uz")}
        kinds.append(max(e, key=e.get))
    return np.sqrt(np.abs(w2)) / 2 / np.pi, kinds


def bending_y(structure, num=12):
    f, kinds = classify(structure, num)
    return f[[k == "uy" for k in kinds]]


def bar_convergence(lines, quick=False):
    lines += ["## 1. Single bar against Euler-Bernoulli", "",
              "Steel bar 300 x 6 x 25 mm (E = 210 GPa, rho = 7850 kg/m^3, nu = 0.3), bending in the 6 mm "
              "direction, Lagrange hexahedra (3D) or plane-stress quadrilaterals (2D). Relative error of the first "
              "three bending frequencies against Euler-Bernoulli (f_n = beta_n^2 / (2 pi L^2) sqrt(E h^2 / 12 rho)).",
              "", "| case | dim | degree | size along / through (mm) | DOFs | f1 (Hz) | err f1 | err f2 | err f3 |",
              "|---|---|---|---|---|---|---|---|---|"]
    for case, beta in BETA.items():
        ref = beta**2 / (2 * np.pi * L**2) * np.sqrt(E * H**2 / 12 / RHO)
        q2_f1 = []  # (size, error of f1) of the 3D Q2 meshes
        for dim, degree, size, hn in (BAR_MESHES_QUICK if quick else BAR_MESHES):
            spec = ContinuumSpec(geometry="bar", dim=dim, clamped=(True, case != "cantilever"), size=size,
                                 size_normal=hn, degree=degree)
            s = create_continuum(spec)
            f = bending_y(s)[:3]
            err = f / ref - 1
            lines.append(f"| {case} | {dim} | {degree} | {size * 1e3:g} / {hn * 1e3:g} | {s.num_dofs} | {f[0]:.3f} | "
                         + " | ".join(f"{e:+.3%}" for e in err) + " |")
            # Checks, as the text below explains them: Q1 hexahedra lock in bending (+13.8 % at
            # least, measured); Q2 elements and the 2D quadrilaterals are within 2.5 % of the beam
            # theory (measured 2.09 % at most: f3, clamped-clamped, the coarsest Q2 mesh), what
            # the beam theory leaves out (shear, rotary inertia, the width) being a few tenths.
            if degree == 1:
                assert err.min() > 0.10, (case, dim, degree, size, err)
            else:
                assert np.abs(err).max() < 0.025, (case, dim, degree, size, err)
            if dim == 3 and degree == 2:
                q2_f1.append((size, err[0]))
        # Q2 hexahedra converge from above: f1's error positive and falling as the mesh is refined
        # (measured +1.64, +0.92, +0.66 % clamped-clamped; +0.79, +0.56, +0.46 % cantilever)
        e1 = [e for _, e in sorted(q2_f1, reverse=True)]
        assert min(e1) > 0 and all(b < a for a, b in zip(e1, e1[1:])), (case, q2_f1)
    lines += ["", "Euler-Bernoulli: " + ", ".join(
        f"{case} {', '.join(f'{x:.3f}' for x in beta**2 / (2 * np.pi * L**2) * np.sqrt(E * H**2 / 12 / RHO))} Hz"
        for case, beta in BETA.items()) + ".", "",
        "Degree 1 hexahedra lock in bending (errors of several per cent that fall slowly with refinement); "
        "degree 2 converges from above to within a few tenths of a per cent, the rest being physics the beam "
        "theory leaves out: shear deformation and rotary inertia lower mode 3 by about 0.4 % for h/L = 0.02 "
        "(Timoshenko), and the 25 mm width stiffens a little towards the plate modulus E/(1 - nu^2) "
        "(+4.6 % for a very wide strip). The scenes use degree 2.", ""]


def lap_vs_beam(lines, quick=False):
    beam = create_beam2d(Beam2DSpec())
    wb = np.sqrt(linalg.eigen(beam.K_lin, beam.M, 5)[0]) / 2 / np.pi
    rows = []
    variants = [("kt_total 3e4 N/m, kn 2e11 N/m^3 (demos/lap3d.toml)", dict(kt_total=3e4, kn=2e11)),
                ("kn x 100 (2e13 N/m^3)", dict(kt_total=3e4, kn=2e13)),
                ("kt, kn x 1e4 (nearly bonded)", dict(kt_total=3e8, kn=2e15))]
    for label, kw in variants:
        spec = ContinuumSpec(geometry="lap", dim=3, size=0.01, size_normal=0.006, pressure=8e4, **kw)
        s = create_continuum(spec)
        f, kinds = classify(s, 8)
        rows.append((label, s, f, kinds))
    lines += ["## 2. 3D lap joint against the beam2d model, stuck", "",
              "Both: two 300 x 6 x 25 mm steel bars, 30 mm overlap, outer ends clamped, joint stuck (linear springs). "
              "beam2d: 3 node pairs with kt = 1e4 N/m, kn = 5e6 N/m and a rotational spring kr = 8e6 N m/rad each. "
              f"Continuum: Q2 hexahedra, {rows[0][1].num_dofs} DOFs, {rows[0][1].num_pairs} node pairs over the overlap, "
              "stiffness spread by consistent nodal area.", "",
              "| mode | beam2d (Hz) | " + " | ".join(r[0] for r in rows) + " |",
              "|---|---|" + "---|" * len(rows)]
    for j in range(8):
        cells = []
        for _, _, f, kinds in rows:
            cells.append(f"{f[j]:.2f} ({kinds[j]})")
        lines.append(f"| {j + 1} | {wb[j]:.2f} | " if j < 5 else f"| {j + 1} | - | " + "")
        lines[-1] += " | ".join(cells) + " |"
    y = [bending_y(r[1])[:3] for r in rows]
    # Checks: the same bars and joint, so the first bending in y agrees with beam2d's within 2.5 %
    # (measured -1.78, -0.10, +0.38 %), and rises with the contact stiffness (the variants' order),
    # the joint's rotational stiffness being what differs (explained below).
    first = np.array([yi[0] for yi in y])
    assert np.abs(first / wb[0] - 1).max() < 0.025, (first, wb[0])
    assert np.all(np.diff(first) > 0), first
    lines += ["", "(uy: bending in the stacking direction, the only kind beam2d has; uz: lateral bending; ux: axial.)",
              "", f"Bending in y, continuum against beam2d (first, second): "
              + "; ".join(f"{r[0]}: {y[i][0] / wb[0] - 1:+.2%}, {y[i][1] / wb[1] - 1:+.2%}" for i, r in enumerate(rows))
              + ".", "",
              "Differences, and why:",
              "- The continuum has lateral (uz) bending modes in between; the plane beam2d model cannot.",
              "- beam2d carries the joint's moment through its rotational springs (3 x 8e6 N m/rad). In the "
              "continuum, the moment is carried by the normal springs spread over the overlap (k_rot ~ kn A "
              "L_o^2 / 12, 1.1e3 N m/rad at 2e11 N/m^3) and by the overlap's own bending: the joint is softer in "
              "rotation, so the first mode, whose curvature peaks near the joint, is lower. Stiffer contact closes "
              "the gap: the table's last column approaches a bonded 6 mm + 6 mm overlap.",
              "- The overlap is modelled in the continuum as two stacked 6 mm layers of true thickness; beam2d "
              "treats it as two beam elements with lever arms h/2, which ignores shear across the layers.", ""]


def brb(lines, quick=False):
    lines += ["## 3. Brake-Reuss-like beam, stuck, free-free", "",
              "Two halves of 0.42 m with a 25.4 x 25.4 mm section overlapping 0.12 m at half thickness "
              "(total 0.72 m), E = 192.85 GPa, nu = 0.29, rho = 7857.8 kg/m^3, free-free as in the experiments. "
              "Three bolts at 30 mm pitch (x = 0.33, 0.36, 0.39 m), each modelled as a preload patch: its force "
              "is spread over the contact nodes within a radius, in proportion to their areas. The six rigid-body "
              "modes are found with a negative shift (sigma = -1e3 rad^2/s^2) and skipped.", "",
              "| joint model | DOFs | pairs | first bending (Hz) | against 168 - 170 Hz |", "|---|---|---|---|---|"]
    Ltot, a = 0.72, 0.0254
    mono = 22.3733 / (2 * np.pi * Ltot**2) * np.sqrt(192.85e9 * a**2 / 12 / 7857.8)
    found = []
    for label, kw, radius in [
            ("whole interface, kt = kn = 1e13 N/m^3", dict(kt=1e13, kn=1e13), 0.0095),
            ("whole interface, kt = kn = 1e15 N/m^3 (nearly bonded)", dict(kt=1e15, kn=1e15), 0.0095),
            ("bolt patches only, r = 9.5 mm, kt = kn = 1e13 N/m^3", dict(kt=1e13, kn=1e13, patches_only=True), 0.0095),
            ("bolt patches only, r = 19 mm, kt = kn = 1e13 N/m^3", dict(kt=1e13, kn=1e13, patches_only=True), 0.019)]:
        bolts = tuple(Bolt(x, 0.0127, radius, 12e3) for x in (0.33, 0.36, 0.39))
        spec = ContinuumSpec(geometry="brb", dim=3, length=0.42, height=a, width=a, overlap=0.12, clamped=(False, False),
                             size=0.0127 if quick else 0.0127 / 2, size_normal=0.0127 / 2, degree=2,
                             young=192.85e9, poisson=0.29,
                             density=7857.8, bolts=bolts, force_at=(0.3, 0.0, 0.0127), **kw)
        s = create_continuum(spec)
        f = bending_y(s, 14)
        f = f[f > 1.0]
        found.append((label, f[0]))
        lines.append(f"| {label} | {s.num_dofs} | {s.num_pairs} | {f[0]:.1f} | {f[0] / 169.0 - 1:+.1%} |")
    # Checks, as the text below explains them: every model stays below the monolithic bar (the
    # free end faces act as half-depth cracks), the stiffer contact and the wider patch are stiffer
    # (measured 194.4 < 204.3 Hz and 150.4 < 167.3 Hz), and the published 168-170 Hz lies between
    # the softest and the stiffest model.
    f1 = {label: f for label, f in found}
    labels = list(f1)
    assert max(f1.values()) < mono, (f1, mono)
    assert f1[labels[0]] < f1[labels[1]] and f1[labels[2]] < f1[labels[3]], f1
    assert min(f1.values()) < 168.0 and max(f1.values()) > 170.0, f1
    below = [x for x in found if x[1] < 168.0]
    above = [x for x in found if x[1] > 170.0]
    inside = [x for x in found if 168.0 <= x[1] <= 170.0]
    lines += ["", f"Monolithic 0.72 m bar, free-free Euler-Bernoulli: {mono:.1f} Hz.", ""]
    if inside:
        lines.append("Within the published 168-170 Hz: " + "; ".join(x[0] for x in inside) + ".")
    elif below and above:
        lines.append(f"The published 168-170 Hz lies between these models: {max(below, key=lambda x: x[1])[0]} "
                     f"({max(x[1] for x in below):.1f} Hz) and {min(above, key=lambda x: x[1])[0]} "
                     f"({min(x[1] for x in above):.1f} Hz).")
    lines += ["",
              "Why the models differ from the published 168-170 Hz: the stuck frequency is set by how much of the "
              "interface carries load and how stiffly, which this model takes as inputs (contact stiffness per "
              "area, the patches under the bolts), not from measurement. A contact stiffness of 1e13 N/m^3 "
              "equals the shear compliance of about 7.5 mm of steel (G / k), comparable to the 12.7 mm half "
              "thickness, so it is far from bonded. 1e15 N/m^3 nearly bonds the halves, yet the beam stays "
              "well below the monolithic bar: where one half's end face meets the other's shoulder (x = 0.30 "
              "and 0.42 m) the faces are free, not in contact, and act as two half-depth cracks. Contact only under the bolts "
              "is softer, and grows stiffer with the patch radius: a real bolt's pressure cone spreads over "
              "about 1.5-2 washer radii. The bolts' own mass and stiffness (heads, nuts, shanks) are not "
              "modelled.", ""]


def brb_swept(lines, quick=False):
    """A pointer: the swept BRB is its own run (make brb), too long for this one."""
    lines += ["## 5. The Brake-Reuss beam swept, beside the published data", "",
              "docs/brb.md (`make brb`, demos/brb.py, about 40 minutes) takes demos/brb.toml: free-free on two soft "
              "supports, the three bolts' preload (Porter & Brake's 12.0, 12.1 and 12.7 kN) through a static contact "
              "solve, 217 contact pairs.  It gives the static contact state, the stuck modes, the mode-1 backbone and "
              "the forced response at three levels with the penalty ROM, each checked against the exact "
              "condensation, and, in its section 6, the model's low-amplitude frequency and backbone beside the "
              "published data (the measured ranges and the low-amplitude damping of Porter & Brake, MSSP 192 (2023) "
              "110210, their simulated backbone, and the inputs of Balaji et al., MSSP 149 (2021) 107249), with what "
              "that comparison can and cannot show.  Section 3's 168 - 170 Hz band was quoted here before without a "
              "source; the sources found since put the measured mode 1 on a 175.5 - 180 Hz axis and Porter & Brake's "
              "flat-interface model at 168.5 Hz (docs/brb.md).  docs/benchmarks_preload.md (`make bench-preload`) "
              "gives the swept model's contact state and stuck frequency against mesh refinement.", ""]


def offline(lines, quick=False):
    from jointfem.rom import RomOptions, build_rom
    from jointfem.scene import create_structure, load_scene

    root = Path(__file__).resolve().parents[1]
    scene = load_scene(root / "demos" / "lap3d.toml")
    t0 = time.perf_counter()
    s = create_structure(scene)
    t1 = time.perf_counter()
    w2, _ = linalg.eigen(s.K_lin, s.M, 20)
    t2 = time.perf_counter()
    G = s.contacts[0].gap
    linalg.Factorized(s.K_lin).solve(G.T.toarray())
    t3 = time.perf_counter()
    rom = build_rom(s, "penalty", RomOptions(modes=10))
    tm = s.info["timings"]
    lines += ["## 4. Offline stages of the 3D lap joint (demos/lap3d.toml)", "",
              f"{s.num_dofs} DOFs, {s.num_pairs} pairs ({3 * s.num_pairs} contact components), "
              f"backend {linalg.backend(s.num_dofs)}, serial.", "",
              "| stage | seconds |", "|---|---|",
              f"| gmsh mesh + distribution | {tm['mesh_s']:.2f} |", f"| dolfinx assembly of K, M | {tm['assembly_s']:.2f} |",
              f"| gather to canonical order, areas, normals | {tm['gather_s']:.2f} |",
              f"| contact pairs | {tm['contact_s']:.2f} |", f"| (whole model build) | {t1 - t0:.2f} |",
              f"| 20 modes (eigen) | {t2 - t1:.2f} |", f"| {G.shape[0]} static solves (factorise + solve) | {t3 - t2:.2f} |",
              f"| penalty ROM, 10 modes (modes + static modes + projection) | {rom.offline_s:.2f} |", ""]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs")
    ap.add_argument("--quick", action="store_true",
                    help="the cheapest bar meshes and a coarser Brake-Reuss mesh (the test's setting)")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    cmd = ("`python demos/validation.py --quick` (the test's smoke run)" if args.quick
           else "`python demos/validation.py --out docs` (`make validate`)")
    lines = ["# Validation of the continuum models", "",
             f"Generated by {cmd} on "
             f"{platform.node() and 'this machine'}: {platform.processor() or platform.machine()}, "
             f"Python {platform.python_version()}. Every number below comes from that one run.", ""]
    for step in (bar_convergence, lap_vs_beam, brb, offline, brb_swept):
        print(f"validation: {step.__name__} ...", file=sys.stderr, flush=True)
        step(lines, quick=args.quick)
    lines.append(f"Total run time: {time.perf_counter() - t0:.0f} s.")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / "validation.md.tmp"
    tmp.write_text("\n".join(lines) + "\n")
    tmp.replace(out / "validation.md")
    print(f"wrote {out / 'validation.md'}")


if __name__ == "__main__":
    main()
