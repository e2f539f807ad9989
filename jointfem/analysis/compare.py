"""Speed against accuracy: every method's size, times and errors against full order.

A method is given as ``name[:modes[:tvd[:kind]]]`` (e.g. ``cb:10``, ``penalty:10:3``,
``tvd:10:3:eq12`` for the paper's TVDs, rom.cms.TVD_KINDS); missing
numbers take the defaults.  Errors are against the full model of the same scene, solved in
the same run with the same harmonics, samples and tolerances.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..contact.law import ContactError
from ..continuation.arclength import ContinuationError, ConvergenceError
from ..linalg import eigen
from ..models.structure import Structure
from ..results import FrequencyResponse
from ..rom import METHODS, RomError, RomOptions, build_rom
from ..rom.cms import TVD_KINDS
from ..rom.reductors import check_options
from .frf import compute_frf


@dataclass(frozen=True)
class MethodSpec:
    method: str
    options: RomOptions

    @property
    def label(self) -> str:
        if self.method in ("full", "exact"):
            return self.method
        o = self.options
        s = f"{self.method}:{o.modes}"
        return s + (f"+{o.tvd}tvd" + ("(eq12)" if o.tvd_kind == "eq12" else "") if o.tvd else "")


def parse_method(text: str, defaults: RomOptions) -> MethodSpec:
    """'penalty:10:3' or 'tvd:10:3:eq12' -> MethodSpec; raises RomError naming the bad part."""
    parts = text.strip().split(":")
    name = parts[0].lower()
    if name not in METHODS:
        raise RomError(f"--methods: {text!r}: unknown method {name!r}; choose from {', '.join(METHODS)}")
    kind = defaults.tvd_kind
    if len(parts) == 4:
        kind = parts.pop().lower()
        if kind not in TVD_KINDS:
            raise RomError(f"--methods: {text!r}: unknown TVD kind {kind!r}; choose from {', '.join(TVD_KINDS)}")
    try:
        nums = [int(p) for p in parts[1:]]
    except ValueError:
        raise RomError(f"--methods: {text!r}: modes and tvd must be integers (name[:modes[:tvd[:kind]]])") from None
    if len(nums) > 2 or any(v < 0 for v in nums):
        raise RomError(f"--methods: {text!r}: expected name[:modes[:tvd[:kind]]] with non-negative integers")
    modes = nums[0] if nums else defaults.modes
    tvd = nums[1] if len(nums) > 1 else defaults.tvd
    spec = MethodSpec(name, replace(defaults, modes=modes, tvd=tvd, tvd_kind=kind))
    if name != "full":  # before the reference is solved, not after it
        check_options(name, spec.options)
    return spec


def curve_error(frf: FrequencyResponse, ref: FrequencyResponse, output: str, *, stable_only: bool = False) -> float:
    """Largest distance of the ROM's points from the reference curve (a polyline through its
    points), in the plane of (omega / omega_peak, amplitude / amplitude_peak) of the reference.

    ROM points outside the reference's omega range are left out (both sweeps cover the requested
    range; each ends at its own first step past it).  The ROM's points are solutions; with a dense reference this measures the ROM and not the
    chords between sparse points (:func:`chord_error_estimate` says how dense; ``compare``'s
    ``reference_ds_max`` makes it denser); a fold or loop is fine.  (A ROM that misses a loop of the
    reference entirely shows up in the peak errors, not here.)
    """
    P, Q = _normalised(ref, ref, output), _normalised(frf, ref, output)
    # only where the reference exists: each sweep stops at its own first step past omega_end
    inside = (frf.omega >= ref.omega.min()) & (frf.omega <= ref.omega.max())
    if stable_only:  # the ROM's stable points (those a time integration would show): NaN if unknown
        if frf.stable is None:
            return float("nan")
        inside &= frf.stable
        if not inside.any():
            return 0.0
    return polyline_distance(P, Q[inside])


def chord_error_estimate(ref: FrequencyResponse, output: str) -> float:
    """How far the polyline through the reference's points may be from its curve, in the units
    of :func:`curve_error`: the distance of its odd points from the polyline through its even
    ones (chords twice as long), divided by 4 (a chord's sag grows as its length squared).  A
    curve error below this is not resolved by the reference."""
    P = _normalised(ref, ref, output)
    return polyline_distance(P[::2], P[1::2]) / 4.0 if len(P) >= 4 else float("nan")


def _normalised(frf: FrequencyResponse, ref: FrequencyResponse, output: str) -> np.ndarray:
    """frf's points as (omega / omega_peak, amplitude / amplitude_peak) of the reference's peak."""
    w0, a0 = ref.peak(output)
    return np.column_stack([frf.omega / w0, frf.amplitude(frf.outputs[output]) / a0])


def polyline_distance(P: np.ndarray, Q: np.ndarray) -> float:
    """Largest distance of the points Q (m x 2) from the polyline through the points P (n x 2)."""
    A, AB = P[:-1], P[1:] - P[:-1]
    L2 = np.maximum((AB**2).sum(axis=1), 1e-300)
    t = np.clip(((Q[:, None, :] - A[None]) * AB[None]).sum(-1) / L2[None], 0.0, 1.0)
    d = np.sqrt(((A[None] + t[..., None] * AB[None] - Q[:, None, :]) ** 2).sum(-1)).min(axis=1)
    return float(d.max())


@dataclass
class MethodResult:
    spec: MethodSpec
    size_min: int
    size_max: int
    full_size: int
    offline_s: float
    online_s: float
    num_points: int
    newton_iterations: int
    freq_errors: np.ndarray  # relative errors of the first natural frequencies
    peak_amp_err_pct: float = 0.0
    peak_freq_err_pct: float = 0.0
    curve_err_pct: float = 0.0
    curve_err_stable_pct: float = float("nan")  # over the ROM's stable points only (NaN: stability unknown)
    frf: FrequencyResponse | None = field(default=None, repr=False)
    failure: str = ""  # why the ROM's sweep stopped (then no FRF errors)

    @property
    def size_text(self) -> str:
        """'16', or '10-16' when the size changed along the branch."""
        return f"{self.size_min}" if self.size_min == self.size_max else f"{self.size_min}-{self.size_max}"

    def row(self) -> dict:
        r = {"method": self.spec.label, "size_min": self.size_min, "size_max": self.size_max,
             "reduction_ratio": self.size_max / self.full_size, "offline_s": self.offline_s,
             "online_s": self.online_s, "s_per_point": self.online_s / max(self.num_points, 1),
             "points": self.num_points, "newton_iterations": self.newton_iterations,
             "peak_amp_err_pct": self.peak_amp_err_pct, "peak_freq_err_pct": self.peak_freq_err_pct,
             "curve_err_pct": self.curve_err_pct, "curve_err_stable_pct": self.curve_err_stable_pct,
             "failure": self.failure}
        if self.failure:
            for k in ("peak_amp_err_pct", "peak_freq_err_pct", "curve_err_pct", "curve_err_stable_pct"):
                r[k] = float("nan")
        for i, e in enumerate(self.freq_errors):
            r[f"nf{i + 1}_rel_err"] = float(e)
        return r


def compare(structure: Structure, specs: list[MethodSpec], sweep, *, output: str, num_freq: int = 9,
            progress=None, reference: str = "full", repeats: int = 1,
            reference_ds_max: float | None = None) -> list[MethodResult]:
    """Solve the reference (full order, or the exact condensation: the same solution, cheaper on
    a large continuum) and every ROM of ``specs``; the first result is the reference.  Each ROM's
    online time is the median of ``repeats`` sweeps (the reference is swept once).

    The curve error measures the ROM's points against the polyline through the reference's; a
    smaller ``reference_ds_max`` makes that polyline dense where the sweep's own steps would leave
    chords as long as the errors to be measured."""
    if reference not in ("full", "exact"):
        raise RomError(f"--reference: {reference!r}: choose full or exact")
    # peaks to 1e-8 in omega, not to their error bar: the peak errors measured here are the ROMs'
    # (down to 1e-7 of the peak), which a search that stops within a tenth of the truncation error
    # would blur by its own tolerance
    sweep = replace(sweep, peak_share=0.0)
    ref_sweep = sweep if reference_ds_max is None else replace(
        sweep, continuation=replace(sweep.continuation, ds_max=reference_ds_max,
                                    ds0=min(sweep.continuation.ds0, reference_ds_max)))
    num_freq = min(num_freq, structure.num_dofs)  # a model of fewer DOFs has no more
    w2, _ = eigen(structure.K_lin, structure.M, num_freq, what="full linearised model")
    w_ref = np.sqrt(w2)
    specs = [MethodSpec(reference, RomOptions())] + [s for s in specs if s.method not in ("full", reference)]
    # every ROM first: a method that cannot be built fails before any nonlinear solve
    models = []
    for spec in specs:
        if spec.method == "full":
            models.append((structure, 0.0, np.zeros(num_freq)))
            continue
        model = build_rom(structure, spec.method, spec.options)
        if spec.method == "exact":  # the full model's equations: no modal truncation to measure
            models.append((model, model.offline_s, np.zeros(num_freq)))
            continue
        wr = model.natural_frequencies(num_freq)
        fe = np.full(num_freq, np.nan)
        fe[:wr.size] = wr / w_ref[:wr.size] - 1.0
        models.append((model, model.offline_s, fe))
    results = []
    ref = None
    for spec, (model, offline, fe) in zip(specs, models):
        on_point = None
        if progress:
            progress(spec.label)
            seen = {"n": 0, "t": time.monotonic()}

            def on_point(point, label=spec.label, seen=seen):
                # a line every 10 s within a method (the exact reference on the 3D lap joint ran
                # for 5.7 minutes with no word before)
                seen["n"] += 1
                if time.monotonic() - seen["t"] > 10.0:
                    seen["t"] = time.monotonic()
                    progress(f"{label}: {seen['n']} points, omega = {point.lam:.6g} rad/s")
        t0 = time.perf_counter()
        try:
            frf, times = None, []
            for _ in range(repeats if ref is not None else 1):
                t1 = time.perf_counter()
                run = compute_frf(model, sweep if ref is not None else ref_sweep, callback=on_point)
                times.append(time.perf_counter() - t1)
                if frf is None:
                    frf = run
            online = float(np.median(times))
        except (ContinuationError, ConvergenceError, ContactError) as exc:
            if ref is None:
                raise  # no reference, no comparison
            size = model.size
            results.append(MethodResult(spec, size, size, structure.num_dofs, offline, time.perf_counter() - t0,
                                        0, 0, fe, failure=str(exc)))
            continue
        sizes = frf.info["arrays"]["rom_size"]
        res = MethodResult(spec, int(sizes.min()), int(sizes.max()), structure.num_dofs, offline, online,
                           frf.num_points, int(frf.iterations.sum()), fe, frf=frf)
        if ref is None:
            ref = frf
        else:
            w0, a0 = ref.peak(output)
            w1, a1 = frf.peak(output)
            res.peak_amp_err_pct = 100.0 * (a1 / a0 - 1.0)
            res.peak_freq_err_pct = 100.0 * (w1 / w0 - 1.0)
            res.curve_err_pct = 100.0 * curve_error(frf, ref, output)
            res.curve_err_stable_pct = 100.0 * curve_error(frf, ref, output, stable_only=True)
        results.append(res)
    return results


def to_markdown(results: list[MethodResult], num_freq: int | None = None) -> str:
    head = ("| method | size | RR | offline s | online s | s/point | peak amp err % | peak freq err % "
            "| curve err % | over stable points % |")
    if num_freq is None:
        num_freq = max((r.freq_errors.size for r in results), default=0)
    lines = ["RR: the ROM's largest size over the full model's DOFs. Curve error: the largest distance of the "
             "ROM's points from the reference's curve, in % of the reference's peak; \"over stable points\": "
             "the same over the points the ROM finds stable (Hill's method), nan where its stability was not "
             "computed.", "", head, "|" + "---|" * 10]
    for r in results:
        size = r.size_text
        if r.failure:
            lines.append(f"| {r.spec.label} | {size} | {r.size_max / r.full_size:.3f} | {r.offline_s:.3f} | "
                         f"failed after {r.online_s:.2f} s: {r.failure} | | | | | |")
            continue
        lines.append(f"| {r.spec.label} | {size} | {r.size_max / r.full_size:.3f} | {r.offline_s:.3f} | "
                     f"{r.online_s:.2f} | {r.online_s / max(r.num_points, 1):.4f} | {r.peak_amp_err_pct:+.4f} | "
                     f"{r.peak_freq_err_pct:+.5f} | {r.curve_err_pct:.4f} | {r.curve_err_stable_pct:.4f} |")
    lines += ["", "Relative errors of the stuck natural frequencies against the full linearised model:", "",
              "| method | " + " | ".join(f"f{i + 1}" for i in range(num_freq)) + " |",
              "|" + "---|" * (num_freq + 1)]
    for r in results[1:]:
        lines.append(f"| {r.spec.label} | " + " | ".join(f"{e:.1e}" for e in r.freq_errors) + " |")
    return "\n".join(lines) + "\n"
