"""Compiled (numba) kernels of the Jenkins AFT.  Same law and same tangent as the
NumPy reference march of tests/reference_jenkins.py; jenkins.py states the equations.

Per pair and sample the local tangents are

    df_i = D_i dg_i + C_i dw_{i-1},      dw_i = A_i dg_i + B_i dw_{i-1},

stick:     D = diag(kt.., kn), C = [-kt I; 0],          A = 0,                      B = I
slip:      D = [r kt P, mu kn e; 0, kn], C = [-r kt P; 0], A = [I - r P, -mu kn e/kt], B = r P
separated: D = 0, C = 0,                                 A = [I, 0],                 B = 0

with e = t/|t|, P = I - e e^T and r = mu N/|t|.  The "direct" part (D) is
returned per sample and transformed by the caller; the "memory" part (C dw) is
accumulated here, with one outer product per stick interval (dw is constant
while a pair sticks), so its cost follows the number of slip samples.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from . import _threading  # noqa: F401 (sets the threading layer before the first prange runs)

from .law import SEPARATED, SLIP, STICK  # noqa: F401 (compile-time constants of the kernels)


@njit(cache=True, inline="always")
def _law(gt0, gt1, gn, w0, w1, kt, kn, mu, N0, nt, has_normal):
    """One return-mapping step.  Returns (state, ft0, ft1, fn, w0, w1, r, e0, e1)."""
    if has_normal:
        N = N0 + kn * gn
    else:
        N = N0
    if N <= 0.0:
        return SEPARATED, 0.0, 0.0, 0.0, gt0, gt1, 0.0, 0.0, 0.0
    t0 = kt * (gt0 - w0)
    t1 = kt * (gt1 - w1) if nt == 2 else 0.0
    tn = np.sqrt(t0 * t0 + t1 * t1)
    lim = mu * N
    if tn <= lim:
        return STICK, t0, t1, N, w0, w1, 1.0, 0.0, 0.0
    e0 = t0 / tn
    e1 = t1 / tn
    r = lim / tn
    f0 = lim * e0
    f1 = lim * e1
    return SLIP, f0, f1, N, gt0 - f0 / kt, (gt1 - f1 / kt) if nt == 2 else 0.0, r, e0, e1


@njit(cache=True, inline="always")
def _phi(a, b):
    """Crossing-corrected share of sample value a > 0 on the interval towards a neighbour b.

    Returns (phi, dphi/da, dphi/db).  With the normal force linear between samples, the
    trapezoid rule on the part of the interval still in contact gives a^2/(a - b) when the
    neighbour is separated (b <= 0); a otherwise.
    """
    if b > 0.0:
        return a, 1.0, 0.0
    d = a - b
    return a * a / d, a * (a - 2.0 * b) / (d * d), a * a / (d * d)


@njit(cache=True, inline="always")
def _recontact(g, i, kn, N0, nt):
    """Slider position where the normal load of a separated sample i-1 crosses zero before the
    contact sample i (linear interpolation): the tangential spring re-engages unloaded there.

    Returns (theta, w0, w1, Nprev, Ncur) with w = g_t(i-1) + theta (g_t(i) - g_t(i-1)) and
    theta = -N(i-1) / (N(i) - N(i-1)) in [0, 1).  Taking the crossing instead of the last
    separated sample makes the stick/slip choice after re-contact depend on the rates of g_t and N
    (slip if kt |g_t'| > mu N'), not on the size of the first contact load, so that it no longer
    flips with tiny changes of N.
    """
    N = g.shape[0]
    ip = (i - 1) % N
    n_p = N0 + kn * g[ip, nt]
    n_c = N0 + kn * g[i, nt]
    theta = -n_p / (n_c - n_p)
    w0 = g[ip, 0] + theta * (g[i, 0] - g[ip, 0])
    w1 = (g[ip, 1] + theta * (g[i, 1] - g[ip, 1])) if nt == 2 else 0.0
    return theta, w0, w1, n_p, n_c


@njit(cache=True, inline="always")
def _recontact_dW(g, i, gamma, dW, theta, n_p, n_c, kn, m, nt):
    """dW <- d w_recontact: (1 - theta) dg_t(i-1) + theta dg_t(i) + (g_t(i) - g_t(i-1)) dtheta,
    dtheta = kn (-N(i) dg_n(i-1) + N(i-1) dg_n(i)) / (N(i) - N(i-1))^2."""
    N = g.shape[0]
    ip = (i - 1) % N
    nhc = gamma.shape[1]
    den = (n_c - n_p) * (n_c - n_p)
    for a in range(nt):
        dg = g[i, a] - g[ip, a]
        for k in range(dW.shape[1]):
            dW[a, k] = 0.0
        for hh in range(nhc):
            dW[a, hh * m + a] = (1.0 - theta) * gamma[ip, hh] + theta * gamma[i, hh]
            dW[a, hh * m + nt] = dg * kn * (-n_c * gamma[ip, hh] + n_p * gamma[i, hh]) / den


@njit(cache=True)
def _period(g, kt, kn, mu, N0, nt, has_normal, w0, w1, T):
    """March one period without forces; T (2x2) <- dw_end/dw_start.  Returns (w0, w1, moved)."""
    N = g.shape[0]
    T[0, 0] = 1.0
    T[0, 1] = 0.0
    T[1, 0] = 0.0
    T[1, 1] = 1.0
    moved = False
    prev_sep = has_normal and N0 + kn * g[N - 1, nt] <= 0.0
    for i in range(N):
        gt1 = g[i, 1] if nt == 2 else 0.0
        gn = g[i, nt] if has_normal else 0.0
        if prev_sep and N0 + kn * gn > 0.0:
            theta, w0, w1, n_p, n_c = _recontact(g, i, kn, N0, nt)
        s, f0, f1, fn, w0, w1, r, e0, e1 = _law(g[i, 0], gt1, gn, w0, w1, kt, kn, mu, N0, nt, has_normal)
        prev_sep = s == SEPARATED
        if s == SEPARATED:
            moved = True
            T[:, :] = 0.0
        elif s == SLIP:
            moved = True
            # B = r (I - e e^T);  T <- B T
            b00 = r * (1.0 - e0 * e0)
            b01 = -r * e0 * e1
            b11 = r * (1.0 - e1 * e1)
            a, b, c, d = T[0, 0], T[0, 1], T[1, 0], T[1, 1]
            T[0, 0] = b00 * a + b01 * c
            T[0, 1] = b00 * b + b01 * d
            T[1, 0] = b01 * a + b11 * c
            T[1, 1] = b01 * b + b11 * d
    return w0, w1, moved


@njit(cache=True, inline="always")
def _advance_dW(s, r, e0, e1, gamma_i, dW, tmp, m, nt, has_normal, kt, kn, mu):
    """dw_i = A_i dg_i + B_i dw_{i-1} in place (slip or separated sample; stick leaves dw).

    On a slip sample ``tmp`` must already hold P dw_{i-1}.
    """
    nhc = gamma_i.shape[0]
    nq = dW.shape[1]
    e = (e0, e1)
    if s == SLIP:
        for a in range(nt):
            for k in range(nq):
                dW[a, k] = r * tmp[a, k]
        for hh in range(nhc):
            gv = gamma_i[hh]
            for a in range(nt):
                for b in range(nt):
                    Pab = (1.0 if a == b else 0.0) - e[a] * e[b]
                    dW[a, hh * m + b] += ((1.0 if a == b else 0.0) - r * Pab) * gv
                if has_normal:
                    dW[a, hh * m + nt] -= mu * kn * e[a] / kt * gv
    elif s == SEPARATED:
        for a in range(nt):
            for k in range(nq):
                dW[a, k] = 0.0
            for hh in range(nhc):
                dW[a, hh * m + a] = gamma_i[hh]


@njit(cache=True, inline="always")
def _project(e0, e1, dW, tmp, nt):
    """tmp <- (I - e e^T) dW."""
    e = (e0, e1)
    for a in range(nt):
        for k in range(dW.shape[1]):
            v = 0.0
            for b in range(nt):
                v += ((1.0 if a == b else 0.0) - e[a] * e[b]) * dW[b, k]
            tmp[a, k] = v


@njit(cache=True)
def _transient_tangent(g, kt, kn, mu, N0, nt, has_normal, gamma, num_periods, q):
    """d w / d G after ``num_periods`` periods marched from w = 0 (the shakedown of a pair that
    slips in its transient and then sticks for good).  Returns dW of shape (nt, q)."""
    N, m = g.shape
    dW = np.zeros((nt, q))
    tmp = np.zeros((nt, q))
    w0, w1 = 0.0, 0.0
    prev_sep = has_normal and N0 + kn * g[N - 1, nt] <= 0.0
    for _ in range(num_periods):
        for i in range(N):
            gt1 = g[i, 1] if nt == 2 else 0.0
            gn = g[i, nt] if has_normal else 0.0
            if prev_sep and N0 + kn * gn > 0.0:
                theta, w0, w1, n_p, n_c = _recontact(g, i, kn, N0, nt)
                _recontact_dW(g, i, gamma, dW, theta, n_p, n_c, kn, m, nt)
            s, f0, f1, fn, w0, w1, r, e0, e1 = _law(g[i, 0], gt1, gn, w0, w1, kt, kn, mu, N0, nt, has_normal)
            prev_sep = s == SEPARATED
            if s == SLIP:
                _project(e0, e1, dW, tmp, nt)
            if s != STICK:
                _advance_dW(s, r, e0, e1, gamma[i], dW, tmp, m, nt, has_normal, kt, kn, mu)
    return dW


@njit(cache=True)
def _steady_search(g, kt, kn, mu, N0, nt, has_normal, rtol, max_iter, num_plain, scale):
    """One search from w = 0: ``num_plain`` plain periods, then Newton on the fixed point.

    Returns (w0, w1, status, err, kind, num_transient, newton_used).
    """
    T = np.empty((2, 2))
    w0, w1 = 0.0, 0.0
    err = np.inf
    newton_used = False
    for it in range(max_iter):
        e0, e1, moved = _period(g, kt, kn, mu, N0, nt, has_normal, w0, w1, T)
        if not moved:
            return w0, w1, 0, 0.0, (0 if it == 0 else 2), it, newton_used
        r0 = e0 - w0
        r1 = e1 - w1
        err = max(abs(r0), abs(r1)) / scale
        plain = it < num_plain
        if plain:  # a plain period
            v0, v1 = e0, e1
        else:  # a Newton step on the fixed point
            newton_used = True
            v0, v1 = w0 + r0, w1 + r1
            if nt == 1:
                den = 1.0 - T[0, 0]
                if abs(den) > 1e-12:
                    v0 = w0 + r0 / den
            else:
                a, b, c, d = 1.0 - T[0, 0], -T[0, 1], -T[1, 0], 1.0 - T[1, 1]
                det = a * d - b * c
                if abs(det) > 1e-12:
                    v0 = w0 + (d * r0 - b * r1) / det
                    v1 = w1 + (-c * r0 + a * r1) / det
        if err <= rtol:
            # w is within rtol * scale of the fixed point, but the forces marched from it carry
            # that error through kt (on the lap joint, 1.1e-10 of the HBM residual's scale, above
            # its tolerance, which Newton then met only by luck).  The next iterate is kept if the
            # period from it still slips (a fixed point of this kind) and closes better.
            f0, f1, still = _period(g, kt, kn, mu, N0, nt, has_normal, v0, v1, T)
            closed = max(abs(f0 - v0), abs(f1 - v1)) / scale
            if still and closed <= err:
                return v0, v1, 0, closed, 1, it + 1, newton_used
            return w0, w1, 0, err, 1, it, newton_used
        w0, w1 = v0, v1
    return w0, w1, 1, err, 1, max_iter, newton_used


@njit(cache=True)
def _steady(g, kt, kn, mu, N0, nt, has_normal, rtol, max_iter):
    """Slider state at tau = 0 of the periodic steady state, marched from w = 0.

    Returns (w0, w1, status, last_err, kind, num_transient):
    kind 0: sticks all period from w = 0 (w* = 0);
    kind 1: slips or separates in the steady period (w* isolated fixed point of the period map,
            whatever path found it);
    kind 2: shakedown, slipped for ``num_transient`` plain periods and then sticks for good (w*
            and its derivative belong to the plain path, which _transient_tangent replays);
    status 1 if not converged.  Two plain periods (1D is periodic after one slipping period),
    then Newton on the fixed point (2D partial slip converges slowly otherwise).  If Newton stalls
    or lands on a shakedown, the search is redone along the plain path (up to 8 max_iter periods),
    so that kind 2 stays consistent with _transient_tangent.
    """
    scale = mu * abs(N0) / kt
    for i in range(g.shape[0]):
        for a in range(nt):
            scale = max(scale, abs(g[i, a]))
    if scale <= 0.0:
        scale = 1.0
    w0, w1, st, err, kind, ntr, newton_used = _steady_search(g, kt, kn, mu, N0, nt, has_normal, rtol, max_iter,
                                                            2, scale)
    if st != 0 or (kind == 2 and newton_used):
        # Newton stalled on a kink of the period map, or landed on a shakedown: follow the plain
        # path instead (it may converge only geometrically, e.g. ratcheting into a shakedown).
        n_plain = 8 * max_iter
        w0, w1, st, err, kind, ntr, newton_used = _steady_search(g, kt, kn, mu, N0, nt, has_normal, rtol,
                                                                n_plain, n_plain, scale)
    return w0, w1, st, err, kind, ntr


@njit(cache=True, parallel=True)
def aft_kernel(g_t, kt, kn, mu, N0, nt, has_normal, gamma, cum_gamma_inv, trig, cum_trig, prod_table,
               want_jac, rtol, max_iter, f_t, state_t, w_start, J_out, status, errs):
    """Steady-state march of every pair (parallel over pairs).

    In:  g_t (N, P, m); pair arrays (P,); gamma (N, nhc); cum_gamma_inv (N+1, nhc), the
         running sums of gamma_inv^T; trig (N, 2, 2H+1) = cos/sin(k tau_i), k = 0..2H, and
         cum_trig (N+1, 2, 2H+1) its running sums; prod_table (nhc, nhc, 7) from
         ``_product_table`` (how gamma_inv[h] * gamma[h'] reduces to single harmonics).
    Out: f_t (N, P, m), state_t (N, P), w_start (P, nt), status/errs (P,);
         if want_jac: J_out (P, nhc, m, nhc*m) = dF/dG, periodicity included.
    """
    P = g_t.shape[1]
    for p in prange(P):
        _pair(p, g_t, kt[p], kn[p], mu[p], N0[p], nt, has_normal, gamma, cum_gamma_inv, trig, cum_trig,
              prod_table, want_jac, rtol, max_iter, f_t, state_t, w_start, J_out, status, errs)


@njit(cache=True)
def _pair(p, g_t, ktp, knp, mup, N0p, nt, has_normal, gamma, cum_gamma_inv, trig, cum_trig, prod_table,
          want_jac, rtol, max_iter, f_t, state_t, w_start, J_out, status, errs):
    """Everything for pair p, with its own scratch arrays (safe under prange)."""
    N, P, m = g_t.shape
    nhc = gamma.shape[1]
    nk = trig.shape[2]
    q = nhc * m
    nq = q + nt
    g = g_t[:, p, :]
    w0, w1, st, err, kind, num_transient = _steady(g, ktp, knp, mup, N0p, nt, has_normal, rtol, max_iter)
    status[p] = st
    errs[p] = err
    w_start[p, 0] = w0
    if nt == 2:
        w_start[p, 1] = w1
    dW = np.zeros((nt, nq))  # dw/d[G, w_start]
    if want_jac:
        if kind == 1:  # periodic slip: differentiate w.r.t. w_start, then close the period below
            for a in range(nt):
                dW[a, q + a] = 1.0
        elif kind == 2:  # shakedown: w* depends on G through the transient
            dW[:, :q] = _transient_tangent(g, ktp, knp, mup, N0p, nt, has_normal, gamma, num_transient, q)
    J = np.zeros((nhc, m, nq))  # memory part of dF/d[G, w_start]
    Dh = np.zeros((2, nk, m, m))  # sum_i cos/sin(k tau_i) D_i  (direct part, k = 0..2H)
    tmp = np.zeros((nt, nq))
    stick_from = -1  # first sample of the current stick run, -1 if not sticking
    prev_sep = has_normal and N0p + knp * g[N - 1, nt] <= 0.0
    for i in range(N + 1):
        if i < N:
            gt1 = g[i, 1] if nt == 2 else 0.0
            gn = g[i, nt] if has_normal else 0.0
            if prev_sep and N0p + knp * gn > 0.0:  # re-contact: the slider starts at the crossing
                theta, w0, w1, n_p, n_c = _recontact(g, i, knp, N0p, nt)
                if want_jac:
                    _recontact_dW(g, i, gamma, dW, theta, n_p, n_c, knp, m, nt)
            s, f0, f1, fn, w0n, w1n, r, e0, e1 = _law(g[i, 0], gt1, gn, w0, w1, ktp, knp, mup, N0p, nt, has_normal)
            prev_sep = s == SEPARATED
            state_t[i, p] = s
            f_t[i, p, 0] = f0
            if nt == 2:
                f_t[i, p, 1] = f1
            Dnn = knp  # d N_eff / d g_n at this sample
            cross_prev = 0.0  # d N_eff / d g_n at the previous / next sample (crossings only)
            cross_next = 0.0
            if has_normal and s != SEPARATED:
                # Normal force of a sample next to a separated one: crossing-corrected (see _phi).
                n_prev = N0p + knp * g[(i - 1) % N, nt]
                n_next = N0p + knp * g[(i + 1) % N, nt]
                pa, pa_a, pa_b = _phi(fn, n_next)
                pb, pb_a, pb_b = _phi(fn, n_prev)
                fn = 0.5 * (pa + pb)
                Dnn = 0.5 * knp * (pa_a + pb_a)
                cross_next = 0.5 * knp * pa_b
                cross_prev = 0.5 * knp * pb_b
            if has_normal:
                f_t[i, p, nt] = fn
            w0, w1 = w0n, w1n
        else:
            s = -1  # end of period: flush a pending stick run
            Dnn = knp
            cross_prev = 0.0
            cross_next = 0.0
        if not want_jac:
            continue
        if has_normal and s != SEPARATED:
            if Dnn != knp:  # stick runs and slip samples below assume kn: correct the difference
                for c in range(2):
                    for k in range(nk):
                        Dh[c, k, nt, nt] += (Dnn - knp) * trig[i, c, k]
            for side in range(2):
                cf_n = cross_next if side == 0 else cross_prev
                if cf_n != 0.0:
                    j = (i + 1) % N if side == 0 else (i - 1) % N
                    for h in range(nhc):
                        gi = (cum_gamma_inv[i + 1, h] - cum_gamma_inv[i, h]) * cf_n
                        for h2 in range(nhc):
                            J[h, nt, h2 * m + nt] += gi * gamma[j, h2]
        if s == STICK:
            if stick_from < 0:
                stick_from = i
            continue
        if stick_from >= 0:
            # Stick run [stick_from, i): D = diag(kt.., kn) and C dw = -kt dw with dw frozen.
            for c in range(2):
                for k in range(nk):
                    w = cum_trig[i, c, k] - cum_trig[stick_from, c, k]
                    for a in range(nt):
                        Dh[c, k, a, a] += ktp * w
                    if has_normal:
                        Dh[c, k, nt, nt] += knp * w
            for h in range(nhc):
                cf = -ktp * (cum_gamma_inv[i, h] - cum_gamma_inv[stick_from, h])
                if cf != 0.0:
                    for a in range(nt):
                        for k in range(nq):
                            J[h, a, k] += cf * dW[a, k]
            stick_from = -1
        if s == SLIP:
            e = (e0, e1)
            # direct: D = [r kt P, mu kn e; 0, kn]
            for c in range(2):
                for k in range(nk):
                    w = trig[i, c, k]
                    for a in range(nt):
                        for b in range(nt):
                            Pab = (1.0 if a == b else 0.0) - e[a] * e[b]
                            Dh[c, k, a, b] += r * ktp * Pab * w
                        if has_normal:
                            Dh[c, k, a, nt] += mup * knp * e[a] * w
                    if has_normal:
                        Dh[c, k, nt, nt] += knp * w
            # memory: C dw = -r kt P dw (tangential rows)
            _project(e0, e1, dW, tmp, nt)
            for h in range(nhc):
                cf = -r * ktp * (cum_gamma_inv[i + 1, h] - cum_gamma_inv[i, h])
                for a in range(nt):
                    for k in range(nq):
                        J[h, a, k] += cf * tmp[a, k]
        if s == SLIP or s == SEPARATED:  # separated: D = 0, C = 0, dw = dg_t
            _advance_dW(s, r, e0, e1, gamma[i], dW, tmp, m, nt, has_normal, ktp, knp, mup)
    if not want_jac:
        return
    # Periodicity: dw*/dG = (I - T)^-1 S with S = dW[:, :q], T = dW[:, q:] (kind 1 only).
    if kind == 1:
        if nt == 1:
            den = 1.0 - dW[0, q]
            for k in range(q):
                tmp[0, k] = dW[0, k] / den
        else:
            a_, b_, c_, d_ = 1.0 - dW[0, q], -dW[0, q + 1], -dW[1, q], 1.0 - dW[1, q + 1]
            det = a_ * d_ - b_ * c_
            for k in range(q):
                s0, s1 = dW[0, k], dW[1, k]
                tmp[0, k] = (d_ * s0 - b_ * s1) / det
                tmp[1, k] = (-c_ * s0 + a_ * s1) / det
        for h in range(nhc):
            for a in range(m):
                for b in range(nt):
                    cf = J[h, a, q + b]
                    if cf != 0.0:
                        for k in range(q):
                            J[h, a, k] += cf * tmp[b, k]
    # Direct part: sum_i gamma_inv[h,i] gamma[i,h'] D_i from the single-harmonic sums Dh.
    for h in range(nhc):
        for h2 in range(nhc):
            cf = prod_table[h, h2, 0]
            i1, c1, s1 = int(prod_table[h, h2, 1]), int(prod_table[h, h2, 2]), prod_table[h, h2, 3]
            i2, c2, s2 = int(prod_table[h, h2, 4]), int(prod_table[h, h2, 5]), prod_table[h, h2, 6]
            for a in range(m):
                for b in range(m):
                    J_out[p, h, a, h2 * m + b] = J[h, a, h2 * m + b] + cf * (
                        s1 * Dh[c1, i1, a, b] + s2 * Dh[c2, i2, a, b])


def product_table(H: int, N: int) -> np.ndarray:
    """gamma_inv[h, i] * gamma[i, h'] = cf * (s1 * T_c1(k1 tau_i) + s2 * T_c2(k2 tau_i)).

    Row (h, h'): [cf, k1, c1, s1, k2, c2, s2] with c = 0 for cos, 1 for sin.
    """
    nhc = 2 * H + 1
    order = [0] + [k for k in range(1, H + 1) for _ in (0, 1)]
    kind = [0] + [c for _ in range(1, H + 1) for c in (0, 1)]
    tab = np.zeros((nhc, nhc, 7))
    for h in range(nhc):
        for h2 in range(nhc):
            k, k2 = order[h], order[h2]
            cf = (1.0 if h == 0 else 2.0) / N * 0.5
            d, sgn, ssum = abs(k - k2), float(np.sign(k - k2)), k + k2
            if kind[h] == 0 and kind[h2] == 0:  # cos k cos k' = (cos(k-k') + cos(k+k'))/2
                row = [cf, d, 0, 1.0, ssum, 0, 1.0]
            elif kind[h] == 0:  # cos k sin k' = (sin(k+k') - sin(k-k'))/2
                row = [cf, ssum, 1, 1.0, d, 1, -sgn]
            elif kind[h2] == 0:  # sin k cos k' = (sin(k+k') + sin(k-k'))/2
                row = [cf, ssum, 1, 1.0, d, 1, sgn]
            else:  # sin k sin k' = (cos(k-k') - cos(k+k'))/2
                row = [cf, d, 0, 1.0, ssum, 0, -1.0]
            tab[h, h2] = row
    return tab
