"""Harmonics chosen along the branch: H raised where a point needs more, lowered where it needs fewer.

A branch of a jointed structure is mostly linear (the stuck flanks, where the contact forces carry
no harmonics above the first) and strongly nonlinear over a short stretch (slip and separation near
the resonance).  One H for the whole branch pays there for the stretch that needs most, and a
branch that runs into a stretch with too few harmonics can follow a loop that more harmonics
remove (the paper's beam at 3 N: separated loops at H = 5 to 17 that H = 21 does not have, docs/
theory.md).  Here the branch is followed at the H it needs, point after point, from the converged
points (an adaptive harmonic balance in the sense of Jaumouille, Sinou and Petitjean, J. Sound Vib.
329 (2010) 4048; the criteria are jointfem's):

* every accepted point's truncation estimate e (analysis.convergence.top_harmonic_share: the contact
  forces' share in the two highest retained harmonics) is compared with the target; where it
  passes it, H rises;
* e does not measure the response's error (it reads 0.006 at the beam's H = 5 peak, 5.1 % low), so
  every point whose e passes ``check_share`` of the target is also solved at H + step, and where
  that solution lies further from the branch at H than ``tol`` of the branch's largest amplitude
  (in each output's first-harmonic amplitude and RMS) or ``omega_tol`` of omega (branch_distance),
  H rises to it; where Newton finds no solution at H + step from the point, it is tried once more
  from the last point checked, moved along the branch by the step since (the harmonics above H
  then start where the branch at H + step has them, not at zero);
* H rises by solving a point again at the higher H (its coefficients padded with zeros; on the
  hyperplane through it normal to the last secant, so also at a fold), and again until its e meets
  the target.  The point is the last one, or, where Newton finds no solution from it or it lies past
  a fold of the stretch at this H, a point 1, 2, 4, ... before (before the fold): a sheet that
  returns after a fold need not be part of the branch at more harmonics (measured on the beam: a
  point of the H = 23 branch's returning sheet lifted to H = 25 lay on a sheet that ran down into
  the separated branch).  The points after the one lifted are dropped and followed again;
* H falls where the point's forces, truncated, predict e below ``lower_share`` of the target at a
  lower H for ``lower_after`` points in a row, each a step the way the sweep goes (on the beam,
  lowered on the returning sheet of the H = 15 branch's folded top, which runs back towards the
  separated branch with e near 0, the branch followed that sheet out of the window);
* the branch goes on from the changed point along the secant of its last step: nothing before it
  is solved again.

Every point keeps the H it was solved at (PointRecord.harmonics).  The branch's points are returned
with their coefficients at the largest H used, the higher harmonics of the points solved at fewer
zero (the same functions of time).
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from ..continuation.arclength import (ContinuationError, ContinuationOptions, ContinuationPoint, ConvergenceError,
                                     continue_branch, correct, solve_adaptive)
from ..contact.law import ContactResult
from ..harmonics import Harmonics
from ..hbm.problem import Problem, newton_system
from .convergence import amplitude_and_rms
from .peaks import output_signal

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class HarmonicAdaptation:
    """``target``: the largest truncation estimate a point may keep; ``H_max``: H is not raised
    beyond it (points above the target there are kept and counted); ``H_min``: nor lowered below;
    ``step``: H changes by this (2: a symmetric law has no even harmonics, so a step of 1 can leave
    the estimate unchanged); ``lower_after``: points in a row, each a step the way the sweep goes,
    whose estimate at a lower H is predicted below ``lower_share`` times the target before H is
    lowered."""

    target: float = 0.05
    H_max: int = 25
    H_min: int = 1
    step: int = 2
    lower_after: int = 8
    lower_share: float = 0.1
    # the check at H + step of every point whose estimate passes check_share times the target: the
    # point solved at H + step must lie within tol of the largest amplitude of the branch so far, or
    # within omega_tol of omega, of the branch at H (branch_distance, each output's first-harmonic
    # amplitude and RMS; else H is raised, to the point solved at H + step).  A distance, not the
    # change at one omega: where the branch is steep or folds, a branch at more harmonics beside it
    # at a shifted omega changes the amplitude at one omega by as much as the slope makes it
    tol: float = 5e-3
    check_share: float = 0.01
    omega_tol: float = 5e-4  # 0.05 % of omega beside tol = 0.5 % of the amplitude, as for a located peak


def resize(x: np.ndarray, q: int, H_to: int) -> np.ndarray:
    """Coefficients of q signals at another H: the harmonics above the smaller H dropped or zero."""
    n_to = q * (2 * H_to + 1)
    out = np.zeros(n_to)
    m = min(x.size, n_to)
    out[:m] = x[:m]
    return out


def enough_harmonics(contact: list[ContactResult], harmonics: Harmonics, adaptation: HarmonicAdaptation) -> int:
    """The smallest H (H_min or more, in steps of adaptation.step down from harmonics.H) at which the
    estimate of the point's forces truncated to it stays at most lower_share times the target."""
    ad = adaptation
    H = harmonics.H
    while H - ad.step >= ad.H_min and share_at(contact, harmonics, H - ad.step) <= ad.lower_share * ad.target:
        H -= ad.step
    return H


def share_at(contact: list[ContactResult], harmonics: Harmonics, H: int, *, top: int = 2) -> float:
    """analysis.convergence.top_harmonic_share of the contact forces truncated to H <= harmonics.H:
    what the estimate would read at H if the point were the same (the prediction that lowers H)."""
    if not contact or H < 1:
        return 0.0
    if H <= top:
        return 1.0
    F = np.concatenate([c.F.reshape(harmonics.num_hc, -1) for c in contact], axis=1)
    orders = harmonics.orders
    dyn = float(np.sum(F[(orders >= 1) & (orders <= H)] ** 2))
    if dyn <= 0.0:
        return 0.0
    return float(np.sqrt(np.sum(F[(orders > H - top) & (orders <= H)] ** 2) / dyn))


def branch_distance(p: tuple[float, float], up: tuple[float, float], units: tuple[float, float],
                    before: tuple[float, float] | None = None) -> float:
    """How far the point ``up`` = (omega, value) of the branch at more harmonics lies from the branch
    at H through ``p`` (and ``before``, the point before it): the distance from ``up`` to the line
    through p along the secant from before, omega and the value each in its ``units``; without
    ``before``, from ``up`` to p.  A branch steep in omega or folding is a curve, not a function of
    omega: where the branch at more harmonics runs beside it at a shifted omega, the change at one
    omega is as large as the slope makes it, the distance between the curves is not."""
    dw, dv = (up[0] - p[0]) / units[0], (up[1] - p[1]) / units[1]
    if before is None:
        return float(np.hypot(dw, dv))
    t = ((p[0] - before[0]) / units[0], (p[1] - before[1]) / units[1])
    n = float(np.hypot(*t))
    return float(np.hypot(dw, dv)) if n == 0.0 else abs(t[0] * dv - t[1] * dw) / n


class _Change(Exception):
    def __init__(self, H: int, point: ContinuationPoint | None = None):
        super().__init__(H)
        self.H = H
        self.point = point  # the point that asked, already solved at H (by the check)


@dataclass
class AdaptiveTrace:
    """What ``trace`` followed: ``points`` (coefficients at ``H_top``), the H each was solved at,
    the check's change per point (NaN where not checked, inf where Newton found no solution at
    H + step), ``amplitude_change``: per point and output, the change of the first-harmonic
    amplitude from the point to the point solved at H + step, m (signed; NaN where not checked or
    not solved), the stop (a ContinuationError) if the
    branch did not reach its end, the changes of H made (omega, from, to), the lowerings tried and
    not made (omega, from, to, why), and the continuation's summed step counts."""

    points: list[ContinuationPoint]
    H_of: np.ndarray
    check: np.ndarray
    amplitude_change: np.ndarray  # (points, outputs)
    H_top: int
    stopped: ContinuationError | None
    changes: list[tuple[float, int, int]]
    refused: list[tuple[float, int, int, str]]
    stats: dict


class _Tracer:
    """The state of one adaptive trace (``trace``)."""

    def __init__(self, problem_at, adaptation: HarmonicAdaptation, omega_start: float, omega_end: float,
                 options: ContinuationOptions, record_at, callback):
        self.problem_at, self.ad, self.options = problem_at, adaptation, options
        self.omega_start, self.omega_end = omega_start, omega_end
        self.lam_scale = abs(omega_end - omega_start)
        self.record_at, self.callback = record_at, callback
        self.pts: list[ContinuationPoint] = []
        self.H_of: list[int] = []
        self.check: list[np.ndarray] = []  # per point: (the check, each output's amplitude change)
        self.changes, self.refused = [], []
        self.top: dict = {}  # output -> the largest first-harmonic amplitude on the branch so far
        self.shadow = None  # (H, the point solved at H + step, the point) of the last check solved
        self.outputs = None
        self.lifted = None  # (the point whose H changed, as it was, and the one before it)
        self._on_branch: dict = {}  # (id of a point, H) -> (the point, on_branch_at)

    def past(self, p: ContinuationPoint) -> bool:
        return (p.lam - self.omega_end) * np.sign(self.omega_end - self.omega_start) >= 0

    def q(self, H: int) -> int:
        pb = self.problem_at(H)
        return pb.num_coefficients // pb.harmonics.num_hc

    def solve_at(self, pt: ContinuationPoint, H: int, before: ContinuationPoint | None, *,
                 record: bool = True, start: tuple[np.ndarray, float] | None = None) -> ContinuationPoint | None:
        """pt solved at H from its coefficients: on the hyperplane through it normal to the secant
        from ``before`` (so also at a fold), else at its omega; None where Newton fails.  Without
        ``record`` the point's record (its stability, with it) is left to ``recorded``.  ``start``:
        (coefficients at H, omega) to start from instead, the hyperplane through it."""
        pb = self.problem_at(H)
        sc = pb.scales(self.omega_start, self.omega_end)
        x = resize(pt.x, self.q(H), H)
        if start is not None and before is not None:
            d_start = (x - resize(before.x, self.q(H), H), pt.lam - before.lam)
            pt = replace(pt, lam=start[1])
            x = start[0]
        else:
            d_start = None
        adapt = pb.adaptation
        if adapt is not None:
            adapt.restore(adapt.state_of(x))
        fun = newton_system(pb)
        try:
            if before is None:
                y, it = solve_adaptive(fun, x, pt.lam, adapt=adapt, x_scale=sc.x, r_scale=sc.r,
                                       options=self.options.newton)
                lam = pt.lam
            else:
                d = d_start or (x - resize(before.x, self.q(H), H), pt.lam - before.lam)
                for _ in range(adapt.max_redo if adapt is not None else 1):
                    y, lam, it, _ = correct(fun, x, pt.lam, d, x_scale=sc.x, lam_scale=self.lam_scale, r_scale=sc.r,
                                            options=self.options.newton,
                                            select=None if adapt is None else adapt.unknowns())
                    if adapt is None or not adapt.after_converge(y, lam):
                        break
                else:
                    return None
        except (ConvergenceError, ContinuationError, np.linalg.LinAlgError, RuntimeError) as exc:
            log.debug("harmonics: no solution at H = %d from omega = %.9g (%s)", H, pt.lam, exc)
            return None
        ev = pb.evaluate(y, lam, jacobian=False)
        res = float(np.max(np.abs(ev.R)) / sc.r) if ev.R.size else 0.0
        point = ContinuationPoint(y, lam, it, pt.ds, None, residual=res, ds_next=pt.ds)
        return self.recorded(point, H) if record else point

    def recorded(self, p: ContinuationPoint, H: int) -> ContinuationPoint:
        if p.extra is None:
            pb = self.problem_at(H)
            if pb.adaptation is not None:
                pb.adaptation.restore(pb.adaptation.state_of(p.x))
            p = replace(p, extra=self.record_at(pb)(p.x, p.lam))
        return p

    def signals(self, x: np.ndarray, H: int):
        h = self.problem_at(H).harmonics
        return {name: amplitude_and_rms(output_signal(x, dof, h), h) for name, dof in self.outputs.items()}

    def unchecked(self, worst: float = np.nan) -> np.ndarray:
        return np.concatenate([[worst], np.full(len(self.outputs), np.nan)])

    def checked(self, p: ContinuationPoint, H: int, before) -> tuple[np.ndarray, ContinuationPoint | None]:
        """The check of p (solved at H): the largest distance (branch_distance, times tol: in the
        units of tol) of p solved at H + step from the branch at H, over each output's
        first-harmonic amplitude and RMS, each over the largest amplitude on the branch so far (inf
        where Newton finds no solution at H + step), followed by each output's change of its
        first-harmonic amplitude (m), and that point."""
        ad = self.ad
        H_up = min(H + ad.step, ad.H_max)
        up = self.solve_at(p, H_up, before, record=False)  # (a point only checked needs no stability)
        sh = self.shadow
        if up is None and before is not None and sh is not None and sh[0] == H:
            # where the branch at H + step departs from the one at H (the onset of separation, a folded
            # top) Newton from p with the harmonics above H zero can stall; from the last point checked,
            # moved by the step of the branch at H since, it starts with those harmonics
            _, up_then, p_then = sh
            q_up = self.q(H_up)
            guess = up_then.x + resize(p.x - resize(p_then.x, self.q(H), H), q_up, H_up)
            up = self.solve_at(p, H_up, before, record=False, start=(guess, up_then.lam + p.lam - p_then.lam))
            log.debug("harmonics: check at omega = %.9g from the last checked point: %s", p.lam,
                      "solved" if up is not None else "no solution")
        if up is None:
            return self.unchecked(np.inf), None
        self.shadow = (H, up, p)
        now, then = self.signals(p.x, H), self.signals(up.x, H_up)
        prev = None if before is None else self.signals(resize(before.x, self.q(H), H), H)
        w_unit = ad.omega_tol * abs(p.lam)
        worst = 0.0
        for k in now:
            units = (w_unit, ad.tol * max(self.top[k], 1e-300))
            for j in (0, 1):  # first-harmonic amplitude, RMS
                dist = branch_distance((p.lam, now[k][j]), (up.lam, then[k][j]), units,
                                       None if prev is None else (before.lam, prev[k][j]))
                worst = max(worst, ad.tol * dist)
        return np.concatenate([[worst], [then[k][0] - now[k][0] for k in self.outputs]]), up

    def on_branch_at(self, p: ContinuationPoint, H_p: int, H: int) -> bool:
        """Whether p, solved at H_p, solves the equations at H too (its coefficients resized, as well
        as it solved its own: to the Newton tolerance or its residual): a stuck stretch has no
        harmonics above the first in its contact forces, and is the same branch at every H."""
        key = (id(p), H)  # (the point is kept with its answer: its id is not reused meanwhile)
        if key not in self._on_branch:
            if H_p == H:
                self._on_branch[key] = (p, True)
            else:
                pb = self.problem_at(H)
                x = resize(p.x, self.q(H), H)
                if pb.adaptation is not None:
                    pb.adaptation.restore(pb.adaptation.state_of(x))
                R = pb.evaluate(x, p.lam, jacobian=False).R
                r = pb.scales(self.omega_start, self.omega_end).r
                tol = max(self.options.newton.tol, p.residual)
                self._on_branch[key] = (p, bool(R.size == 0 or np.max(np.abs(R)) / r <= tol))
        return self._on_branch[key][1]

    def traced_at(self, H: int) -> list[ContinuationPoint]:
        """The points before the last that the retrace rule (ContinuationOptions.retrace_tol) sees as
        the branch at H, in order, resized to H: those that solve the equations at H (on_branch_at).
        Those solved at another H and not solving these are near this branch but not on it, and a
        fold of this branch passing near them is no step back; a stuck stretch solved at a lower H is
        this branch, and a step back along it is one (on the paper's beam at 3 N, sampled AFT, the
        branch raised to H = 17 where separation starts turned back at the corner and went down the
        stuck flank solved at H = 3, to 785 rad/s).  The points skipped leave a chord: they lie
        where the branches at the two H part, within the steps either side."""
        return [p if self.H_of[j] == H else replace(p, x=resize(p.x, self.q(H), H))
                for j, p in enumerate(self.pts[:-1]) if self.on_branch_at(p, self.H_of[j], H)]

    def raised(self, want: int, ready: ContinuationPoint | None) -> ContinuationPoint | None:
        """The branch at H = want (or more, until the estimate meets the target) from its last point,
        else from points further back (1, 2, 4, ... before it), where the response is nearer the one
        at more harmonics; the points after the one solved are dropped (the branch is followed again
        from it).  None where no point lifts."""
        ad, pts = self.ad, self.pts
        # not from a point past a fold of the stretch at this H: the sheet it returns on need not be
        # part of the branch at more harmonics (on the paper's beam at 3 N the H = 23 branch's top
        # folds back at 1693.79 rad/s, and a point of its returning sheet lifted to H = 25 lay on a
        # sheet that runs down into the separated branch, which the branch at H = 25 does not)
        k = len(self.H_of) - 1
        while k > 0 and self.H_of[k - 1] == self.H_of[-1]:
            k -= 1
        lam = np.array([p.lam for p in pts[k:]])
        turn = np.flatnonzero(np.diff(np.sign(np.diff(lam))) != 0) if lam.size > 2 else np.array([], int)
        n = len(pts) if turn.size == 0 else k + int(turn[0]) + 1  # the points up to the stretch's first fold
        back = sorted({max(n - 1 - j, 0) for j in [0] + [2 ** i for i in range(int(np.log2(max(n, 1))) + 2)]},
                      reverse=True)
        n = len(pts)
        for i in back:
            H_try = want
            while True:
                new = self.recorded(ready, H_try) if (ready is not None and i == n - 1 and H_try == want) else \
                    self.solve_at(pts[i], H_try, pts[i - 1] if i > 0 else None)
                if new is None or new.extra.harmonic_error <= ad.target or H_try >= ad.H_max:
                    break
                H_try = min(H_try + ad.step, ad.H_max)
            if new is not None:
                self.lifted = (pts[i], pts[i - 1] if i > 0 else None)
                del pts[i + 1:], self.H_of[i + 1:], self.check[i + 1:]
                return new
        return None

    def run(self, H0: int, x0: np.ndarray, resume=None) -> AdaptiveTrace:
        ad, pts = self.ad, self.pts
        self.outputs = self.problem_at(H0).layout.outputs
        t_start = time.monotonic()
        H, heading, stopped, stats = H0, None, None, {}
        if resume is not None:
            pts.extend(resume[0])
            self.H_of.extend(resume[1])
            self.check.extend([self.unchecked() for _ in resume[1]])
            H = self.H_of[-1]
            for p, H_p in zip(pts, self.H_of):
                for k, v in self.signals(p.x, H_p).items():
                    self.top[k] = max(self.top.get(k, 0.0), v[0])
            if len(pts) >= 2:
                heading = ((pts[-1].x - resize(pts[-2].x, self.q(H), H), pts[-1].lam - pts[-2].lam),
                           max(pts[-1].ds_next, self.options.ds_min))
        quiet_until = 0  # no lowering before the branch has this many points

        try:
            while True:
                pb = self.problem_at(H)
                sc = pb.scales(self.omega_start, self.omega_end)
                fresh: list[ContinuationPoint] = []
                fresh_check: list[np.ndarray] = []
                low_run: list[tuple[float, int]] = []  # (omega, harmonics_enough) of the run of points
                first = [True]

                def cb(p: ContinuationPoint, H=H, pb=pb, fresh=fresh, fresh_check=fresh_check, low_run=low_run,
                       first=first):
                    if first[0] and pts:  # the start of a later stretch: the point kept already
                        first[0] = False
                        return
                    first[0] = False
                    fresh.append(p)
                    fresh_check.append(self.unchecked())
                    if self.callback is not None:
                        self.callback(p)
                    rec = p.extra
                    for k, v in self.signals(p.x, H).items():
                        self.top[k] = max(self.top.get(k, 0.0), v[0])
                    if self.past(p):  # the branch's last point: continue_branch stops after it
                        return
                    if H < ad.H_max and rec.harmonic_error > ad.target:
                        raise _Change(min(H + ad.step, ad.H_max))
                    if H < ad.H_max and rec.harmonic_error > ad.check_share * ad.target:
                        before = fresh[-2] if len(fresh) >= 2 else (pts[-1] if pts else None)
                        fresh_check[-1], up = self.checked(p, H, before)
                        worst = fresh_check[-1][0]
                        log.debug("harmonics: H = %d at omega = %.9g: e = %.3g, change at H + %d %.3g", H, p.lam,
                                  rec.harmonic_error, ad.step, worst)
                        if worst > ad.tol:
                            raise _Change(min(H + ad.step, ad.H_max), up)
                    # lowered only on points that move the way the sweep goes: on the beam at 3 N the
                    # H = 15 branch's top folds back, its returning sheet runs towards the separated
                    # branch with an estimate near 0, and lowered there the branch followed it out of
                    # the window
                    lams = ([pts[-1].lam] if pts else []) + [f.lam for f in fresh]
                    onward = len(lams) >= 2 and (lams[-1] - lams[-2]) * (self.omega_end - self.omega_start) > 0
                    if (onward and len(pts) + len(fresh) > quiet_until and rec.harmonics_enough is not None
                            and rec.harmonics_enough < H):
                        low_run.append((p.lam, rec.harmonics_enough))
                        if len(low_run) >= ad.lower_after:
                            raise _Change(max(e for _, e in low_run[-ad.lower_after:]))
                    else:
                        low_run.clear()

                used = time.monotonic() - t_start
                opts = self.options
                cont = replace(opts, max_points=max(2, opts.max_points - len(pts)),
                               time_limit=None if opts.time_limit is None else max(opts.time_limit - used, 0.0))
                part: dict = {}
                change, ready = None, None
                try:
                    continue_branch(newton_system(pb), pts[-1].x if pts else x0,
                                    pts[-1].lam if pts else self.omega_start, self.omega_end, x_scale=sc.x,
                                    lam_scale=self.lam_scale, r_scale=sc.r, options=cont, callback=cb,
                                    extra=self.record_at(pb), adapt=pb.adaptation, stats=part, resume=heading,
                                    traced=self.traced_at(H))
                except _Change as exc:
                    change, ready = exc.H, exc.point
                except ContinuationError as exc:
                    stopped = exc
                for key, v in part.items():
                    stats[key] = stats.get(key, 0) + v
                pts.extend(fresh)
                self.H_of.extend([H] * len(fresh))
                self.check.extend(fresh_check)
                if change is None:
                    break
                here, n = pts[-1], len(pts)
                self.lifted = (here, pts[-2] if n >= 2 else None)
                if change > H:
                    new = self.raised(change, ready)
                    if new is None:
                        stopped = ContinuationError(
                            f"harmonics: the branch at omega [rad/s] = {here.lam:.9g} needs more than H = {H}, and "
                            f"Newton found no solution at H = {change} from it or any point before it", points=pts)
                        break
                    # not lowered again before the branch is past the point that asked (else it could
                    # come back to it at the H it had there, and round again)
                    quiet_until = n + ad.lower_after
                else:
                    new = self.solve_at(here, change, pts[-2] if n >= 2 else None)
                    why = ("Newton did not converge" if new is None else
                           f"estimate {new.extra.harmonic_error:.3g} at H = {change}"
                           if new.extra.harmonic_error > ad.target else None)
                    if why is not None:
                        self.refused.append((here.lam, H, change, why))
                        quiet_until = n + 4 * ad.lower_after
                        new = None
                if new is not None:
                    H_new = new.extra.harmonics
                    self.changes.append((new.lam, self.H_of[-1], H_new))
                    log.info("harmonics: H %d -> %d at omega = %.6g rad/s", self.H_of[-1], H_new, new.lam)
                    pts[-1], self.H_of[-1], self.check[-1] = new, H_new, self.unchecked()
                    H = H_new
                if self.past(pts[-1]):
                    break
                # the heading: the secant of the branch's last step before H changed, in the
                # coefficients of H.  Not the secant to the point solved at the new H: the jump between
                # the branches at the two H can be larger than the step, and turn it back (on the
                # paper's beam at 3 N, sampled AFT, the point lifted to H = 5 where separation starts
                # lay 0.015 rad/s below the one before it, and the branch went back down its stuck
                # flank to 785 rad/s)
                old, prev = self.lifted
                heading = (((resize(old.x, self.q(H), H) - resize(prev.x, self.q(H), H), old.lam - prev.lam),
                            max(pts[-1].ds, self.options.ds_min)) if prev is not None else None)
        except KeyboardInterrupt as exc:  # (Ctrl-C while a point is solved at another H)
            if not pts:
                raise
            stopped = ContinuationError(f"continuation interrupted ({str(exc) or 'Ctrl-C'}) at omega [rad/s] = "
                                        f"{pts[-1].lam:.9g} after {len(pts)} points", points=pts, interrupted=True)
            del self.H_of[len(pts):], self.check[len(pts):]
        H_top = max(self.H_of)
        out = [replace(p, x=resize(p.x, self.q(H_top), H_top)) for p in pts]
        check = np.array(self.check).reshape(len(pts), 1 + len(self.outputs))
        return AdaptiveTrace(out, np.array(self.H_of), check[:, 0], check[:, 1:], H_top, stopped, self.changes,
                             self.refused, stats)


def trace(problem_at: Callable[[int], Problem], H0: int, adaptation: HarmonicAdaptation, *, omega_start: float,
          omega_end: float, x0: np.ndarray, options: ContinuationOptions,
          record_at: Callable[[Problem], Callable[[np.ndarray, float], object]],
          callback: Callable[[ContinuationPoint], None] | None = None, resume=None) -> AdaptiveTrace:
    """Follow the forced response from (x0, omega_start) to omega_end with H chosen along it (the
    module's docstring).  ``resume``: (points, H per point) of a branch that stopped, each point at
    its own H with its record: the branch goes on from the last, along the secant of its last step.  ``problem_at(H)``: the problem at H (the same N at every H);
    ``record_at(problem)``: the record function of the points solved in it, whose PointRecord
    carries ``harmonics``, ``harmonic_error`` and ``harmonics_enough`` (the estimate at its H and
    the lowest H predicted to do, enough_harmonics)."""
    return _Tracer(problem_at, adaptation, omega_start, omega_end, options, record_at, callback).run(H0, x0, resume)
