"""Check the jointed beam's separating FRF (its loop near 260-271 Hz) by time integration.

    python demos/beam_timeint_check.py [--periods 60] [--steps 2000]

Takes points of the HBM branch of demos/beam2d.toml (3.0 N; --harmonics to change H), starts an implicit Newmark
integration (average acceleration, Newton on each step) of the same equations from each point's
state at t = 0, and compares half the peak-to-peak of b1.mid.uy over the last period with the HBM.
The contact law in the integrator is written here from scratch (return mapping per step, the
slider re-engaging where the pair is at the step of first contact), sharing no code with the AFT.
Each point also gets its stability from jointfem's own Hill analysis (analysis.stability: the
full-order problem's Jacobian at the point, the largest real part of its Floquet exponents), so
that the integration can confirm it: from a point marked stable it must stay on the orbit (within
1 % in amplitude and in waveform over the last period), from one marked unstable it must leave it.
Besides the points above, the loop's highest frequency and the first and last separated points are
taken, and the branch's stability change nearest the largest amplitude is located (by Hill's
method, starting at the omega fold nearest it, where a real exponent passes zero): the adjacent
points on either side of it are integrated too.  The dense eigenproblem is of twice the unknowns
(5520 at H = 11): one to three minutes per point.  Where the branch is not converged in H, a point
may have no true orbit within 1 % of it, stable or not: compare H = 9 and 11 (--harmonics).
Writes results/beam_timeint/check.json.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from jointfem.analysis.frf import create_problem
from jointfem.analysis.stability import is_stable, max_real_part
from jointfem.app import solve_scene
from jointfem.harmonics import Harmonics
from jointfem.scene import load_scene

HERE = Path(__file__).resolve().parent


def contact(g, w, kt, kn, mu, N0):
    """Pairs with one tangential and one normal component: g (P, 2) -> f - f0 (P, 2), w_new,
    tangent (P, 2, 2)."""
    P = g.shape[0]
    f = np.zeros((P, 2))
    Kt = np.zeros((P, 2, 2))
    w_new = w.copy()
    for p in range(P):
        N = N0[p] + kn[p] * g[p, 1]
        if N <= 0.0:
            w_new[p] = g[p, 0]
            f[p] = (0.0, -N0[p])
            continue
        t = kt[p] * (g[p, 0] - w[p])
        if abs(t) <= mu[p] * N:
            f[p] = (t, N - N0[p])
            Kt[p] = ((kt[p], 0.0), (0.0, kn[p]))
        else:
            sgn = np.sign(t)
            f[p] = (mu[p] * N * sgn, N - N0[p])
            w_new[p] = g[p, 0] - mu[p] * N * sgn / kt[p]
            Kt[p] = ((0.0, mu[p] * kn[p] * sgn), (0.0, kn[p]))
    return f, w_new, Kt


def integrate(structure, U, omega, w0, *, periods: int, steps: int, dof: int, keep: int = 2):
    """Newmark from the HBM state; returns the response of ``dof`` over the last ``keep`` periods."""
    grp = structure.contacts[0]
    G = grp.gap.tocsr()
    pr = grp.pairs
    n = structure.num_dofs
    H = (U.size // n - 1) // 2
    h = Harmonics(H, 2 * H + 1)
    Uh = U.reshape(h.num_hc, n)
    u = Uh[0] + sum(Uh[h.block_cos(k)] for k in range(1, H + 1))
    v = omega * sum(k * Uh[h.block_sin(k)] for k in range(1, H + 1))
    M, D, K = structure.M.tocsc(), structure.D.tocsc(), structure.K.tocsc()
    dt = 2 * np.pi / omega / steps
    w = w0.copy()

    def force(t):
        return structure.fc * np.cos(omega * t) + structure.fs * np.sin(omega * t)

    fc0, _, _ = contact((G @ u).reshape(-1, 2), w, pr.kt, pr.kn, pr.mu, pr.N0)
    a = spla.spsolve(M, force(0.0) - D @ v - K @ u - G.T @ fc0.ravel())
    base = (4 / dt**2) * M + (2 / dt) * D + K
    lu_cache = {}
    out = np.zeros(keep * steps)
    t = 0.0
    for it in range(periods * steps):
        t += dt
        x = u + dt * v + dt**2 / 4 * a  # predictor: a_{n+1} = a_n
        for _ in range(30):
            a1 = 4 / dt**2 * (x - u - dt * v) - a
            v1 = v + dt / 2 * (a + a1)
            fcn, w1, Kt = contact((G @ x).reshape(-1, 2), w, pr.kt, pr.kn, pr.mu, pr.N0)
            r = M @ a1 + D @ v1 + K @ x + G.T @ fcn.ravel() - force(t)
            if np.abs(r).max() <= 1e-9 * np.abs(structure.fc).max():
                break
            key = Kt.round(12).tobytes()
            if key not in lu_cache:
                Kc = sp.block_diag(list(Kt), format="csr")
                lu_cache[key] = spla.splu((base + G.T @ Kc @ G).tocsc())
            x = x - lu_cache[key].solve(r)
        else:
            # a stick/slip switch can make Newton cycle just above the tolerance: accept below 1e-7
            if np.abs(r).max() > 1e-7 * np.abs(structure.fc).max():
                raise RuntimeError(f"Newmark step at t = {t:.6g} s did not converge: max|r| = {np.abs(r).max():.3e} N")
        u, v, a, w = x, v1, a1, w1
        k = it - (periods - keep) * steps
        if k >= 0:
            out[k] = u[dof]
    return out


def hbm_response(U, n, h, omega, dof, t):
    """The HBM displacement of ``dof`` (m) at the times t (s)."""
    Uh = U.reshape(h.num_hc, n)[:, dof]
    y = np.full(t.shape, Uh[0])
    for k in range(1, h.H + 1):
        y += Uh[h.block_cos(k)] * np.cos(k * omega * t) + Uh[h.block_sin(k)] * np.sin(k * omega * t)
    return y


def departure(structure, U, omega, h, *, periods: int, steps: int, dof: int) -> np.ndarray:
    """How far Newmark started on the HBM orbit U (every DOF's coefficients, harmonics ``h``) gets
    from it: per period k = 1..periods, |Y_k - Y| / |Y| with Y_k the first harmonic (complex:
    amplitude and phase) of ``dof`` over period k and Y the orbit's.  The sliders start where the
    orbit has them at t = 0 (the full model's AFT)."""
    from jointfem.analysis.frf import create_problem
    n = structure.num_dofs
    Uh = U.reshape(h.num_hc, n)[:, dof]
    Y = Uh[h.block_cos(1)] - 1j * Uh[h.block_sin(1)]
    w0 = create_problem(structure, h).evaluate(U, omega, jacobian=False).contact[0].w_start[:, 0]
    y = integrate(structure, U, omega, w0, periods=periods, steps=steps, dof=dof, keep=periods).reshape(periods, steps)
    wt = np.arange(1, steps + 1) * (2 * np.pi / steps)  # omega t at the step ends of a period
    Yk = (2.0 / steps) * (y * np.exp(-1j * wt)).sum(axis=1)
    return np.abs(Yk - Y) / abs(Y)


def growth_rate(e: np.ndarray, omega: float, lo: float = 1e-4, hi: float = 1e-2) -> float | None:
    """1/s: the slope of log e against time over the periods where lo < e, before e first passes hi
    (None with fewer than 3 such periods): an unstable orbit's departure grows like e^{Re s t}."""
    stop = int(np.argmax(e > hi)) if (e > hi).any() else e.size
    k = np.flatnonzero(e[:stop] > lo)
    if k.size < 3:
        return None
    return float(np.polyfit((k + 1) * (2 * np.pi / omega), np.log(e[k]), 1)[0])


def stability_change(stable, top, lo, hi, omega, known=()):
    """The adjacent branch points (like ``top``, unlike it) between which the Hill stability changes
    nearest ``top`` on the separating part lo..hi of the branch, or None; ``stable(i)`` -> bool.

    A real Floquet exponent passes zero where the HBM Jacobian is singular, at an omega fold: the
    nearest fold on each side of the top is tried, nearer first, from the point just beyond it; a
    change found there is narrowed by bisection towards the top, probing the fold and its top-side
    neighbour first (two or three eigensolves when the change is at the fold).  Failing that, the
    change is bisected between the top and the nearest point of ``known`` (already evaluated) of the
    other stability: a change off the folds (a Neimark-Sacker one) is found only that way."""
    d = np.sign(np.diff(omega[lo:hi + 1]))
    folds = lo + 1 + np.flatnonzero(d[1:] * d[:-1] < 0)
    near = sorted((int(f) for f in np.concatenate([folds[folds < top][-1:], folds[folds > top][:1]])),
                  key=lambda f: abs(f - top))
    tries = [(f + (1 if f > top else -1), [f, f - (1 if f > top else -1)]) for f in near]
    tries += [(j, []) for j in sorted(known, key=lambda j: abs(j - top)) if j != top]
    like = stable(top)
    for b, probes in tries:
        if not lo <= b <= hi or stable(b) == like:
            continue
        a = top
        while abs(b - a) > 1:
            m = probes.pop(0) if probes else (a + b) // 2
            if not min(a, b) < m < max(a, b):
                continue
            if stable(m) == like:
                a = m
            else:
                b = m
        return a, b
    return None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--periods", type=int, default=60)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--harmonics", type=int, help="override the scene's H")
    ap.add_argument("--samples", type=int, help="override the scene's N")
    ap.add_argument("--out", default="results/beam_timeint")
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    scene = load_scene(HERE / "beam2d.toml")
    if args.harmonics:
        import dataclasses

        scene = dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, harmonics=args.harmonics))
    if args.samples:
        import dataclasses

        scene = dataclasses.replace(scene, solver=dataclasses.replace(scene.solver, samples=args.samples))
    sol = solve_scene(scene, progress=False)
    t_sweep = time.perf_counter() - t_start
    structure, frf = sol.structure, sol.frf
    dof = structure.outputs["b1.mid.uy"]
    amp = frf.half_peak_to_peak(dof)
    sep = (frf.states == 2).mean(axis=(1, 2))
    f_hz = frf.omega / (2 * np.pi)
    print(f"sweep: {frf.omega.size} points, {frf.info['num_unknowns']} unknowns (H = {scene.solver.harmonics}), "
          f"{t_sweep:.0f} s")
    # points: the stuck flank at 275 Hz; on the separating part, the largest amplitude, the lowest
    # frequency (the fold) and a point half-way between them along the branch; the highest frequency,
    # so that the loop's other end is checked as well; and the first and last separated points, where
    # the separation is slight and the HBM best converged in H
    picks = {"stuck flank 275 Hz": int(np.argmin(np.abs(f_hz - 275.0) + 1e3 * (sep > 0)))}
    on = np.flatnonzero(sep > 0)
    if on.size:
        top, fold = int(on[np.argmax(amp[on])]), int(on[np.argmin(f_hz[on])])
        picks["separated, largest amplitude"] = top
        picks["separated, half-way to the fold"] = (top + fold) // 2
        picks["separated, lowest frequency"] = fold
        picks["separated, highest frequency"] = int(on[np.argmax(f_hz[on])])
        picks["separated, first point"] = int(on[0])
        picks["separated, last point"] = int(on[-1])
    # Hill's stability on the full-order problem, as the sweep computes it by default: the
    # same harmonics and AFT samples as the sweep, so that the point is a root of its residual
    h = Harmonics(scene.solver.harmonics, scene.solver.samples)
    problem = create_problem(structure, h)
    hill = {}  # branch index -> (max Re s in 1/s, stable, seconds): one dense eigensolve each

    def stable(i):
        if i not in hill:
            t0 = time.perf_counter()
            ev = problem.evaluate(frf.U[i], frf.omega[i], jacobian=True)
            re = max_real_part(problem, frf.U[i], frf.omega[i], ev)
            hill[i] = (re, is_stable(re, frf.omega[i]), time.perf_counter() - t0)
            print(f"  Hill at point {i} ({f_hz[i]:.3f} Hz): max Re s = {re:+.4g} 1/s, "
                  f"{'stable' if hill[i][1] else 'unstable'} ({hill[i][2]:.0f} s)", flush=True)
        return hill[i][1]

    for i in picks.values():
        stable(i)
    change = None
    if on.size:
        # the separating part is one stretch of the branch here (from the first separated point to
        # the last one): the search stays inside it
        change = stability_change(stable, top, int(on[0]), int(on[-1]), frf.omega, known=list(hill))
        if change is not None:
            a, b = change
            s_, u_ = (a, b) if hill[a][1] else (b, a)
            picks["stability change nearest the top, stable side"] = s_
            picks["stability change nearest the top, unstable side"] = u_
            print(f"  stability changes between points {a} and {b} ({f_hz[a]:.4f} and {f_hz[b]:.4f} Hz)")
        else:
            print("  no stability change found next to the largest amplitude")
    report = {}
    n = structure.num_dofs
    for label, i in picks.items():
        t0 = time.perf_counter()
        w0 = problem.evaluate(frf.U[i], frf.omega[i], jacobian=False).contact[0].w_start[:, 0]
        y = integrate(structure, frf.U[i], frf.omega[i], w0, periods=args.periods, steps=args.steps, dof=dof)
        t_ti = time.perf_counter() - t0
        last, prev = y[args.steps:], y[:args.steps]
        a_ti, a_prev = 0.5 * np.ptp(last), 0.5 * np.ptp(prev)
        # the force fixes the phase, and the last period starts at a whole number of periods: the
        # integrated orbit is compared sample by sample with the HBM's as well (an orbit that left
        # for one of about the same amplitude shows here)
        t_last = np.arange(1, args.steps + 1) * (2 * np.pi / frf.omega[i] / args.steps)
        y_hbm = hbm_response(frf.U[i], n, h, frf.omega[i], dof, t_last)
        wave = np.abs(last - y_hbm).max() / amp[i]
        re, st, t_hill = hill[i]
        rel = a_ti / amp[i] - 1
        # on the orbit within 1 %: the amplitude, and the waveform (an orbit of about the same
        # amplitude but another phase, e.g. the stuck one, passes the first and fails the second)
        stays = abs(rel) < 0.01 and wave < 0.01
        report[label] = {"branch_index": i, "freq_Hz": float(f_hz[i]), "omega_rad_s": float(frf.omega[i]),
                         "hbm_halfp2p_m": float(amp[i]), "ti_halfp2p_m": float(a_ti),
                         "rel_diff": float(rel), "period_to_period_change": float(a_ti / a_prev - 1),
                         "waveform_diff_last_period": float(wave), "separated_share_hbm": float(sep[i]),
                         "floquet_max_real": float(re), "stable": bool(st),
                         # what the integration says about Hill's verdict: stays within 1 % if stable
                         "ti_amplitude_within_1pct": bool(abs(rel) < 0.01),
                         "ti_waveform_within_1pct": bool(wave < 0.01),
                         "ti_stays_within_1pct": bool(stays), "agrees_with_hill": bool(stays == st),
                         "time_hill_s": float(t_hill), "time_ti_s": float(t_ti)}
        print(f"{label:>48}: {f_hz[i]:.3f} Hz  HBM {amp[i]:.5e} m  time integration {a_ti:.5e} m  "
              f"({100 * rel:+.3f} %, drift {a_ti / a_prev - 1:+.1e} per period, waveform {100 * wave:.2f} %)  "
              f"max Re s {re:+.4g} 1/s {'stable' if st else 'unstable'}, separated {sep[i]:.3f}  "
              f"[{'agrees' if stays == st else 'DISAGREES'}]  ({t_ti:.0f} s)", flush=True)
    # The check checks itself where the answer is known: on the stuck flank the orbit is linear
    # and stable, so the integration must stay on it (its own error is about 1e-5 at 2000 steps).
    assert abs(report["stuck flank 275 Hz"]["rel_diff"]) < 1e-3, report["stuck flank 275 Hz"]
    assert report["stuck flank 275 Hz"]["stable"], report["stuck flank 275 Hz"]
    agree = sum(r["agrees_with_hill"] for r in report.values())
    print(f"time integration agrees with Hill's stability at {agree} of {len(report)} points; "
          f"total {time.perf_counter() - t_start:.0f} s")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "check.json").write_text(json.dumps({
        "harmonics": scene.solver.harmonics, "samples": scene.solver.samples, "periods": args.periods,
        "steps_per_period": args.steps, "num_unknowns": int(frf.info["num_unknowns"]), "time_sweep_s": t_sweep,
        # the adjacent points between which Hill's stability changes nearest the top: [stable, unstable]
        "stability_change": None if change is None else {"branch_index": [s_, u_],
                                                          "freq_Hz": [float(f_hz[s_]), float(f_hz[u_])]},
        # every eigensolve done (the picks and the search for the change), by branch index
        "hill": {str(j): {"freq_Hz": float(f_hz[j]), "floquet_max_real": float(v[0]), "stable": bool(v[1]),
                          "separated_share_hbm": float(sep[j])} for j, v in sorted(hill.items())},
        "points": report}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
