"""Compiled (numba) kernel of the Jenkins law's Floquet Jacobian: the contact forces' response to
a perturbation e^{s t} v(t) of the gaps, v periodic, about the steady period.

The AFT's Jacobian (_kernels.py) is that of periodic forces with respect to periodic gaps.  A
stuck slider remembers the gap at its stick onset: a perturbation dg = e^{st} v changes a stuck
force by kt (dg(t) - dg(t_on)) = e^{st} kt (v(t) - e^{-s tau} v(t_on)), tau = t - t_on, which the
periodic Jacobian has with e^{-s tau} = 1 (docs/benchmarks_slip_stability.md measures what that
costs Hill's exponents).  Here the same tangent recursions as _kernels.py

    df_i = D_i dg_i + C_i dw_{i-1},      dw_i = A_i dg_i + B_i dw_{i-1}

are written for u_i with dw_i = e^{s t_i} u_i: every step back in time multiplies by
z = e^{-s T / N}, so that u_i = A_i v_i + z B_i u_{i-1} (slip), u_i = z u_{i-1} (stick), and the
crossing-corrected normal force of sample i, which reads the gaps of samples i - 1 and i + 1,
weighs them by z and 1 / z.  The periodic closure u_{-1} = u_{N-1} is solved as in _kernels.py.
At s = 0 this is the AFT's Jacobian, except for a pair that slipped in its transient and then
sticks for good (a shakedown): its slider is frozen (dw = 0), where the AFT's tangent carries how
the transient from w = 0 placed it, which is how the harmonic balance chooses among the steady
states, not how a perturbed orbit moves.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from . import _threading  # noqa: F401 (sets the threading layer before the first prange runs)
from ._kernels import _advance_dW, _law, _phi, _project, _recontact
from .law import SEPARATED, SLIP, STICK  # noqa: F401 (compile-time constants of the kernels)


@njit(cache=True, parallel=True)
def floquet_kernel(g_t, kt, kn, mu, N0, nt, has_normal, gamma, gamma_inv, w_start, moved, z, dt, J_out, dJ_out):
    """Per pair (parallel): J_out (P, nhc, m, nhc*m) complex <- dF/dV of the perturbation
    e^{st} V, z = e^{-s dt}, dt = T / N, and dJ_out <- its derivative in s.  gamma_inv (nhc, N)
    complex (the analysis, as the harmonics' own).  g_t (N, P, m) the
    steady gaps, w_start (P, nt) the slider at tau = 0, moved (P,) whether the pair leaves stick
    in the steady period."""
    P = g_t.shape[1]
    for p in prange(P):
        _floquet_pair(p, g_t, kt[p], kn[p], mu[p], N0[p], nt, has_normal, gamma, gamma_inv, w_start, moved[p],
                      z, dt, J_out, dJ_out)


@njit(cache=True)
def _floquet_pair(p, g_t, ktp, knp, mup, N0p, nt, has_normal, gamma, gamma_inv, w_start, moved, z, dt, J_out,
                  dJ_out):
    """One pair; every array x has its derivative in s, xd, carried beside it."""
    N, P, m = g_t.shape
    nhc = gamma.shape[1]
    q = nhc * m
    nq = q + nt
    g = g_t[:, p, :]
    zi = 1.0 / z
    zd = -dt * z  # dz/ds
    zid = dt * zi
    dW = np.zeros((nt, nq), dtype=np.complex128)  # u = d[w]/d[V, u_start]
    dWd = np.zeros((nt, nq), dtype=np.complex128)
    tmp = np.zeros((nt, nq), dtype=np.complex128)
    tmpd = np.zeros((nt, nq), dtype=np.complex128)
    phis = np.zeros((N, m, nq), dtype=np.complex128)  # the force perturbation of each sample
    phids = np.zeros((N, m, nq), dtype=np.complex128)
    if moved:
        for a in range(nt):
            dW[a, q + a] = 1.0
    w0 = w_start[p, 0]
    w1 = w_start[p, 1] if nt == 2 else 0.0
    prev_sep = has_normal and N0p + knp * g[N - 1, nt] <= 0.0
    for i in range(N):
        for a in range(nt):
            for k in range(nq):
                dWd[a, k] = z * dWd[a, k] + zd * dW[a, k]
                dW[a, k] *= z
        gt1 = g[i, 1] if nt == 2 else 0.0
        gn = g[i, nt] if has_normal else 0.0
        ip = (i - 1) % N
        if prev_sep and N0p + knp * gn > 0.0:  # re-contact: u at the crossing, sample i - 1 one step back
            theta, w0, w1, n_p, n_c = _recontact(g, i, knp, N0p, nt)
            den = (n_c - n_p) * (n_c - n_p)
            for a in range(nt):
                dga = g[i, a] - g[ip, a]
                for k in range(nq):
                    dW[a, k] = 0.0
                    dWd[a, k] = 0.0
                for hh in range(nhc):
                    dW[a, hh * m + a] = (1.0 - theta) * z * gamma[ip, hh] + theta * gamma[i, hh]
                    dW[a, hh * m + nt] = dga * knp * (-n_c * z * gamma[ip, hh] + n_p * gamma[i, hh]) / den
                    dWd[a, hh * m + a] = (1.0 - theta) * zd * gamma[ip, hh]
                    dWd[a, hh * m + nt] = -dga * knp * n_c * zd * gamma[ip, hh] / den
        s, f0, f1, fn, w0n, w1n, r, e0, e1 = _law(g[i, 0], gt1, gn, w0, w1, ktp, knp, mup, N0p, nt, has_normal)
        prev_sep = s == SEPARATED
        w0, w1 = w0n, w1n
        phi = phis[i]
        phid = phids[i]
        if s != SEPARATED:
            if has_normal:
                Dnn = knp
                n_prev = N0p + knp * g[ip, nt]
                n_next = N0p + knp * g[(i + 1) % N, nt]
                pa, pa_a, pa_b = _phi(fn, n_next)
                pb, pb_a, pb_b = _phi(fn, n_prev)
                Dnn = 0.5 * knp * (pa_a + pb_a)
                c_next = 0.5 * knp * pa_b * zi
                c_prev = 0.5 * knp * pb_b * z
                for hh in range(nhc):
                    phi[nt, hh * m + nt] += (Dnn * gamma[i, hh] + c_next * gamma[(i + 1) % N, hh]
                                             + c_prev * gamma[ip, hh])
                    phid[nt, hh * m + nt] += 0.5 * knp * (pa_b * zid * gamma[(i + 1) % N, hh]
                                                          + pb_b * zd * gamma[ip, hh])
            if s == STICK:  # D = kt I, C = -kt I (tangential)
                for a in range(nt):
                    for hh in range(nhc):
                        phi[a, hh * m + a] += ktp * gamma[i, hh]
                    for k in range(nq):
                        phi[a, k] -= ktp * dW[a, k]
                        phid[a, k] -= ktp * dWd[a, k]
            else:  # slip: D = [r kt P, mu kn e], C = -r kt P
                e = (e0, e1)
                for hh in range(nhc):
                    gv = gamma[i, hh]
                    for a in range(nt):
                        for b in range(nt):
                            Pab = (1.0 if a == b else 0.0) - e[a] * e[b]
                            phi[a, hh * m + b] += r * ktp * Pab * gv
                        if has_normal:
                            phi[a, hh * m + nt] += mup * knp * e[a] * gv
                _project(e0, e1, dW, tmp, nt)
                _project(e0, e1, dWd, tmpd, nt)
                for a in range(nt):
                    for k in range(nq):
                        phi[a, k] -= r * ktp * tmp[a, k]
                        phid[a, k] -= r * ktp * tmpd[a, k]
        if s == SLIP:  # u = A v + r P u: its derivative r P ud
            _advance_dW(s, r, e0, e1, gamma[i], dW, tmp, m, nt, has_normal, ktp, knp, mup)
            for a in range(nt):
                for k in range(nq):
                    dWd[a, k] = r * tmpd[a, k]
        elif s == SEPARATED:  # u = v
            _advance_dW(s, r, e0, e1, gamma[i], dW, tmp, m, nt, has_normal, ktp, knp, mup)
            for a in range(nt):
                for k in range(nq):
                    dWd[a, k] = 0.0
    # the coefficients of the samples' perturbations (a BLAS product: the per-sample sums cost more
    # than the march)
    Phi = np.dot(gamma_inv, phis.reshape(N, m * nq)).reshape(nhc, m, nq)
    Phid = np.dot(gamma_inv, phids.reshape(N, m * nq)).reshape(nhc, m, nq)
    if moved:  # u_start = X = (I - T)^-1 S, S = dW[:, :q], T = dW[:, q:]; X' = (I - T)^-1 (T' X + S')
        Tm = np.zeros((nt, nt), dtype=np.complex128)
        for a in range(nt):
            for b in range(nt):
                Tm[a, b] = (1.0 if a == b else 0.0) - dW[a, q + b]
        X = np.linalg.solve(Tm, np.ascontiguousarray(dW[:, :q]))
        rhs = np.ascontiguousarray(dWd[:, :q]).copy()
        for a in range(nt):
            for b in range(nt):
                for k in range(q):
                    rhs[a, k] += dWd[a, q + b] * X[b, k]
        Xd = np.linalg.solve(Tm, rhs)
        for h in range(nhc):
            for a in range(m):
                for b in range(nt):
                    cf = Phi[h, a, q + b]
                    cfd = Phid[h, a, q + b]
                    for k in range(q):
                        Phi[h, a, k] += cf * X[b, k]
                        Phid[h, a, k] += cfd * X[b, k] + cf * Xd[b, k]
    for h in range(nhc):
        for a in range(m):
            for k in range(q):
                J_out[p, h, a, k] = Phi[h, a, k]
                dJ_out[p, h, a, k] = Phid[h, a, k]
