"""Independent NumPy reference of the Jenkins AFT, for cross-checking the compiled kernel.

Written as a plain time march over all pairs at once, with the tangent propagated
with respect to every gap coefficient (no stick-interval shortcut), so that it
shares no code path with jointfem.contact._kernels.
"""
import numpy as np

from jointfem.contact.jenkins import STICK, SLIP, SEPARATED, ContactError, ContactResult, JenkinsPairs
from jointfem.hbm.harmonics import Harmonics


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
            f_t[i, :, nt] = np.where(sep, 0.0, N)
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
                df[:, nt] = np.where(sep[:, None], 0.0, pairs.kn[:, None] * dg[nt][None, :])
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


def compute_steady_slider(pairs: JenkinsPairs, g_t: np.ndarray, *, rtol: float = 1e-12,
                          max_iter: int = 50) -> np.ndarray:
    """Slider state at tau = 0 of the periodic steady state, shape (P, nt)."""
    P = pairs.num_pairs
    nt = pairs.num_tangential
    w0 = np.zeros((P, nt))
    # Length scale for the convergence test: the slip length and the gap amplitude.
    scale = np.maximum(pairs.mu * np.abs(pairs.N0) / pairs.kt, np.abs(g_t[:, :, :nt]).max(axis=(0, 2)))
    scale = np.where(scale > 0, scale, 1.0)
    _, state_t, w1, _ = _march(pairs, g_t, w0)
    active = (state_t != STICK).any(axis=0)
    if not active.any():
        return w0  # every pair sticks about the unloaded position: linear spring
    w = np.where(active[:, None], w1, w0)
    eye = np.eye(nt)
    last = np.inf
    for _ in range(max_iter):
        _, state_t, w_end, T = _march(pairs, g_t, w, need_T=True)
        r = w_end - w
        err = np.abs(r).max(axis=1) / scale
        last = float(err.max())
        if last <= rtol:
            return w
        # Newton on the fixed point for pairs that slip in this period, plain iteration otherwise.
        moved = (state_t != STICK).any(axis=0)
        step = r.copy()
        if moved.any():
            A = eye[None] - T[moved]
            ok = np.abs(np.linalg.det(A)) > 1e-12
            idx = np.flatnonzero(moved)[ok]
            step[idx] = np.linalg.solve(A[ok], r[idx][..., None])[..., 0]
        w = w + step
    raise ContactError(
        f"slider steady state not reached after {max_iter} periods: max relative change {last:.3e} > {rtol:.1e}"
    )


def compute_aft_reference(pairs: JenkinsPairs, G: np.ndarray, harmonics: Harmonics, *, jacobian: bool = True) -> ContactResult:
    """Alternating frequency-time evaluation of a group of Jenkins pairs.

    G: gap coefficients, shape (num_hc, P, m), m.  Returns a ContactResult.
    """
    G = np.asarray(G, dtype=float)
    num_hc, P, m = G.shape
    if num_hc != harmonics.num_hc or P != pairs.num_pairs or m != pairs.num_comp:
        raise ValueError(f"gap coefficients of shape {G.shape} do not fit {harmonics} and {P} pairs x {pairs.num_comp}")
    g_t = harmonics.to_time(G)
    w_start = compute_steady_slider(pairs, g_t)
    if not jacobian:
        f_t, state_t, _, _ = _march(pairs, g_t, w_start)
        return ContactResult(harmonics.from_time(f_t), None, f_t, g_t, state_t, w_start)
    f_t, state_t, _, J_G, J_w, S, T = _march(pairs, g_t, w_start, gamma=harmonics.gamma,
                                              gamma_inv=harmonics.gamma_inv)
    # Periodicity of the slider: w* = P(w*, G)  =>  dw*/dG = (I - T)^-1 S for pairs that slip
    # or separate; a pair stuck all period keeps w* = 0, independent of G.
    moved = (state_t != STICK).any(axis=0)
    J = J_G
    if moved.any():
        nt = pairs.num_tangential
        A = np.eye(nt)[None] - T[moved]
        dw = np.linalg.solve(A, S[moved])  # (Pm, nt, q)
        J = J_G.copy()
        J[moved] += np.einsum("phac,pcq->phaq", J_w[moved], dw)
    J = J.reshape(P, num_hc, m, num_hc, m)
    return ContactResult(harmonics.from_time(f_t), J, f_t, g_t, state_t, w_start)


