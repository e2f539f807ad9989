"""Independent NumPy reference of the Jenkins AFT, for cross-checking the compiled kernel.

Written as a plain time march over all pairs at once, with the tangent propagated
with respect to every gap coefficient (no stick-interval shortcut), so that it
shares no code path with jointfem.contact._kernels.
"""
import numpy as np

from jointfem.contact.jenkins import STICK, SLIP, SEPARATED, ContactError, ContactResult, JenkinsPairs
from jointfem.harmonics import Harmonics


def _phi(a, b):
    """Vectorised twin of jointfem.contact._kernels._phi (used where a > 0)."""
    cross = b <= 0
    d = np.where(cross, a - b, 1.0)
    d = np.where(d == 0, 1.0, d)
    return (np.where(cross, a * a / d, a), np.where(cross, a * (a - 2 * b) / d**2, 1.0),
            np.where(cross, a * a / d**2, 0.0))


def _march(pairs: JenkinsPairs, g_t: np.ndarray, w_start: np.ndarray, *, gamma: np.ndarray | None = None,
           gamma_inv: np.ndarray | None = None, need_T: bool = False):
    """March one period from ``w_start``.

    Without ``gamma``: returns (f_t, state_t, w_end, T) with T = dw_end/dw_start
    (only if need_T).  With ``gamma`` (N, num_hc) and ``gamma_inv``: also
    propagates d/dG and d/dw_start and returns the accumulated coefficient
    Jacobians J_G (P, num_hc, m, num_hc*m) and J_w (P, num_hc, m, nt) and
    S = dw_end/dG (P, nt, num_hc*m), T = dw_end/dw_start (P, nt, nt).
    """
    N_t, P, m = g_t.shape
    nt = pairs.num_tangential
    kt = pairs.kt[:, None]
    mu = pairs.mu
    tangent = gamma is not None
    f_t = np.zeros_like(g_t)
    state_t = np.empty((N_t, P), dtype=np.int8)
    prev_sep = (pairs.N0 + pairs.kn * g_t[-1, :, nt] <= 0) if pairs.has_normal else np.zeros(P, bool)
    w = w_start.copy()
    eye_nt = np.eye(nt)
    if tangent:
        num_hc = gamma.shape[1]
        q = num_hc * m
        nq = q + nt  # parameters: G coefficients (h'*m + b), then w_start
        dW = np.zeros((P, nt, nq))
        dW[:, :, q:] = eye_nt
        J_acc = np.zeros((num_hc, P, m, nq))
        eye_m = np.eye(m)
        chunk = max(1, min(N_t, 32))
        df_chunk = np.zeros((chunk, P, m, nq))
    elif need_T:
        T = np.broadcast_to(eye_nt, (P, nt, nt)).copy()
    for i in range(N_t):
        g = g_t[i]
        gt = g[:, :nt]
        if pairs.has_normal:
            N = pairs.N0 + pairs.kn * g[:, nt]
        else:
            N = pairs.N0
        sep = N <= 0.0
        if pairs.has_normal:
            # re-contact: the slider starts where N crosses zero between the samples
            rec = prev_sep & ~sep
            if rec.any():
                ip = (i - 1) % N_t
                n_p = pairs.N0 + pairs.kn * g_t[ip, :, nt]
                th = np.where(rec, -n_p / np.where(rec, N - n_p, 1.0), 0.0)
                gp = g_t[ip, :, :nt]
                w = np.where(rec[:, None], gp + th[:, None] * (gt - gp), w)
                if tangent:
                    for p_ in np.flatnonzero(rec):
                        row = lambda j, c: np.kron(gamma[j % N_t], np.eye(m)[c])  # noqa: E731
                        dw = np.zeros((nt, nq))
                        den = (N[p_] - n_p[p_]) ** 2
                        for a in range(nt):
                            dw[a, :q] = ((1 - th[p_]) * row(ip, a) + th[p_] * row(i, a)
                                         + (gt[p_, a] - gp[p_, a]) * pairs.kn[p_]
                                         * (-N[p_] * row(ip, nt) + n_p[p_] * row(i, nt)) / den)
                        dW[p_] = dw
            prev_sep = sep
        trial = kt * (gt - w)
        tnorm = np.sqrt(np.einsum("pa,pa->p", trial, trial))
        limit = mu * np.where(sep, 0.0, N)
        slip = (~sep) & (tnorm > limit)
        stick = (~sep) & (~slip)
        safe = np.where(tnorm > 0.0, tnorm, 1.0)
        e = trial / safe[:, None]
        ft = np.where(stick[:, None], trial, np.where(slip[:, None], limit[:, None] * e, 0.0))
        w_new = np.where(stick[:, None], w, np.where(sep[:, None], gt, gt - ft / kt))
        f_t[i, :, :nt] = ft
        if pairs.has_normal:
            # crossing-corrected normal force next to a separated sample
            n_prev = pairs.N0 + pairs.kn * g_t[(i - 1) % N_t, :, nt]
            n_next = pairs.N0 + pairs.kn * g_t[(i + 1) % N_t, :, nt]
            pa, pa_a, pa_b = _phi(N, n_next)
            pb, pb_a, pb_b = _phi(N, n_prev)
            f_t[i, :, nt] = np.where(sep, 0.0, 0.5 * (pa + pb))
        state_t[i] = np.where(sep, SEPARATED, np.where(slip, SLIP, STICK))
        if tangent:
            # dg_i/dparam: kron(gamma[i], I_m), zero on the w_start columns.
            dg = np.zeros((m, nq))
            dg[:, :q] = np.kron(gamma[i], eye_m)
            dgt = dg[:nt]
            dtrial = kt[:, :, None] * (dgt[None] - dW)  # (P, nt, nq)
            dft = np.where(stick[:, None, None], dtrial, 0.0)
            if slip.any():
                s = np.flatnonzero(slip)
                es = e[s]
                proj = eye_nt[None] - es[:, :, None] * es[:, None, :]
                d_slip = (limit[s] / tnorm[s])[:, None, None] * np.einsum("pab,pbq->paq", proj, dtrial[s])
                if pairs.has_normal:
                    dN = pairs.kn[s, None] * dg[nt][None, :]
                    d_slip += (mu[s, None] * es)[:, :, None] * dN[:, None, :]
                dft[s] = d_slip
            df = df_chunk[i % chunk]
            df[:, :nt] = dft
            if pairs.has_normal:
                row = lambda j: np.kron(gamma[j % N_t], eye_m)[nt]  # noqa: E731
                dn = np.zeros((P, nq))
                dn[:, :q] = 0.5 * pairs.kn[:, None] * ((pa_a + pb_a)[:, None] * row(i)[None]
                                                       + pa_b[:, None] * row(i + 1)[None]
                                                       + pb_b[:, None] * row(i - 1)[None])
                df[:, nt] = np.where(sep[:, None], 0.0, dn)
            dW = np.where(stick[:, None, None], dW,
                          np.where(sep[:, None, None], dgt[None], dgt[None] - dft / kt[:, :, None]))
            if (i + 1) % chunk == 0 or i == N_t - 1:
                i0 = i - (i % chunk)
                n_c = i - i0 + 1
                J_acc += np.tensordot(gamma_inv[:, i0 : i + 1], df_chunk[:n_c], axes=(1, 0))
        elif need_T:
            # dw/dw_start only (for the fixed-point Newton on the slider state)
            Tn = T.copy()
            if sep.any():
                Tn[sep] = 0.0
            if slip.any():
                s = np.flatnonzero(slip)
                es = e[s]
                proj = eye_nt[None] - es[:, :, None] * es[:, None, :]
                # w = g - (mu N/|t|)(t) / kt ... dw/dw_prev = (mu N / |t|) proj
                Tn[s] = (limit[s] / tnorm[s])[:, None, None] * np.einsum("pab,pbc->pac", proj, T[s])
            T = Tn
        w = w_new
    if tangent:
        J_acc = np.moveaxis(J_acc, 0, 1)  # (P, num_hc, m, nq)
        return f_t, state_t, w, J_acc[..., :q], J_acc[..., q:], dW[:, :, :q], dW[:, :, q:]
    return f_t, state_t, w, (T if need_T else None)


def compute_steady_slider(pairs: JenkinsPairs, g_t: np.ndarray, *, rtol: float = 1e-10, max_iter: int = 50,
                          num_plain: int = 2):
    """Steady slider state at tau = 0, marched from w = 0, pair by pair.

    Returns (w_start (P, nt), kind (P,), num_transient (P,)) with the kinds of the kernel:
    0 stuck from w = 0, 1 slipping steady period, 2 shakedown after num_transient periods.
    """
    P, nt = pairs.num_pairs, pairs.num_tangential
    w_out = np.zeros((P, nt))
    kind = np.zeros(P, dtype=int)
    ntr = np.zeros(P, dtype=int)
    for p in range(P):
        one = JenkinsPairs(kt=pairs.kt[p:p + 1], kn=pairs.kn[p:p + 1], mu=pairs.mu[p:p + 1], N0=pairs.N0[p:p + 1],
                           num_tangential=nt, has_normal=pairs.has_normal)
        g = g_t[:, p:p + 1]
        scale = max(pairs.mu[p] * abs(pairs.N0[p]) / pairs.kt[p], np.abs(g[:, :, :nt]).max())
        scale = scale if scale > 0 else 1.0
        try:
            w, kind[p], ntr[p], newton = _search(one, g, nt, scale, rtol, max_iter, num_plain)
        except ContactError:
            newton = kind[p] = None
        if kind[p] is None or (kind[p] == 2 and newton):  # follow the plain path instead
            w, kind[p], ntr[p], _ = _search(one, g, nt, scale, rtol, 8 * max_iter, 8 * max_iter)
        w_out[p] = w[0]
    return w_out, kind, ntr


def _search(one, g, nt, scale, rtol, max_iter, num_plain):
    """One search from w = 0 (twin of _kernels._steady_search): (w, kind, num_transient, newton)."""
    newton = False
    w = np.zeros((1, nt))
    for it in range(max_iter):
        _, state_t, w_end, T = _march(one, g, w, need_T=True)
        if not (state_t != STICK).any():
            return w, (0 if it == 0 else 2), it, newton
        r = w_end - w
        err = np.abs(r).max() / scale
        if it < num_plain:
            v = w_end
        else:
            newton = True
            A = np.eye(nt) - T[0]
            v = w + (np.linalg.solve(A, r[0]) if abs(np.linalg.det(A)) > 1e-12 else r[0])
        if err <= rtol:  # the next iterate is kept if its period still slips and closes better
            _, state_v, v_end, _ = _march(one, g, v)
            if (state_v != STICK).any() and np.abs(v_end - v).max() / scale <= err:
                return v, 1, it + 1, newton
            return w, 1, it, newton
        w = v
    raise ContactError("slider steady state not reached")


def compute_aft_reference(pairs: JenkinsPairs, G: np.ndarray, harmonics: Harmonics, *, jacobian: bool = True) -> ContactResult:
    """Alternating frequency-time evaluation of a group of Jenkins pairs (reference).

    G: gap coefficients, shape (num_hc, P, m), m.  Returns a ContactResult.
    The Jacobian is closed by the chain rule through w_start: kind 1 by the fixed point,
    dw*/dG = (I - T)^-1 S; kind 2 through the transient periods, S_k + T_k S_(k-1).
    """
    G = np.asarray(G, dtype=float)
    num_hc, P, m = G.shape
    g_t = harmonics.to_time(G)
    w_start, kind, ntr = compute_steady_slider(pairs, g_t)
    if not jacobian:
        f_t, state_t, _, _ = _march(pairs, g_t, w_start)
        return ContactResult(harmonics.from_time(f_t), None, f_t, g_t, state_t, w_start)
    gam, gami = harmonics.gamma, harmonics.gamma_inv
    f_t, state_t, _, J_G, J_w, S, T = _march(pairs, g_t, w_start, gamma=gam, gamma_inv=gami)
    nt = pairs.num_tangential
    J = J_G.copy()
    for p in range(P):
        if kind[p] == 1:
            dw = np.linalg.solve(np.eye(nt) - T[p], S[p])
        elif kind[p] == 2:
            dw = np.zeros_like(S[p])
            w = np.zeros((P, nt))
            for _ in range(ntr[p]):
                _, _, w_end, _, _, S_k, T_k = _march(pairs, g_t, w, gamma=gam, gamma_inv=gami)
                dw = S_k[p] + T_k[p] @ dw
                w = w_end
        else:
            continue
        J[p] += J_w[p] @ dw
    J = J.reshape(P, num_hc, m, num_hc, m)
    return ContactResult(harmonics.from_time(f_t), J, f_t, g_t, state_t, w_start)
