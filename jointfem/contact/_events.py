"""Compiled (numba) kernel of the event-accurate Jenkins AFT (one tangential direction).

The sampled law (_kernels.py) decides the state of the slider at each sample, so every switch
of state snaps to a sample, and its DFT of a kinked force converges like N^-2.  Here the law is
integrated in continuous time instead:

* each switch (stick -> slip where |kt (g_t - w)| reaches mu N, slip -> stick where the slider's
  rate g_t' - sigma mu N'/kt changes sign, separation and re-contact where N = N0 + kn g_n crosses
  zero) is located between samples, as the root of a cubic: the Hermite interpolant of the gaps
  and of their tau-rates at the samples (both exact, from the Fourier series);
* the force coefficients are integrals over the pieces between switches, not a DFT of samples.
  What is integrated is the departure from the stuck spring, f - f0 - Kc g: -kt w while stuck,
  sigma mu N - kt g_t while slipping, -kt g_t and -N while separated, with the gaps of the Fourier
  series itself: exactly (product-to-sum) over runs of intervals without a switch, by 4-point
  Gauss-Legendre on the pieces of an interval with one.  f0 + Kc G is added exactly by the caller,
  so a pair stuck all period is exactly the linear spring and a separated one exactly zero.

The force is continuous at a switch up to the interpolant's error there (the switch is located on
the cubic, the force evaluated on the series), so F is C1 in G wherever the switches are
transversal, and the Jacobian (the integral of d(f - Kc g)/dG over the pieces plus the memory of
each stick phase, dw/dG at its onset with d tau/dG of a re-contact instant) omits only the jump
times d tau_e/dG: measured 2e-5 of the largest entry at N = 64, 7e-8 at N = 256 (O(N^-4)).
Grazing switches are not smoothed: at the onset of slip where |f| only just reaches mu N, the
slider's slip grows like the overshoot, a kink of the continuous-time law itself.

The steady state is marched from w = 0 as in the sampled law: periods until the slider's state
at tau = 0 repeats (a pair that never slips keeps w = 0; one that slips only in its transient
keeps where it stopped), then one more period that integrates the forces.  With one tangential
direction a slip or a separation erases the slider's memory, so the period map's derivative is
zero after it and dw/dG propagated through the march is already the periodic one.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from . import _threading  # noqa: F401 (sets the threading layer before the first prange runs)

from .law import SEPARATED, SLIP, STICK

MAX_EVENTS = 16  # switches within one sample interval before the march gives up (status 2)


@njit(cache=True, inline="always")
def _hermite(y0, y1, d0, d1, h):
    """Power coefficients in s in [0, 1] of the cubic with values y0, y1 and tau-rates d0, d1."""
    return y0, h * d0, 3.0 * (y1 - y0) - 2.0 * h * d0 - h * d1, 2.0 * (y0 - y1) + h * d0 + h * d1


@njit(cache=True, inline="always")
def _ev(c0, c1, c2, c3, s):
    return c0 + s * (c1 + s * (c2 + s * c3))


@njit(cache=True, inline="always")
def _dev(c1, c2, c3, s):
    return c1 + s * (2.0 * c2 + s * 3.0 * c3)


@njit(cache=True)
def _root(c0, c1, c2, c3, a, b):
    """The root of a cubic monotone on [a, b] with p(a) <= 0 < p(b): Newton, safeguarded by bisection."""
    s = 0.5 * (a + b)
    for _ in range(100):
        f = _ev(c0, c1, c2, c3, s)
        if f > 0.0:
            b = s
        else:
            a = s
        if b - a <= 1e-16:
            break
        d = _dev(c1, c2, c3, s)
        sn = s - f / d if d != 0.0 else 0.5 * (a + b)
        if not (a < sn < b):
            sn = 0.5 * (a + b)
        if abs(sn - s) <= 1e-17:
            s = sn
            break
        s = sn
    return s


@njit(cache=True)
def _crossing(c0, c1, c2, c3, s0):
    """First s in (s0, 1] where the cubic passes from <= 0 to > 0; 2.0 if it does not.

    The interval is split at the critical points, so each piece is monotone and holds at most one
    crossing.  A function that starts a state at zero (the switch just made) is positive there
    only by round-off: it crosses only once it has been <= 0, and critical points closer than
    1e-12 to s0 (a tangency at the switch) do not split the interval.
    """
    # critical points: roots of 3 c3 s^2 + 2 c2 s + c1 in (s0, 1)
    qa, qb, qc = 3.0 * c3, 2.0 * c2, c1
    r1, r2 = 2.0, 2.0
    if qa != 0.0:
        disc = qb * qb - 4.0 * qa * qc
        if disc > 0.0:
            sq = np.sqrt(disc)
            t = -0.5 * (qb + sq) if qb >= 0.0 else -0.5 * (qb - sq)
            x1 = t / qa
            x2 = qc / t if t != 0.0 else 2.0
            r1, r2 = min(x1, x2), max(x1, x2)
    elif qb != 0.0:
        r1 = -qc / qb
    if r1 <= s0 + 1e-12:
        r1 = r2
        r2 = 2.0
    if r1 <= s0 + 1e-12:
        r1 = 2.0
    a = s0
    fa = _ev(c0, c1, c2, c3, a)
    for k in range(3):
        if k == 0:
            b = r1 if s0 < r1 < 1.0 else (r2 if s0 < r2 < 1.0 else 1.0)
        elif k == 1:
            if b >= 1.0:
                break
            b = r2 if b < r2 < 1.0 else 1.0
        else:
            if b >= 1.0:
                break
            b = 1.0
        fb = _ev(c0, c1, c2, c3, b)
        if fa <= 0.0 < fb:
            return _root(c0, c1, c2, c3, a, b)
        a, fa = b, fb
    return 2.0


@njit(cache=True, inline="always")
def _beta(gamma, gammad, i, i1, s, h, out):
    """out[h'] = d g(tau_i + h s) / d G_h' of the Hermite interpolant."""
    s2 = s * s
    s3 = s2 * s
    b00 = 2.0 * s3 - 3.0 * s2 + 1.0
    b01 = -2.0 * s3 + 3.0 * s2
    b10 = (s3 - 2.0 * s2 + s) * h
    b11 = (s3 - s2) * h
    for k in range(out.shape[0]):
        out[k] = b00 * gamma[i, k] + b01 * gamma[i1, k] + b10 * gammad[i, k] + b11 * gammad[i1, k]


@njit(cache=True, inline="always")
def _trig(tau, coef, out):
    """out[j] = (1, cos tau, sin tau, cos 2 tau, ...)[j] times coef/(2 pi) (j = 0) or coef/pi, the weights
    of the coefficient integrals; coef = 0 gives the plain values."""
    c1 = np.cos(tau)
    s1 = np.sin(tau)
    w0, w = (1.0, 1.0) if coef == 0.0 else (coef / (2.0 * np.pi), coef / np.pi)
    out[0] = w0
    ck, sk = 1.0, 0.0
    for k in range(1, (out.shape[0] - 1) // 2 + 1):
        ck, sk = ck * c1 - sk * s1, sk * c1 + ck * s1
        out[2 * k - 1] = w * ck
        out[2 * k] = w * sk


@njit(cache=True)
def _prod_int(a, b, E):
    """E[j, j2] = c_j * integral over [a, b] of trig_j(tau) trig_j2(tau), exactly (c_0 = 1/(2 pi), else 1/pi;
    trig = 1, cos tau, sin tau, cos 2 tau, ...), by the product-to-sum formulas."""
    nhc = E.shape[0]
    H = (nhc - 1) // 2
    Ic = np.empty(2 * H + 1)
    Is = np.empty(2 * H + 1)
    Ic[0] = b - a
    Is[0] = 0.0
    for k in range(1, 2 * H + 1):
        Ic[k] = (np.sin(k * b) - np.sin(k * a)) / k
        Is[k] = (np.cos(k * a) - np.cos(k * b)) / k
    for j in range(nhc):
        k = (j + 1) // 2
        c = 0 if j % 2 == 1 or j == 0 else 1
        cj = 0.5 / np.pi if j == 0 else 1.0 / np.pi
        for j2 in range(nhc):
            k2 = (j2 + 1) // 2
            c2 = 0 if j2 % 2 == 1 or j2 == 0 else 1
            d = abs(k - k2)
            sg = 1.0 if k > k2 else (-1.0 if k < k2 else 0.0)
            sm = k + k2
            if c == 0 and c2 == 0:
                v = 0.5 * (Ic[d] + Ic[sm])
            elif c == 0:
                v = 0.5 * (Is[sm] - sg * Is[d])
            elif c2 == 0:
                v = 0.5 * (Is[sm] + sg * Is[d])
            else:
                v = 0.5 * (Ic[d] - Ic[sm])
            E[j, j2] = cj * v


@njit(cache=True)
def _run(J, F, Gp, runs, b, ra, cb, i, coef, h, E, want_jac):
    """Extend run b (rows of component ra, columns of component cb) of switch-free intervals to
    interval i with coefficient coef, or close it and start a new one: closing adds
    coef * integral of trig_j trig_j2 over the run (_prod_int) to F (times G) and J.
    runs[b] = [first interval, coef]; first < 0 when no run is open."""
    if runs[b, 0] >= 0.0 and runs[b, 1] == coef:
        return
    if runs[b, 0] >= 0.0 and runs[b, 1] != 0.0:
        c = runs[b, 1]
        _prod_int(runs[b, 0] * h, i * h, E)
        m = F.shape[1]
        for j in range(E.shape[0]):
            v = 0.0
            for j2 in range(E.shape[1]):
                v += E[j, j2] * Gp[j2, cb]
                if want_jac:
                    J[j, ra, j2 * m + cb] += c * E[j, j2]
            F[j, ra] += c * v
    runs[b, 0] = i
    runs[b, 1] = coef
    if coef == 0.0:
        runs[b, 0] = -1.0


@njit(cache=True)
def _pair(g, gd, Gp, gamma, gammad, Tcum, xq, wq, kt, kn, mu, N0, has_normal, want_jac, max_periods, rtol,
          F, J, f_s, state_s, res):
    """March pair p to its periodic steady state and integrate its force over the last period.

    g, gd: (N, m) gaps and tau-rates at the samples; Gp (nhc, m) its gap coefficients; Tcum: see
    event_kernel.  Out: F (nhc, m), J (nhc, m, nhc*m) (the departure from the stuck spring), f_s (N, m),
    state_s (N,), res <- [w_start, status (0 ok, 1 no steady state, 2 too many switches), last change,
    number of switches (or the interval of too many)].
    """
    N, m = g.shape
    nhc = gamma.shape[1]
    q = nhc * m
    nn = m - 1  # the normal component (if has_normal)
    h = 2.0 * np.pi / N
    tr = np.zeros(nhc)
    tv = np.zeros(nhc)
    E = np.zeros((nhc, nhc))
    macc = np.zeros(nhc)  # sum of the stick pieces' -kt trig weights since dW last changed
    runs = np.full((3, 2), -1.0)  # open runs of event-free intervals: tt, tn, nn blocks
    dW = np.zeros(q)
    scale = mu * abs(N0) / kt
    for i in range(N):
        scale = max(scale, abs(g[i, 0]))
    if scale <= 0.0:
        scale = 1.0
    # initial state at tau = 0 from w = 0
    n_init = N0 + kn * g[0, nn] if has_normal else N0
    w = 0.0
    sig = 1.0
    if n_init <= 0.0:
        st = SEPARATED
        w = g[0, 0]
    elif mu == 0.0 or kt * abs(g[0, 0]) > mu * n_init:
        st = SLIP
        sig = 1.0 if g[0, 0] > 0.0 else -1.0
        w = g[0, 0] - sig * mu * n_init / kt
    else:
        st = STICK
    acc = False
    status = 1
    change = np.inf
    num_events = 0
    for period in range(max_periods + 1):
        w_begin, st_begin, sig_begin = w, st, sig
        moved = False
        for i in range(N):
            i1 = (i + 1) % N
            t0, t1, t2, t3 = _hermite(g[i, 0], g[i1, 0], gd[i, 0], gd[i1, 0], h)
            if has_normal:
                n0, n1, n2, n3 = _hermite(g[i, nn], g[i1, nn], gd[i, nn], gd[i1, nn], h)
                n0 = N0 + kn * n0
                n1 *= kn
                n2 *= kn
                n3 *= kn
            else:
                n0, n1, n2, n3 = N0, 0.0, 0.0, 0.0
            if acc:
                state_s[i] = st
                if st == STICK:
                    f_s[i, 0] = kt * (t0 - w)
                elif st == SLIP:
                    f_s[i, 0] = sig * mu * n0
                else:
                    f_s[i, 0] = 0.0
                if has_normal:
                    f_s[i, nn] = n0 if st != SEPARATED else 0.0
            s = 0.0
            for ev in range(MAX_EVENTS + 1):
                # the next switch of the current state
                which = -1
                se = 2.0
                if st == STICK:
                    x = _crossing(kt * (t0 - w) - mu * n0, kt * t1 - mu * n1, kt * t2 - mu * n2,
                                  kt * t3 - mu * n3, s)
                    if x < se:
                        se, which = x, 0
                    x = _crossing(-kt * (t0 - w) - mu * n0, -kt * t1 - mu * n1, -kt * t2 - mu * n2,
                                  -kt * t3 - mu * n3, s)
                    if x < se:
                        se, which = x, 1
                elif st == SLIP and mu > 0.0:
                    # the slider's rate sig (g_t' - sig mu N'/kt) falls through zero: stick (never
                    # without friction: the slider follows the gap)
                    x = _crossing(-(sig * kt * t1 - mu * n1), -2.0 * (sig * kt * t2 - mu * n2),
                                  -3.0 * (sig * kt * t3 - mu * n3), 0.0, s)
                    if x < se:
                        se, which = x, 3
                if st != SEPARATED and has_normal:  # N falls through zero: separation
                    x = _crossing(-n0, -n1, -n2, -n3, s)
                    if x < se:
                        se, which = x, 2
                elif st == SEPARATED:
                    x = _crossing(n0, n1, n2, n3, s)
                    if x < se:
                        se, which = x, 4
                sb = min(se, 1.0)
                if acc and se > 1.0 and s == 0.0:
                    # no switch in this interval: the departure from the stuck spring is linear in G
                    # here (plus a constant), integrated exactly over runs of equal coefficients
                    cf_tt = -kt if st != STICK else 0.0
                    cf_tn = sig * mu * kn if (st == SLIP and has_normal) else 0.0
                    cf_nn = -kn if (st == SEPARATED and has_normal) else 0.0
                    _run(J, F, Gp, runs, 0, 0, 0, i, cf_tt, h, E, want_jac)
                    _run(J, F, Gp, runs, 1, 0, nn, i, cf_tn, h, E, want_jac)
                    _run(J, F, Gp, runs, 2, nn, nn, i, cf_nn, h, E, want_jac)
                    c_t = -kt * w if st == STICK else (sig * mu * N0 if st == SLIP else 0.0)
                    c_n = -N0 if (st == SEPARATED and has_normal) else 0.0
                    for j in range(nhc):
                        dT = Tcum[i + 1, j] - Tcum[i, j]
                        F[j, 0] += c_t * dT
                        if has_normal:
                            F[j, nn] += c_n * dT
                        if want_jac and st == STICK:
                            macc[j] -= kt * dT
                    whole = True
                else:
                    if acc and s == 0.0:  # an interval with switches ends every run
                        for b in range(3):
                            _run(J, F, Gp, runs, b, 0 if b < 2 else nn, 0 if b == 0 else nn, i, 0.0, h, E, want_jac)
                    whole = False
                if acc and sb > s and not whole:
                    # the departure from the stuck spring, f - f0 - Kc g: -kt w (stick), mu N sig - kt g_t
                    # (slip), -kt g_t and -N (separated), with the gaps of the Fourier series at the
                    # Gauss points; f0 + Kc G is added exactly after the march
                    L = sb - s
                    for k in range(xq.shape[0]):
                        tq = (i + s + L * xq[k]) * h
                        _trig(tq, wq[k] * L * h, tr)
                        _trig(tq, 0.0, tv)
                        gt_q = 0.0
                        gn_q = 0.0
                        for j in range(nhc):
                            gt_q += tv[j] * Gp[j, 0]
                            if has_normal:
                                gn_q += tv[j] * Gp[j, nn]
                        nv = N0 + kn * gn_q
                        if st == STICK:
                            ct = -kt * w
                            cn = 0.0
                        elif st == SLIP:
                            ct = sig * mu * nv - kt * gt_q
                            cn = 0.0
                        else:
                            ct = -kt * gt_q
                            cn = -nv
                        for j in range(nhc):
                            F[j, 0] += tr[j] * ct
                            if has_normal:
                                F[j, nn] += tr[j] * cn
                        if not want_jac:
                            continue
                        if st == STICK:
                            for j in range(nhc):
                                macc[j] -= kt * tr[j]
                            continue
                        for j in range(nhc):
                            a = -kt * tr[j]
                            for j2 in range(nhc):
                                J[j, 0, j2 * m] += a * tv[j2]
                        if has_normal:
                            cf = sig * mu * kn if st == SLIP else 0.0
                            cfn = -kn if st == SEPARATED else 0.0
                            for j in range(nhc):
                                a = cf * tr[j]
                                an = cfn * tr[j]
                                for j2 in range(nhc):
                                    J[j, 0, j2 * m + nn] += a * tv[j2]
                                    J[j, nn, j2 * m + nn] += an * tv[j2]
                if se > 1.0:
                    break
                if ev == MAX_EVENTS:
                    res[1] = 2.0
                    res[3] = i
                    return
                # the switch at se
                moved = True
                num_events += 1
                gt = _ev(t0, t1, t2, t3, se)
                nv = _ev(n0, n1, n2, n3, se)
                gtp = _dev(t1, t2, t3, se) / h
                npr = _dev(n1, n2, n3, se) / h
                _beta(gamma, gammad, i, i1, se, h, tv)  # d g(tau_e) / d G of the interpolant
                if want_jac and st == STICK:  # leaving a stick phase: its memory term is complete
                    for j in range(nhc):
                        if macc[j] != 0.0:
                            for k in range(q):
                                J[j, 0, k] += macc[j] * dW[k]
                        macc[j] = 0.0
                if which == 0 or which == 1:
                    st = SLIP
                    sig = 1.0 if which == 0 else -1.0
                elif which == 2:
                    st = SEPARATED
                elif which == 3:
                    # the slider stops where its rate is zero, so d tau_e/dG does not enter dw
                    st = STICK
                    w = gt - sig * mu * nv / kt
                    if want_jac:
                        for j2 in range(nhc):
                            dW[j2 * m] = tv[j2]
                            if has_normal:
                                dW[j2 * m + nn] = -sig * mu * kn / kt * tv[j2]
                else:  # re-contact: slip if the spring would load faster than the cone opens
                    if mu == 0.0 or kt * abs(gtp) > mu * npr:
                        st = SLIP
                        sig = 1.0 if gtp > 0.0 else -1.0
                    else:
                        # stick from the gap at the crossing: dw = dg_t(tau_e) + g_t' d tau_e, with
                        # d tau_e = -kn dg_n(tau_e) / N'
                        st = STICK
                        w = gt
                        if want_jac:
                            for j2 in range(nhc):
                                dW[j2 * m] = tv[j2]
                                dW[j2 * m + nn] = -gtp * kn * tv[j2] / npr
                s = se
            if st == SLIP:
                w = _ev(t0, t1, t2, t3, 1.0) - sig * mu * _ev(n0, n1, n2, n3, 1.0) / kt
            elif st == SEPARATED:
                w = _ev(t0, t1, t2, t3, 1.0)
        if acc:
            for b in range(3):
                _run(J, F, Gp, runs, b, 0 if b < 2 else nn, 0 if b == 0 else nn, N, 0.0, h, E, want_jac)
            if want_jac and st == STICK:
                for j in range(nhc):
                    if macc[j] != 0.0:
                        for k in range(q):
                            J[j, 0, k] += macc[j] * dW[k]
            status = 0
            break
        change = abs(w - w_begin) / scale
        if not moved or (st == st_begin and sig == sig_begin and change <= rtol):
            acc = True
            res[0] = w
    res[1] = status
    res[2] = change if status else 0.0
    res[3] = num_events


@njit(cache=True, parallel=True)
def event_kernel(g_t, gd_t, G, gamma, gammad, Tcum, xq, wq, kt, kn, mu, N0, has_normal, want_jac, max_periods, rtol,
                 F, J, f_t, state_t, res):
    """Every pair in parallel: g_t, gd_t (N, P, m) the gaps and their tau-rates at the samples, G
    (nhc, P, m) their coefficients; Tcum (N+1, nhc) the running integrals of c_j trig_j (event_tables); F (P, nhc, m); J (P, nhc, m, nhc*m);
    f_t (N, P, m); state_t (N, P); res (P, 4) = [w_start, status, last change, events]."""
    P = g_t.shape[1]
    for p in prange(P):
        f_p = np.zeros((g_t.shape[0], g_t.shape[2]))
        s_p = np.zeros(g_t.shape[0], dtype=np.int8)
        _pair(np.ascontiguousarray(g_t[:, p, :]), np.ascontiguousarray(gd_t[:, p, :]), np.ascontiguousarray(G[:, p, :]),
              gamma, gammad, Tcum,
              xq, wq,
              kt[p], kn[p], mu[p], N0[p], has_normal, want_jac, max_periods, rtol, F[p], J[p], f_p, s_p, res[p])
        f_t[:, p, :] = f_p
        state_t[:, p] = s_p


def event_tables(N: int, nhc: int) -> np.ndarray:
    """Tcum (N+1, nhc): c_j times the integral of trig_j from 0 to tau_i, exactly (c_0 = 1/(2 pi), else 1/pi):
    an interval without a switch contributes a constant c times Tcum[i+1] - Tcum[i]."""
    tau = 2.0 * np.pi * np.arange(N + 1) / N
    k = np.arange(1, (nhc - 1) // 2 + 1)
    T = np.empty((N + 1, nhc))
    T[:, 0] = tau / (2.0 * np.pi)
    T[:, 1::2] = np.sin(np.outer(tau, k)) / k / np.pi
    T[:, 2::2] = (1.0 - np.cos(np.outer(tau, k))) / k / np.pi
    return T
