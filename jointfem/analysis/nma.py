"""Nonlinear modes: frequency and damping against amplitude by the extended periodic motion
concept (EPMC; Krack 2015, J. Sound Vib. 339, "Nonlinear modal analysis of nonconservative
systems: extension of the periodic motion concept").

The free, unforced structure gets a self-excitation term that makes its damped motion periodic:

    M u'' + (D - xi M) u' + K u + f_nl(u, u') = f_static,

xi (1/s) being an unknown that cancels the dissipation of a period exactly.  The modal damping
ratio is zeta = xi / (2 omega) (Krack's D), the convention of NLvib and tmdsimpy.  In HBM, with
the harmonic force of the scene removed and the static one kept, the residual of any problem of
the protocol (hbm.problem) is

    R_e(x, omega, xi; a) = (R(U_s + a x, omega) + F_h) / a - xi omega (nabla (x) M) x,

U_s the static state (the preload alone), a the amplitude (the parameter, continued in log10 a)
and x the motion per unit amplitude, normalised so that the first harmonic of the ``output``
is cos(tau): c_1 = 1, s_1 = 0 there (the amplitude is measured where the user says, in m, and the
phase of the autonomous motion is fixed).  F_h = -R(0) on the harmonic blocks (the contact forces
vanish at zero gaps: R(0) = -F), and nabla (x) M = (nabla (x) I) Delta2, with Delta2 = I (x) M
the problem's Hill operator: any problem with Hill operators has nonlinear modes (full order,
the Galerkin ROMs, the penalty ROM with its active set).  The exact condensation, which has none,
carries xi M inside its dynamic stiffness instead (CondensedModalProblem).

Per point: omega (rad/s), zeta, the energy dissipated per cycle (W = xi pi omega sum_k k^2
(c_k^T M c_k + s_k^T M s_k), the self-excitation's input, equal to the dissipation of a period),
the joints' share of it (the contact pairs' own hysteresis energy), the contact states, and the
harmonic truncation estimate (analysis.convergence).
"""
from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..continuation.arclength import (Adaptive, ContinuationError, ContinuationOptions, ConvergenceError,
                                     continue_branch, solve_adaptive)
from ..harmonics import Harmonics
from ..hbm.condensed import CondensedProblem
from ..hbm.problem import Evaluation, Problem, Scales, newton_system
from ..linalg import eigen, with_sweep_blas
from ..models.structure import Structure
from ..results import first_harmonic_amplitude
from ..rom.common import Reduction
from .convergence import top_harmonic_share
from .frf import create_problem

log = logging.getLogger(__name__)
LN10 = math.log(10.0)


class NmaError(ValueError):
    """Nonlinear modes cannot be computed for this problem or these options (names the reason)."""


class ModalProblem(Problem):
    """The EPMC of an inner (forced) problem: coefficients x (the inner's, per unit amplitude),
    then omega (rad/s) and xi (1/s); lam = log10 of the amplitude at ``output`` (m)."""

    EXCITATIONS = ("all", "fundamental")

    def __init__(self, inner: Problem, mode: int, output: str, *, excitation: str = "all"):
        self._check(inner)
        if output not in inner.layout.outputs:
            raise NmaError(f"output {output!r} is not one of the model's outputs {sorted(inner.layout.outputs)}")
        if excitation not in self.EXCITATIONS:
            raise NmaError(f"self-excitation {excitation!r}: choose one of {', '.join(self.EXCITATIONS)}")
        self.inner, self.mode, self.output, self.excitation = inner, int(mode), output, excitation
        self.harmonics, self.layout, self.tol_floor = inner.harmonics, inner.layout, inner.tol_floor
        self.adaptation = None if inner.adaptation is None else _Modal(self)
        self.nc = inner.num_coefficients
        q = self.layout.num_coords
        o = inner.layout.outputs[output]
        self._out = np.zeros(q)
        if np.ndim(o):
            self._out[:] = o
        else:
            self._out[int(o)] = 1.0
        self._ops: _Ops | None = None
        self.static = np.zeros(self.nc)
        self._static_state()
        self.omega0, self.xi0, self.shape0, self.r_scale = self._linear_mode()

    @staticmethod
    def _check(inner: Problem) -> None:
        if inner.hill_operators(1.0) is None:
            raise NmaError("nonlinear modes need the mass operator of the problem (Hill's Delta2), which this "
                           "method does not have: use full order, a ROM or the exact condensation")

    # --- what the inner problem gives, over its unknowns now ------------------------------------
    def _inner_unknowns(self) -> np.ndarray:
        u = self.inner.unknowns()
        return np.arange(self.nc) if u is None else u

    def _operators(self) -> "_Ops":
        """The operators for the inner unknowns now (taken again when they change: the penalty ROM's
        active set); with ``excitation = "fundamental"``, nabla of the first harmonic only."""
        u = self._inner_unknowns()
        if self._ops is None or not np.array_equal(self._ops.u, u):
            qn = u.size // self.harmonics.num_hc
            Fh = -self.inner.evaluate(np.zeros(self.nc), 1.0, jacobian=False).R
            Fh[:qn] = 0.0  # the static force stays
            d2 = self.inner.hill_operators(1.0)[1]
            nab = self.harmonics.derivative_matrix()
            if self.excitation == "fundamental":
                first = self.harmonics.orders == 1
                nab = nab * np.outer(first, first)
            NI = sp.csr_matrix(sp.kron(sp.csr_matrix(nab), sp.identity(qn)))
            self._ops = _Ops(u, qn, Fh, sp.csr_matrix(NI @ d2), NI, d2)
        return self._ops

    def _static_state(self) -> None:
        """U_s: the static state under the preload alone (no motion), by Newton on the zeroth
        harmonic of the inner problem."""
        ops = self._operators()
        u, qn = ops.u, ops.qn
        U = np.zeros(self.nc)
        ref = None
        for _ in range(30):
            ev = self.inner.evaluate(U, 1.0, jacobian=True)
            if ref is None:  # at U = 0: R(0) = -F, the external force
                ref = max(float(np.abs(ev.R).max(initial=0.0)), float(np.abs(ops.Fh).max(initial=0.0)), 1e-300)
            r = (ev.R + ops.Fh)[:qn]
            if np.abs(r).max(initial=0.0) <= 1e-12 * ref:
                break
            J = ev.J[:qn, :qn]
            U[u[:qn]] -= spla.spsolve(J.tocsc(), r) if sp.issparse(J) else np.linalg.solve(J, r)
        else:
            raise NmaError(f"the static state under the preload did not converge: max|R0| = {np.abs(r).max():.3e} N")
        self.static = U

    def _linear_mode(self):
        """The stuck linear mode ``mode`` at the static state: (omega, xi, x per unit amplitude at
        the output over every coefficient, residual scale)."""
        ops = self._operators()
        u, qn = ops.u, ops.qn
        ev = self.inner.evaluate(self.static, 0.0, jacobian=True)  # J(U_s, omega = 0) = I (x) K_lin
        d1, d2 = self.inner.hill_operators(0.0)  # at omega = 0: I (x) D, I (x) M
        blk = slice(qn, 2 * qn)  # the cosine of the first harmonic
        K, M, D = (A[blk, blk] for A in (ev.J, d2, d1))
        try:
            w2, Phi = eigen(K, M, self.mode, what="nma: the stuck linear structure")
        except Exception as exc:
            raise NmaError(f"mode {self.mode}: {exc}") from None
        phi = Phi[:, self.mode - 1]
        coords = u[:qn]
        at_out = float(self._out[coords] @ phi)
        if abs(at_out) < 1e-9 * np.abs(phi).max() * np.abs(self._out).max():
            raise NmaError(f"output {self.output!r} does not move in mode {self.mode} (a node of the mode): "
                           f"measure the amplitude at another output ([nma] output)")
        xi = float(phi @ (D @ phi))  # mass-normalised phi: the linear mode's 2 zeta omega
        x = np.zeros(self.nc)
        x[u[blk]] = phi / at_out
        r = float(max(w2[self.mode - 1], 0.0) * np.abs(M @ (phi / at_out)).max())
        return float(np.sqrt(w2[self.mode - 1])), xi, x, max(r, 1e-300)

    # --- the protocol ------------------------------------------------------------------------------
    @property
    def num_coefficients(self) -> int:
        return self.nc + 2

    def unknowns(self):
        u = self.inner.unknowns()
        return None if u is None else np.concatenate([u, [self.nc, self.nc + 1]])

    def physical(self, x: np.ndarray, lam: float) -> np.ndarray:
        """The inner problem's coefficients U = U_s + a x (m) of a point."""
        return self.static + 10.0 ** lam * x[:self.nc]

    def _norm_rows(self, u) -> np.ndarray:
        """The amplitude and phase rows over the inner unknowns u: o on the first harmonic's blocks."""
        h, q = self.harmonics, self.layout.num_coords
        row_c, row_s = np.zeros(self.nc), np.zeros(self.nc)
        row_c[h.cos(1, q)], row_s[h.sin(1, q)] = self._out, self._out
        return self.r_scale * np.vstack([row_c[u], row_s[u]])

    def _norm_residual(self, x) -> np.ndarray:
        h, q = self.harmonics, self.layout.num_coords
        return self.r_scale * np.array([self._out @ x[h.cos(1, q)] - 1.0, self._out @ x[h.sin(1, q)]])

    def evaluate(self, x, lam, *, jacobian=True) -> Evaluation:
        a = 10.0 ** lam
        omega, xi = float(x[self.nc]), float(x[self.nc + 1])
        ops = self._operators()
        u, NM = ops.u, ops.NM
        ev = self.inner.evaluate(self.physical(x, lam), omega, jacobian=jacobian)
        xu = x[u]
        nmx = NM @ xu
        R_dyn = (ev.R + ops.Fh) / a - xi * omega * nmx
        R = np.concatenate([R_dyn, self._norm_residual(x)])
        if not jacobian:
            return Evaluation(R, None, None, ev.contact)
        rows = self._norm_rows(u)
        col_w = ev.dR_dlam / a - xi * nmx
        col_xi = -omega * nmx
        dR = np.concatenate([LN10 * (ev.J @ xu - R_dyn - xi * omega * nmx), [0.0, 0.0]])
        if sp.issparse(ev.J):
            Jd = (ev.J - (xi * omega) * NM).tocsr()
            J = sp.bmat([[Jd, sp.csr_matrix(np.column_stack([col_w, col_xi]))],
                         [sp.csr_matrix(rows), None]], format="csr")
        else:
            Jd = np.asarray(ev.J) - (xi * omega) * NM.toarray()
            J = np.block([[Jd, col_w[:, None], col_xi[:, None]], [rows, np.zeros((2, 2))]])
        return Evaluation(R, J, dR, ev.contact)

    def initial_guess(self, lam):
        x = np.zeros(self.num_coefficients)
        x[:self.nc] = self.shape0
        x[self.nc], x[self.nc + 1] = self.omega0, self.xi0
        return x

    def scales(self, lam_start, lam_end) -> Scales:
        """Per coordinate, the larger of the linear mode's amplitude and the inner problem's own
        scale near the mode (brought to the mode's size: a ROM's scales hold the amplitude at which
        a basis vector alone reaches the largest displacement, hbm.forced.compute_rom_scales, which
        a joint that slips excites however little the mode moves it; without them the arclength
        is dominated by those coordinates at the onset of slip, measured on a CB ROM of the lap
        joint); at least 1e-3 of the largest.  omega0 for omega and for xi."""
        q = self.layout.num_coords
        blk = self.harmonics.cos(1, q)
        per = np.abs(self.shape0[blk])
        top = per.max()
        own = self.inner.scales(0.99 * self.omega0, 1.01 * self.omega0).x[blk]
        if np.all(np.isfinite(own)) and own.max() > 0:
            per = np.maximum(per, own * (top / own.max()))
        per = np.where(per > 0, np.maximum(per, 1e-3 * top), top)
        x = Scales.from_coordinates(per, self.harmonics, self.r_scale).x
        return Scales(np.concatenate([x, [self.omega0, self.omega0]]), self.r_scale)

    def record(self, x, lam, evaluation):
        return self.inner.record(self.physical(x, lam), float(x[self.nc]), evaluation)

    def branch_info(self) -> dict:
        return self.inner.branch_info()

    # per point quantities
    def energy_per_cycle(self, x: np.ndarray, lam: float) -> float:
        """The energy the self-excitation puts in per period, which the structure dissipates, J."""
        ops = self._operators()
        y = ops.NI @ x[ops.u]
        return float(x[self.nc + 1] * math.pi * x[self.nc] * 10.0 ** (2 * lam) * (y @ (ops.d2 @ y)))

    def modal_terms(self, x: np.ndarray) -> tuple[float, complex]:
        """(modal mass psi^H M psi, kg; modal force psi^H F, N) of the first harmonic psi = c_1 - i s_1
        per unit output amplitude, F = fc - i fs the scene's harmonic force (single nonlinear mode
        theory, ``synthesize_frf``)."""
        ops = self._operators()
        qn, Fh = ops.qn, ops.Fh
        xu = x[ops.u]
        c, s = xu[qn:2 * qn], xu[2 * qn:3 * qn]
        M = ops.d2[qn:2 * qn, qn:2 * qn]
        m = float(c @ (M @ c) + s @ (M @ s))
        f = complex((c + 1j * s) @ (Fh[qn:2 * qn] - 1j * Fh[2 * qn:3 * qn]))
        return m, f


class CondensedModalProblem(ModalProblem):
    """The EPMC in the exact condensation (hbm.condensed): the self-excitation -xi M u' enters each
    excited harmonic's dynamic stiffness, Z_k = K - (k omega)^2 M + i k omega (D - xi M), so S_k
    depends on xi (dS/dxi = S X^T (i k omega M) X S) and is exact, with the contact gaps and outputs
    as the only unknowns.  The energy and the modal mass are those of the full field, u_k = T_k y_k
    (T_k = Z_k^-1 C^T S_k), per harmonic.  The preload needs no static solve (f0 balances the
    stuck contact at zero gap: U_s = 0; a static force is refused by the condensation itself)."""

    @staticmethod
    def _check(inner: Problem) -> None:
        pass

    def _inner_unknowns(self) -> np.ndarray:
        return np.arange(self.nc)

    def _static_state(self) -> None:
        self.static = np.zeros(self.nc)

    @property
    def _orders(self) -> tuple:
        return (1,) if self.excitation == "fundamental" else tuple(range(1, self.harmonics.H + 1))

    def _linear_mode(self):
        inner: CondensedProblem = self.inner
        try:
            omega, phi, xi = inner.linear_mode(self.mode)
        except Exception as exc:
            raise NmaError(f"mode {self.mode}: {exc}") from None
        y = inner.C @ phi  # the gaps and outputs of the mode
        at_out = float(self._out @ y)
        if abs(at_out) < 1e-9 * np.abs(phi).max():
            raise NmaError(f"output {self.output!r} does not move in mode {self.mode} (a node of the mode): "
                           f"measure the amplitude at another output ([nma] output)")
        q = self.layout.num_coords
        x = np.zeros(self.nc)
        x[self.harmonics.cos(1, q)] = y / at_out
        r = float(omega**2 * np.abs(inner.full.M @ (phi / at_out)).max())
        return omega, xi, x, max(r, 1e-300)

    def evaluate(self, x, lam, *, jacobian=True) -> Evaluation:
        a = 10.0 ** lam
        omega, xi = float(x[self.nc]), float(x[self.nc + 1])
        ev, dRxi = self.inner.evaluate_self_excited(a * x[:self.nc], omega, xi, self._orders, jacobian=jacobian)
        R_dyn = ev.R / a
        R = np.concatenate([R_dyn, self._norm_residual(x)])
        if not jacobian:
            return Evaluation(R, None, None, ev.contact)
        xu = x[:self.nc]
        J = np.block([[ev.J, (ev.dR_dlam / a)[:, None], (dRxi / a)[:, None]],
                      [self._norm_rows(np.arange(self.nc)), np.zeros((2, 2))]])
        dR = np.concatenate([LN10 * (ev.J @ xu - R_dyn), [0.0, 0.0]])
        return Evaluation(R, J, dR, ev.contact)

    def _fields(self, x) -> list[np.ndarray]:
        return self.inner.harmonic_fields(x[:self.nc], float(x[self.nc]), float(x[self.nc + 1]), self._orders)

    def energy_per_cycle(self, x: np.ndarray, lam: float) -> float:
        M = self.inner.full.M
        u = self._fields(x)
        q = sum(k * k * float(np.real(np.conj(u[k]) @ (M @ u[k]))) for k in self._orders)
        return float(x[self.nc + 1] * math.pi * x[self.nc] * 10.0 ** (2 * lam) * q)

    def modal_terms(self, x: np.ndarray) -> tuple[float, complex]:
        u1 = self._fields(x)[1]
        full = self.inner.full
        m = float(np.real(np.conj(u1) @ (full.M @ u1)))
        return m, complex(np.conj(u1) @ (full.fc - 1j * full.fs))


def modal_problem(inner: Problem, mode: int, output: str, *, excitation: str = "all") -> ModalProblem:
    """The EPMC of a problem of the protocol: through its Hill operators, or inside the exact
    condensation's dynamic stiffness."""
    cls = CondensedModalProblem if isinstance(inner, CondensedProblem) else ModalProblem
    return cls(inner, mode, output, excitation=excitation)


@dataclass(frozen=True)
class _Ops:
    """What ModalProblem takes from its inner problem for one set of inner unknowns u (qn per
    harmonic block): F_h, nabla (x) M and nabla (x) I (nabla of the excited harmonics), Delta2."""

    u: np.ndarray
    qn: int
    Fh: np.ndarray
    NM: sp.csr_matrix
    NI: sp.csr_matrix
    d2: sp.spmatrix


class _Modal(Adaptive):
    """The inner problem's hooks on the physical coefficients and omega of a point."""

    def __init__(self, outer: ModalProblem):
        self.outer = outer
        self.inner = outer.inner.adaptation
        self.max_redo = self.inner.max_redo

    def unknowns(self):
        return self.outer.unknowns()

    def state_of(self, x):
        return self.inner.state_of(x[:self.outer.nc])

    def before_step(self, x, lam) -> bool:
        return self.inner.before_step(self.outer.physical(x, lam), float(x[self.outer.nc]))

    def after_converge(self, x, lam) -> bool:
        return self.inner.after_converge(self.outer.physical(x, lam), float(x[self.outer.nc]))

    def restore(self, state) -> None:
        self.inner.restore(state)


@dataclass(frozen=True)
class NmaOptions:
    mode: int = 1  # the stuck linear mode continued (1 = the lowest)
    amplitude_start: float = 1e-6  # m, first-harmonic amplitude at ``output``
    amplitude_end: float = 1e-3
    output: str | None = None  # where the amplitude is measured (None: the model's first output)
    # the self-excitation -xi M u' on every harmonic ("all": Krack 2015, as NLvib and tmdsimpy), or
    # on the fundamental only ("fundamental"), which leaves the higher harmonics their physical
    # damping: a mode near an internal resonance then does not pump energy into the other mode
    excitation: str = "all"
    harmonics: Harmonics = Harmonics(5, 256)
    continuation: ContinuationOptions = field(default_factory=ContinuationOptions)
    harmonic_tol: float = 0.05  # warn above this truncation estimate (as SweepOptions.harmonic_tol)
    # amplitudes (m) at which the mode is also solved exactly, by Newton at that amplitude from the
    # nearest branch point (Backbone.info["at"]): to compare backbones at the same amplitudes
    at: tuple[float, ...] = ()


@dataclass
class Backbone:
    """A nonlinear mode along its amplitude.

    amplitude: (points,) first-harmonic amplitude at ``output``, m.  omega: rad/s.  xi: the
    self-excitation, 1/s; zeta = xi / (2 omega).  U: (points, coefficients) the physical harmonic
    coefficients (layout of ``outputs``).  states: (points, N, pairs) int8.  info["arrays"]: the
    per-point data by name (energy_J, joint_energy_J, modal_mass_kg, modal_force_N, ...).
    """

    output: str
    mode: int
    amplitude: np.ndarray
    omega: np.ndarray
    xi: np.ndarray
    U: np.ndarray
    states: np.ndarray
    harmonics: Harmonics
    outputs: dict
    pair_names: tuple = ()
    info: dict = field(default_factory=dict)
    pair_coords: np.ndarray | None = None  # (pairs, 3) m, for the interface pictures
    pair_areas: np.ndarray | None = None  # (pairs,) m^2, for the per-area quantities

    @property
    def zeta(self) -> np.ndarray:
        """Modal damping ratio (Krack's D = xi / (2 omega))."""
        return self.xi / (2.0 * self.omega)

    @property
    def num_points(self) -> int:
        return self.omega.size

    def output_amplitude(self, name: str) -> np.ndarray:
        """First-harmonic amplitude of an output at every point, m."""
        return first_harmonic_amplitude(self.U, self.harmonics, self.outputs[name])


class NmaIncomplete(ContinuationError):
    """A backbone that stopped before amplitude_end: ``backbone`` holds its converged points."""

    def __init__(self, message: str, *, backbone: Backbone, points=None, interrupted: bool = False):
        super().__init__(message, points=points, interrupted=interrupted)
        self.backbone = backbone


@with_sweep_blas
def compute_backbone(model: Structure | Reduction, options: NmaOptions, *, callback=None) -> Backbone:
    """The nonlinear mode ``options.mode`` of a model from amplitude_start (the stuck linear mode
    there, refined by Newton) to amplitude_end, by arclength continuation in log10 of the amplitude."""
    a0, a1 = options.amplitude_start, options.amplitude_end
    if not 0 < a0 < a1:
        raise NmaError(f"amplitudes must be 0 < start < end, got {a0}, {a1}")
    t0 = time.perf_counter()
    inner = create_problem(model, options.harmonics)
    output = options.output or next(iter(inner.layout.outputs), None)
    if output is None:
        raise NmaError("the model has no output at which to measure the amplitude")
    problem = modal_problem(inner, options.mode, output, excitation=options.excitation)
    lam0, lam1 = math.log10(a0), math.log10(a1)
    sc = problem.scales(lam0, lam1)
    cont = options.continuation
    if cont.lam_bounds is None:
        cont = replace(cont, lam_bounds=(lam0 - (lam1 - lam0), lam1 + (lam1 - lam0)))
    if cont.newton.tol < problem.tol_floor:
        cont = replace(cont, newton=replace(cont.newton, tol=problem.tol_floor))
    h = options.harmonics
    t_setup = time.perf_counter() - t0

    def record(x, lam):
        ev = problem.evaluate(x, lam, jacobian=False)
        rec = replace(problem.record(x, lam, ev), harmonic_error=top_harmonic_share(ev.contact, h),
                      unknowns=problem.num_unknowns)
        m, f = problem.modal_terms(x)
        return rec, problem.energy_per_cycle(x, lam), m, f

    steps = {}
    stopped = None
    t1 = time.perf_counter()
    try:
        points = continue_branch(newton_system(problem), problem.initial_guess(lam0), lam0, lam1, x_scale=sc.x,
                                 lam_scale=lam1 - lam0, r_scale=sc.r, options=cont, callback=callback,
                                 extra=record, adapt=problem.adaptation, stats=steps)
    except ContinuationError as exc:
        if len(exc.points) < 2:
            raise
        points, stopped = exc.points, exc
    lam = np.array([p.lam for p in points])
    X = np.array([p.x for p in points])
    recs = [p.extra[0] for p in points]
    at = _solve_at(problem, points, options.at, sc, cont) if stopped is None or not stopped.interrupted else {}
    nc = problem.nc
    U = problem.static[None, :] + (10.0 ** lam)[:, None] * X[:, :nc]
    info = {"time_setup_s": t_setup, "time_online_s": time.perf_counter() - t1, "continuation": steps,
            "num_unknowns": int(max(r.unknowns for r in recs)), "newton_tol": cont.newton.tol,
            "excitation": options.excitation, "linear_omega_rad_s": problem.omega0, "linear_zeta": problem.xi0 / (2 * problem.omega0),
            "status": "complete" if stopped is None else "incomplete", "at": at,
            # the EPMC is a model of the damped free decay, not a motion of the structure: no stability
            "stability": "not applicable (nonlinear modes: the EPMC's self-excited motion is not a response)",
            "arrays": {"residual": np.array([p.residual for p in points]),
                       "iterations": np.array([p.iterations for p in points]),
                       "energy_J": np.array([p.extra[1] for p in points]),
                       "joint_energy_J": np.array([r.pair_summary[:, 0].sum() for r in recs]),
                       "pair_energy_J": np.array([r.pair_summary[:, 0] for r in recs]),
                       "pair_tangential_amp_m": np.array([r.pair_summary[:, 1] for r in recs]),
                       "pair_peak_normal_N": np.array([r.pair_summary[:, 2] for r in recs]),
                       "modal_mass_kg": np.array([p.extra[2] for p in points]),
                       "modal_force_N": np.array([p.extra[3] for p in points]),
                       "harmonic_error": np.array([r.harmonic_error for r in recs]),
                       "rom_size": np.array([r.size for r in recs]),
                       "unknowns": np.array([r.unknowns for r in recs])}}
    if stopped is not None:
        info["stop_reason"] = (str(stopped).replace("lam = ", "log10(amplitude [m]) = ")
                               .replace("lam_end", "amplitude_end").replace(" (lam_bounds)", ""))
    info.update(problem.branch_info())
    warnings = []
    he = info["arrays"]["harmonic_error"]
    if he.max() > options.harmonic_tol:
        k = int(np.argmax(he))
        warnings.append(f"harmonic truncation estimate {he[k]:.3g} > {options.harmonic_tol:g} at amplitude "
                        f"{10.0 ** lam[k]:.6g} m: more harmonics are needed there (H = {h.H})")
    back = np.flatnonzero(np.diff(lam) < 0)
    if back.size:
        warnings.append(f"the backbone turns back in amplitude at {10.0 ** lam[back[0]]:.6g} m (omega "
                        f"{X[back[0], nc]:.6g} rad/s)" + (": the self-excitation may be feeding a higher harmonic "
                        "(an internal resonance); self_excitation = \"fundamental\" excites the fundamental only"
                        if options.excitation == "all" else ""))
    for w_ in warnings:
        log.warning("nma: %s", w_)
    if warnings:
        info["warnings"] = warnings
    bb = Backbone(output, options.mode, 10.0 ** lam, X[:, nc], X[:, nc + 1], U,
                  np.array([r.states for r in recs], dtype=np.int8), h, dict(problem.layout.outputs),
                  problem.layout.pair_names, info, problem.layout.pair_coords, problem.layout.pair_areas)
    if stopped is not None:
        raise NmaIncomplete(info["stop_reason"], backbone=bb, points=points, interrupted=stopped.interrupted)
    return bb


def _solve_at(problem: ModalProblem, points, amplitudes, sc: Scales, cont: ContinuationOptions) -> dict:
    """{amplitude: {"omega_rad_s", "zeta", "energy_J", "modal_mass_kg", "iterations"}} solved at each of ``amplitudes`` inside the
    branch, by Newton at that amplitude from the nearest point (in its active set)."""
    out = {}
    lam = np.array([p.lam for p in points])
    adapt = problem.adaptation
    for a in amplitudes:
        la = math.log10(a)
        if not lam.min() <= la <= lam.max():
            continue
        x0 = points[int(np.argmin(np.abs(lam - la)))].x
        if adapt is not None:
            adapt.restore(adapt.state_of(x0))
        try:
            x, it = solve_adaptive(newton_system(problem), x0, la, adapt=adapt, x_scale=sc.x, r_scale=sc.r,
                                   options=cont.newton)
        except (ConvergenceError, ContinuationError) as exc:
            log.warning("nma: the mode at amplitude %.6g m did not converge: %s", a, exc)
            continue
        w, xi = float(x[problem.nc]), float(x[problem.nc + 1])
        out[float(a)] = {"omega_rad_s": w, "zeta": xi / (2.0 * w), "energy_J": problem.energy_per_cycle(x, la),
                         "modal_mass_kg": problem.modal_terms(x)[0], "iterations": int(it)}
    return out


def synthesize_frf(backbone: Backbone, scale: float = 1.0) -> dict:
    """The forced response near the mode from its backbone, by single nonlinear mode theory
    (Szemplinska-Stupnicka; Krack 2015, Eq. 22): the motion is the mode at amplitude a, forced by
    its modal force scale * psi^H F,

        a^2 m^2 [(omega^2 - Omega^2)^2 + (2 zeta omega Omega)^2] = |scale psi^H F|^2,

    solved for the excitation frequency Omega at each backbone point: two solutions (below and
    above resonance) where the amplitude is reachable.  Returns {"omega": (2, points) rad/s with
    NaN where unreachable, "amplitude": (points,) m at the backbone's output, "peak_amplitude",
    "peak_omega", "main_peak_amplitude", "main_peak_omega", "detached"}.  A peak is where the two
    branches meet (disc = 0, interpolated in the backbone's points).  Where the modal damping falls
    again at larger amplitude, the amplitude becomes reachable again beyond an unreachable stretch:
    a part of the response detached from the one that grows from rest (an isola), which the picture
    draws.  "peak_*" is then the largest amplitude of all (what the picture shows), "main_peak_*"
    the first one, on the part connected to small amplitudes, and "detached" says so.  Where the
    backbone's last point is still reachable, the response goes on beyond the backbone's amplitude
    range: "beyond_backbone" is True and that end counts as a peak (a lower bound of the true one)."""
    arr = backbone.info["arrays"]
    a, w, z = backbone.amplitude, backbone.omega, backbone.zeta
    m, f = arr["modal_mass_kg"], np.abs(arr["modal_force_N"]) * scale
    if not np.any(f > 0):
        raise NmaError("the scene has no harmonic force on this mode: no forced response to synthesise")
    rhs = (f / (a * m)) ** 2
    base = w ** 2 * (1.0 - 2.0 * z ** 2)
    disc = w ** 4 * (1.0 - 2.0 * z ** 2) ** 2 - w ** 4 + rhs
    ok = disc >= 0
    sq = np.sqrt(np.where(ok, disc, 0.0))
    lo, hi = base - sq, base + sq
    om = np.full((2, a.size), np.nan)
    om[0, ok & (lo > 0)] = np.sqrt(lo[ok & (lo > 0)])
    om[1, ok & (hi > 0)] = np.sqrt(hi[ok & (hi > 0)])
    # the peak: where disc = 0 (the two branches meet), between the last reachable point and the next
    g = disc / w ** 4
    peaks = []
    # a peak where a reachable point is followed by an unreachable one (the other way round is the
    # foot of a detached part, not a peak)
    for i in np.flatnonzero((g[:-1] >= 0) & (g[1:] < 0)):
        t = g[i] / (g[i] - g[i + 1])
        la = np.log(a[i]) + t * (np.log(a[i + 1]) - np.log(a[i]))
        peaks.append((float(np.exp(la)), float(np.sqrt(np.interp(t, [0, 1], [base[i], base[i + 1]])))))
    beyond = bool(a.size) and g[-1] >= 0
    if beyond:
        peaks.append((float(a[-1]), float(np.sqrt(base[-1]))))
    nan = (float("nan"), float("nan"))
    main = peaks[0] if peaks else nan
    top = max(peaks) if peaks else nan
    return {"omega": om, "amplitude": a, "peak_amplitude": top[0], "peak_omega": top[1],
            "main_peak_amplitude": main[0], "main_peak_omega": main[1], "detached": bool(peaks) and top != main,
            "beyond_backbone": beyond and top == peaks[-1]}


@dataclass
class BackboneResult:
    """One method's backbone in a comparison: sizes, times, and its largest relative errors in
    omega and zeta against the reference at the comparison's amplitudes (each solved there)."""

    label: str
    backbone: Backbone | None
    offline_s: float
    online_s: float
    omega_err: float = float("nan")
    zeta_err: float = float("nan")
    compared: int = 0  # amplitudes at which both were solved
    failure: str = ""

    def row(self) -> dict:
        bb = self.backbone
        sz = bb.info["arrays"]["rom_size"] if bb is not None else np.zeros(1, int)
        return {"method": self.label, "size_min": int(sz.min()), "size_max": int(sz.max()),
                "status": bb.info["status"] if bb is not None else "failed",
                "points": bb.num_points if bb is not None else 0, "offline_s": self.offline_s,
                "online_s": self.online_s, "omega_rel_err": self.omega_err, "zeta_rel_err": self.zeta_err,
                "amplitudes_compared": self.compared, "failure": self.failure}


def compare_backbones(structure: Structure, specs, options: NmaOptions, *, reference: str = "full",
                      num_amplitudes: int = 12, progress=None) -> list[BackboneResult]:
    """The backbone of the reference (full order, or a ROM given as a method spec) and of every
    method of ``specs`` (analysis.compare.MethodSpec), each solved exactly at ``num_amplitudes``
    amplitudes spread evenly in log over the range; the first result is the reference.  A method
    that stops early is compared where it got to (its status says so)."""
    from ..rom import RomOptions, build_rom
    from .compare import MethodSpec, parse_method

    lo, hi = math.log10(options.amplitude_start), math.log10(options.amplitude_end)
    at = tuple(float(a) for a in np.logspace(lo, hi, num_amplitudes + 2)[1:-1])
    opts = replace(options, at=at)
    ref_spec = parse_method(reference, RomOptions()) if reference != "full" else MethodSpec("full", RomOptions())
    specs = [ref_spec] + [s for s in specs if s.label != ref_spec.label]
    out: list[BackboneResult] = []
    for spec in specs:
        if progress:
            progress(spec.label)
        t0 = time.perf_counter()
        model = structure if spec.method == "full" else build_rom(structure, spec.method, spec.options)
        offline = time.perf_counter() - t0
        t1 = time.perf_counter()
        try:
            bb = compute_backbone(model, opts)
        except NmaIncomplete as exc:
            bb = exc.backbone
        except (ContinuationError, ConvergenceError, NmaError) as exc:
            if not out:
                raise
            out.append(BackboneResult(spec.label, None, offline, time.perf_counter() - t1, failure=str(exc)))
            continue
        res = BackboneResult(spec.label, bb, offline, time.perf_counter() - t1)
        if out:
            ref = out[0].backbone.info["at"]
            mine = bb.info["at"]
            common = [a for a in at if a in ref and a in mine]
            if common:
                res.omega_err = max(abs(mine[a]["omega_rad_s"] / ref[a]["omega_rad_s"] - 1) for a in common)
                res.zeta_err = max(abs(mine[a]["zeta"] / ref[a]["zeta"] - 1) for a in common)
            res.compared = len(common)
        out.append(res)
    return out


__all__ = ["ModalProblem", "CondensedModalProblem", "modal_problem", "NmaOptions", "Backbone", "NmaError", "NmaIncomplete", "compute_backbone",
           "synthesize_frf", "BackboneResult", "compare_backbones"]
