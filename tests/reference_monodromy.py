"""Independent event-driven monodromy matrix of lumped oscillators with 1D Jenkins sliders, for
checking the stability that jointfem computes by Hill's method (issue 46, item 4).

Written from scratch on numpy/scipy only (no jointfem code).  Conventions as tests/reference_timeint.py:
slider p has the gap g_p = Gt[p] @ x, the slider position w_p (its memory), the force
f_p = kt_p (g_p - w_p) while stuck (|f_p| < Fs_p = mu N0, w_p constant), f_p = s Fs_p while slipping
in direction s = +-1 (w_p = g_p - s Fs_p / kt_p follows the gap); the force on the DOFs is Gt^T f.

System:  M x'' + D x' + K x + Gt^T f = fc cos(omega t) + fs sin(omega t).

State.  y = (x, v, w), of dimension 2n + P in every phase: w is kept as a state in slip too, with
w_p' = g_p' there (so g_p - w_p = s Fs_p / kt_p stays constant along a slip phase) and w_p' = 0 in
stick.  Each phase (a mode: stick / slip+ / slip- per slider) is a linear time-invariant system driven
by the harmonic force, so it is solved exactly, state and variational equation together: the
augmented state z = (y, 1, cos omega t, sin omega t) obeys z' = A_mode z, and a phase of length tau
maps z by expm(A_mode tau), whose upper-left (2n+P) block is the phase's variational matrix
(the Jacobian of the phase's flow).  No time stepping error: the flow is exact to round-off.

Events (all have the form h(y) = a . y + b crossing zero upward):
  stick -> slip s:  h = s kt (g - w) - Fs   (the stuck force reaches the slip force);
  slip s -> stick:  h = -s g'               (the relative velocity changes sign; a Jenkins slider
                                              always sticks at a reversal: in stick f' = kt g').
Within a phase every event function is sampled on a grid of T / SAMPLES and the first upward
crossing refined by brentq on the closed form; a crossing and return within one grid step (grazing)
would be missed, and a phase ending exactly at its start is not an event.

Saltation matrix at an event at time t_e (R. I. Leine and H. Nijmeijer, Dynamics and Bifurcations
of Non-Smooth Mechanical Systems, Lecture Notes in Applied and Computational Mechanics 18,
Springer 2004; after M. A. Aizerman and F. R. Gantmakher, On the stability of periodic motions,
J. Appl. Math. Mech. 22, 1958):

    S = I + (f+ - f-) a^T / (a . f-),

f- and f+ the vector fields before and after the switch at the event point.  Here (x, v) is C^1
across both kinds of event (the contact force is continuous), so S only acts on w:
  stick -> slip:  f+ - f- = (0, 0, g' e_p) and a . f- = s kt g', so S sets dw_p = dg_p: the memory
                  of a perturbation's slider position is erased (S is a rank-one-deficient projection);
  slip -> stick:  f+ - f- = 0 (g' = 0 there), S = I.
The monodromy matrix over one period T = 2 pi / omega from t0 is Phi = E_k S_k ... S_1 E_1 (E_i the
phases' variational matrices).

The extra multipliers of w.  The state has P more components than the 2n of the mechanical system:
  - a slider that slips somewhere in the period contributes one multiplier exactly 0 (its S is
    singular: after the slip onset the slider position is slaved to the gap, whatever its
    perturbation was): exponent -infinity, no dynamics; dropped as the |mu| < ZERO_MULTIPLIER ones;
  - a slider stuck over the whole period contributes a multiplier exactly 1: its row of Phi is
    e_w^T (w' = 0 always), a neutral direction that moves to a neighbouring periodic orbit with
    another slider position (a stuck joint has a continuum of steady states; jointfem picks w = 0,
    the unloaded spring).  It is dropped by deleting that row and column (exact, the matrix being
    block triangular there): the remaining 2n multipliers are those of the stuck linear system.
The remaining 2n multipliers mu_i give the Floquet exponents log(mu_i) / T (real part log|mu_i| / T,
imaginary part defined modulo omega).  Their set does not depend on t0: the monodromy matrices from
two start times are A B and B A for the two parts of the period, which have the same nonzero
eigenvalues even where the saltation matrices are singular.

Periodic orbit by shooting: Newton on y0 = P(y0) (P the period map from t0, Jacobian Phi - I;
the w of a slider stuck all the period is held at the guess's value, the rest solved), started from
a sampled guess (jointfem's HBM solution) with t0 in the middle of the longest stick interval of the
guess, so that the start state determines its mode (|f| < Fs).  The orbit is accepted when
|P(y0) - y0| <= PERIODIC_TOL (1 + |y0|).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
from scipy.optimize import brentq

SAMPLES = 512  # event bracketing grid per period
ZERO_MULTIPLIER = 1e-8  # multipliers below this (relative to the largest) are the erased slider memory
PERIODIC_TOL = 1e-11


@dataclass(frozen=True)
class JenkinsSystem:
    """M x'' + D x' + K x + Gt^T f = fc cos(omega t) + fs sin(omega t), P sliders (SI units)."""

    M: np.ndarray
    K: np.ndarray
    D: np.ndarray
    fc: np.ndarray
    fs: np.ndarray
    Gt: np.ndarray  # (P, n)
    kt: np.ndarray  # (P,)
    Fs: np.ndarray  # (P,) slip force mu N0

    @property
    def n(self) -> int:
        return self.K.shape[0]

    @property
    def P(self) -> int:
        return self.Gt.shape[0]


def sdof_system(F: float, c: float = 0.02) -> JenkinsSystem:
    """tests/conftest.py sdof(F, c): m = k = kt = mu = N0 = 1, slider to ground, damping c."""
    return JenkinsSystem(M=np.eye(1), K=np.eye(1), D=c * np.eye(1), fc=np.array([F]), fs=np.zeros(1),
                         Gt=np.eye(1), kt=np.ones(1), Fs=np.ones(1))


def chain2_system(F: float, c: float = 0.02) -> JenkinsSystem:
    """Two unit masses in a chain, springs k = 1 ground-m1 and m1-m2, dampers c from each mass to
    ground (mass-proportional: every stuck mode decays at -c/2), one Jenkins slider (kt = 1,
    Fs = 1) from m1 to ground, the force F cos(omega t) on m2."""
    return JenkinsSystem(M=np.eye(2), K=np.array([[2.0, -1.0], [-1.0, 1.0]]), D=c * np.eye(2),
                         fc=np.array([0.0, F]), fs=np.zeros(2), Gt=np.array([[1.0, 0.0]]), kt=np.ones(1),
                         Fs=np.ones(1))


@dataclass
class Event:
    t: float
    slider: int
    before: int  # mode of the slider: 0 stick, +1 / -1 slip in that direction
    after: int


@dataclass
class Run:
    y: np.ndarray  # state at the end
    Phi: np.ndarray | None  # variational matrix d y_end / d y_start (with saltations)
    events: list = field(default_factory=list)
    slip_time: np.ndarray | None = None  # time spent slipping, per slider


class Flow:
    """The exact piecewise flow of a JenkinsSystem under forcing at omega."""

    def __init__(self, system: JenkinsSystem, omega: float, samples: int = SAMPLES):
        self.s = system
        self.omega = float(omega)
        self.T = 2 * np.pi / self.omega
        self.dt = self.T / samples
        self.Minv = np.linalg.inv(system.M)
        self.ny = 2 * system.n + system.P
        self._cache: dict = {}

    # ---- one mode: the augmented matrix and its events ------------------------------------------
    def matrix(self, mode: tuple) -> np.ndarray:
        s, n, P = self.s, self.s.n, self.s.P
        A = np.zeros((self.ny + 3, self.ny + 3))
        ix, iv, iw = slice(0, n), slice(n, 2 * n), slice(2 * n, 2 * n + P)
        one, cos, sin = self.ny, self.ny + 1, self.ny + 2
        A[ix, iv] = np.eye(n)
        Bv = np.zeros((n, self.ny + 3))
        Bv[:, ix] = -s.K
        Bv[:, iv] = -s.D
        Bv[:, cos] = s.fc
        Bv[:, sin] = s.fs
        for p, m in enumerate(mode):
            G = s.Gt[p]
            if m == 0:  # stick: -G^T kt (G x - w_p)
                Bv[:, ix] -= s.kt[p] * np.outer(G, G)
                Bv[:, 2 * n + p] += s.kt[p] * G
            else:  # slip: -G^T m Fs, and w_p' = G v
                Bv[:, one] -= m * s.Fs[p] * G
                A[2 * n + p, iv] = G
        A[iv, :] = self.Minv @ Bv
        A[cos, sin] = -self.omega
        A[sin, cos] = self.omega
        return A

    def events_of(self, mode: tuple):
        """[(a, b, slider, new mode)]: h = a . y + b crosses zero upward at the event."""
        s, n = self.s, self.s.n
        out = []
        for p, m in enumerate(mode):
            G = s.Gt[p]
            if m == 0:
                for sign in (1, -1):
                    a = np.zeros(self.ny)
                    a[:n] = sign * s.kt[p] * G
                    a[2 * n + p] = -sign * s.kt[p]
                    out.append((a, -s.Fs[p], p, sign))
            else:
                a = np.zeros(self.ny)
                a[n:2 * n] = -m * G
                out.append((a, 0.0, p, 0))
        return out

    def _mode_data(self, mode):
        if mode not in self._cache:
            A = self.matrix(mode)
            self._cache[mode] = (A, sla.expm(A * self.dt), self.events_of(mode))
        return self._cache[mode]

    def _root(self, A, z0, ev, lo, hi):
        """The crossing of event ev between lo and hi (phase times), on the closed form."""
        a, b = ev[0], ev[1]

        def fun(tt):
            return a @ (sla.expm(A * tt) @ z0)[:self.ny] + b
        fa, fb = fun(lo), fun(hi)
        if fa >= 0.0:  # the grid's accumulated product and the closed form differ by round-off
            return lo
        if fb < 0.0:
            return hi
        return brentq(fun, lo, hi, xtol=1e-15, rtol=1e-15, maxiter=200)

    def field(self, y, t, mode):
        A = self._mode_data(mode)[0]
        return A[:self.ny] @ np.concatenate([y, [1.0, np.cos(self.omega * t), np.sin(self.omega * t)]])

    def mode_of(self, y) -> tuple:
        """The mode a state determines: stick where |f| < Fs, else slip in the force's direction."""
        n = self.s.n
        f = self.s.kt * (self.s.Gt @ y[:n] - y[2 * n:])
        return tuple(0 if abs(fp) < Fs else int(np.sign(fp)) for fp, Fs in zip(f, self.s.Fs))

    # ---- the flow ------------------------------------------------------------------------------
    def run(self, t0: float, y0: np.ndarray, duration: float, *, mode: tuple | None = None,
            variational: bool = False) -> Run:
        """Propagate y0 from t0 over ``duration``, locating events; with the variational matrix."""
        y = np.array(y0, dtype=float)
        mode = self.mode_of(y) if mode is None else tuple(mode)
        t, t_end = float(t0), float(t0) + duration
        Phi = np.eye(self.ny) if variational else None
        events = []
        slip_time = np.zeros(self.s.P)
        while True:
            A, Edt, evs = self._mode_data(mode)
            z0 = np.concatenate([y, [1.0, np.cos(self.omega * t), np.sin(self.omega * t)]])
            remaining = t_end - t
            hit = None  # (tau, event)
            z_prev, tau_prev = z0, 0.0
            h_prev = [a @ z0[:self.ny] + b for a, b, _, _ in evs]
            while tau_prev < remaining and hit is None:
                full = tau_prev + self.dt <= remaining
                tau = tau_prev + self.dt if full else remaining
                z = Edt @ z_prev if full else sla.expm(A * tau) @ z0
                h = [a @ z[:self.ny] + b for a, b, _, _ in evs]
                cands = [(self._root(A, z0, evs[k], tau_prev, tau), k)
                         for k in range(len(evs)) if h_prev[k] < 0.0 <= h[k]]
                if cands:
                    hit = min(cands)
                z_prev, tau_prev, h_prev = z, tau, h
            tau = hit[0] if hit is not None else remaining
            E = sla.expm(A * tau)
            y = (E @ z0)[:self.ny]
            for p, m in enumerate(mode):
                if m != 0:
                    slip_time[p] += tau
            t += tau
            if variational:
                Phi = E[:self.ny, :self.ny] @ Phi
            if hit is None:
                break
            a, b, p, new = evs[hit[1]]
            new_mode = tuple(new if q == p else m for q, m in enumerate(mode))
            if variational:
                f_minus, f_plus = self.field(y, t, mode), self.field(y, t, new_mode)
                S = np.eye(self.ny) + np.outer(f_plus - f_minus, a) / (a @ f_minus)
                Phi = S @ Phi
            events.append(Event(t, p, mode[p], new))
            if new != 0:  # exactly on the slip manifold (remove the round-off of the event time)
                n = self.s.n
                y[2 * n + p] = self.s.Gt[p] @ y[:n] - new * self.s.Fs[p] / self.s.kt[p]
            mode = new_mode
        return Run(y, Phi, events, slip_time)


@dataclass
class Orbit:
    system: JenkinsSystem
    omega: float
    t0: float
    y0: np.ndarray
    T: float
    residual: float  # max |P(y0) - y0| / (1 + max |y0|)
    newton_iterations: int
    events: list
    slip_share: np.ndarray  # per slider, fraction of the period slipping
    Phi: np.ndarray  # monodromy matrix from t0


def guess_from_samples(system: JenkinsSystem, omega: float, x_t: np.ndarray):
    """(t0, y0) from samples x_t (N, n) of a periodic displacement at t_i = i T / N (jointfem's HBM
    solution): velocity by spectral differentiation, the slider by marching the Jenkins law over
    three periods from w = 0, t0 in the middle of the longest stick interval of the last period
    (of slider 0, and of every slider if they share one)."""
    x_t = np.asarray(x_t, float).reshape(len(x_t), -1)
    N = x_t.shape[0]
    k = np.fft.rfftfreq(N, 1.0 / N)
    v_t = np.fft.irfft(1j * k[:, None] * omega * np.fft.rfft(x_t, axis=0), n=N, axis=0)
    g = x_t @ system.Gt.T  # (N, P)
    w = np.zeros(system.P)
    W = np.zeros((3 * N, system.P))
    stick = np.zeros((3 * N, system.P), bool)
    for i in range(3 * N):
        f = system.kt * (g[i % N] - w)
        slip = np.abs(f) > system.Fs
        w = np.where(slip, g[i % N] - np.sign(f) * system.Fs / system.kt, w)
        W[i], stick[i] = w, ~slip
    W, stick = W[2 * N:], stick[2 * N:]
    all_stick = stick.all(axis=1)
    if all_stick.all():
        i0 = 0
    else:
        # longest run of all_stick, cyclically
        s2 = np.concatenate([all_stick, all_stick])
        best, start, run = (0, 0), 0, 0
        for i, st in enumerate(s2):
            run = run + 1 if st else 0
            if run > best[0] and run <= N:
                best = (run, i - run + 1)
        if best[0] == 0:
            raise ValueError("no instant with every slider stuck: choose t0 by hand")
        i0 = (best[1] + best[0] // 2) % N
    t0 = 2 * np.pi / omega * i0 / N
    return t0, np.concatenate([x_t[i0], v_t[i0], W[i0]])


def periodic_orbit(system: JenkinsSystem, omega: float, t0: float, y0: np.ndarray, *,
                   max_iter: int = 30, samples: int = SAMPLES) -> Orbit:
    """Shooting: Newton on P(y0) = y0 from the guess (t0, y0) (guess_from_samples)."""
    flow = Flow(system, omega, samples)
    y = np.array(y0, float)
    n = system.n
    for it in range(max_iter + 1):
        r = flow.run(t0, y, flow.T, variational=True)
        R = r.y - y
        res = np.abs(R).max() / (1.0 + np.abs(y).max())
        if res <= PERIODIC_TOL:
            break
        if it == max_iter:
            raise RuntimeError(f"shooting did not converge: residual {res:.2e}")
        slipped = {e.slider for e in r.events}
        free = [i for i in range(flow.ny) if i < 2 * n or (i - 2 * n) in slipped]
        J = r.Phi - np.eye(flow.ny)
        y[free] -= np.linalg.solve(J[np.ix_(free, free)], R[free])
    if any(m != 0 for m in flow.mode_of(y)):
        raise RuntimeError("the orbit's start state is not stuck: choose another t0")
    share = r.slip_time / flow.T
    return Orbit(system, float(omega), float(t0), y, flow.T, float(res), it, r.events, share, r.Phi)


def floquet(orbit: Orbit) -> tuple[np.ndarray, np.ndarray]:
    """(exponents (2n,), dropped multipliers) of the orbit: log(mu) / T of the 2n physical
    multipliers, largest real part first (see the module docstring for the P dropped ones)."""
    s, Phi, n = orbit.system, orbit.Phi, orbit.system.n
    slipped = sorted({e.slider for e in orbit.events})
    stuck = [p for p in range(s.P) if p not in slipped]
    keep = [i for i in range(Phi.shape[0]) if i < 2 * n or (i - 2 * n) not in stuck]
    dropped = [1.0] * len(stuck)
    for p in stuck:  # a slider stuck all the period: w' = 0, its row is exactly e_w
        row = Phi[2 * n + p].copy()
        row[2 * n + p] -= 1.0
        assert np.abs(row).max() < 1e-12, "a stuck slider's row of the monodromy matrix is not e_w"
    mu = np.linalg.eigvals(Phi[np.ix_(keep, keep)])
    order = np.argsort(np.abs(mu))
    zero, mu = mu[order[:len(slipped)]], mu[order[len(slipped):]]
    if len(slipped):
        assert np.abs(zero).max() < ZERO_MULTIPLIER * np.abs(mu).max(), ("memory multipliers not zero", zero, mu)
    dropped = np.concatenate([zero, dropped])
    expo = np.log(mu.astype(complex)) / orbit.T
    return expo[np.argsort(-expo.real, kind="stable")], dropped


def leading_exponent(orbit: Orbit) -> complex:
    """The Floquet exponent with the largest real part, imaginary part folded into
    [0, omega / 2] (as jointfem reports a complex pair by its member with Im s > 0)."""
    s = floquet(orbit)[0][0]
    im = np.mod(s.imag + orbit.omega / 2, orbit.omega) - orbit.omega / 2
    return complex(s.real, abs(im))


def flow_map_fd(orbit: Orbit, eps: float = 1e-6) -> np.ndarray:
    """d P / d y0 by central differences of the period map (events located afresh for every
    perturbed start): the check of the variational matrices and saltation matrices."""
    flow = Flow(orbit.system, orbit.omega)
    ny = flow.ny
    J = np.empty((ny, ny))
    for j in range(ny):
        d = np.zeros(ny)
        d[j] = eps
        mode = flow.mode_of(orbit.y0)
        J[:, j] = (flow.run(orbit.t0, orbit.y0 + d, flow.T, mode=mode).y
                   - flow.run(orbit.t0, orbit.y0 - d, flow.T, mode=mode).y) / (2 * eps)
    return J


def sample_orbit(orbit: Orbit, N: int) -> tuple[np.ndarray, np.ndarray]:
    """(x (N, n), w (N, P)) at t_i = i T / N (for comparison with the HBM solution), by propagating
    from t0 sample to sample."""
    flow = Flow(orbit.system, orbit.omega)
    n = orbit.system.n
    ts = orbit.T * np.arange(N) / N
    k0 = int(np.ceil(orbit.t0 / orbit.T * N - 1e-12)) % N
    x = np.empty((N, n))
    w = np.empty((N, orbit.system.P))
    y, t = orbit.y0.copy(), orbit.t0
    for j in range(N):
        i = (k0 + j) % N
        target = ts[i] + (orbit.T if ts[i] < t - 1e-12 else 0.0)
        if target > t:
            y = flow.run(t, y, target - t).y
            t = target
        x[i], w[i] = y[:n], y[2 * n:]
    return x, w
