"""Independent time integration of lumped systems with 1D Jenkins elements (with or without a
normal DOF and separation), for checking the harmonic balance.

Classical RK4 on (u, v) with the slider frozen within a step and committed by return mapping at
the end of the step.  Written from scratch (scalar loops, numba), sharing no code with jointfem:
its error is first order in the step at stick/slip transitions and fourth order elsewhere.
"""
import numpy as np
from numba import njit


@njit(cache=True)
def _contact(u, w, Gt, Gn, has_n, kt, kn, mu, N0, f, w_new):
    f[:] = 0.0
    for p in range(kt.shape[0]):
        gt = 0.0
        for j in range(u.shape[0]):
            gt += Gt[p, j] * u[j]
        N = N0[p]
        if has_n[p]:
            gn = 0.0
            for j in range(u.shape[0]):
                gn += Gn[p, j] * u[j]
            N = N0[p] + kn[p] * gn
        if N <= 0.0:
            ft, fn, wn = 0.0, 0.0, gt
        else:
            trial = kt[p] * (gt - w[p])
            if abs(trial) <= mu[p] * N:
                ft, wn = trial, w[p]
            else:
                ft = mu[p] * N * np.sign(trial)
                wn = gt - ft / kt[p]
            fn = N
        w_new[p] = wn
        for j in range(u.shape[0]):
            f[j] += Gt[p, j] * ft
            if has_n[p]:
                f[j] += Gn[p, j] * (fn - max(N0[p], 0.0))  # the static preload is balanced (an open pair has none)


@njit(cache=True)
def integrate(Minv, K, D, fc, fs, omega, Gt, Gn, has_n, kt, kn, mu, N0, periods, steps):
    """March ``periods`` periods of 2 pi/omega from rest; return u over the last two periods,
    shape (2*steps, n), sampled at the step ends."""
    n = K.shape[0]
    P = kt.shape[0]
    dt = 2.0 * np.pi / omega / steps
    u = np.zeros(n)
    v = np.zeros(n)
    w = np.zeros(P)
    wn = np.zeros(P)
    f = np.zeros(n)
    out = np.zeros((2 * steps, n))
    ku = np.zeros((4, n))
    kv = np.zeros((4, n))
    t = 0.0
    for it in range(periods * steps):
        for s in range(4):
            c = 0.0 if s == 0 else (0.5 if s < 3 else 1.0)
            us = u + c * dt * ku[s - 1] if s > 0 else u.copy()
            vs = v + c * dt * kv[s - 1] if s > 0 else v.copy()
            ts = t + c * dt
            _contact(us, w, Gt, Gn, has_n, kt, kn, mu, N0, f, wn)
            rhs = fc * np.cos(omega * ts) + fs * np.sin(omega * ts) - K @ us - D @ vs - f
            ku[s] = vs
            kv[s] = Minv @ rhs
        u = u + dt / 6.0 * (ku[0] + 2 * ku[1] + 2 * ku[2] + ku[3])
        v = v + dt / 6.0 * (kv[0] + 2 * kv[1] + 2 * kv[2] + kv[3])
        t += dt
        _contact(u, w, Gt, Gn, has_n, kt, kn, mu, N0, f, wn)
        w[:] = wn
        k = it - (periods - 2) * steps
        if k >= 0:
            out[k] = u
    return out


def steady_amplitudes(system: dict, omegas, *, periods=300, steps=2000):
    """Half peak-to-peak of every DOF over the last period, and its change from the period before.

    system: dict of dense arrays M, K, D, fc, fs, Gt, Gn (P x n), has_n, kt, kn, mu, N0.
    Returns (amp (len(omegas), n), drift (len(omegas),) relative).
    """
    s = {k: np.ascontiguousarray(np.asarray(v, dtype=float if k != "has_n" else np.bool_))
         for k, v in system.items()}
    Minv = np.linalg.inv(s["M"])
    amps, drifts = [], []
    for om in np.atleast_1d(omegas):
        x = integrate(Minv, s["K"], s["D"], s["fc"], s["fs"], float(om), s["Gt"], s["Gn"], s["has_n"], s["kt"],
                      s["kn"], s["mu"], s["N0"], periods, steps)
        last, prev = x[steps:], x[:steps]
        a = 0.5 * (last.max(axis=0) - last.min(axis=0))
        b = 0.5 * (prev.max(axis=0) - prev.min(axis=0))
        amps.append(a)
        drifts.append(np.max(np.abs(a - b)) / np.max(a))
    return np.array(amps), np.array(drifts)
