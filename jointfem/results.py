"""Frequency responses: derived quantities and files a user can open (CSV, NPZ, JSON)."""
from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .contact.law import STATE_NAMES
from .harmonics import Harmonics


class OutputError(RuntimeError):
    """A result holds a non-finite value and would not be written."""


@dataclass
class FrequencyResponse:
    """A solved branch.

    omega: (num_points,) rad/s.  U: (num_points, num_hc * n) harmonic coefficients, m.
    states: (num_points, N, num_pairs) int8, 0 stick / 1 slip / 2 separated.
    iterations: Newton iterations per point.  outputs: name -> dof index, or for a ROM a
    recovery row (num_dofs,) from the ROM coordinates (then num_dofs is the ROM's size).
    """

    omega: np.ndarray
    U: np.ndarray
    iterations: np.ndarray
    states: np.ndarray
    harmonics: Harmonics
    num_dofs: int
    outputs: dict
    dof_names: tuple = ()
    pair_names: tuple = ()
    info: dict = field(default_factory=dict)

    @property
    def num_points(self) -> int:
        return self.omega.size

    def coefficients(self, dof) -> np.ndarray:
        """Harmonic coefficients of one DOF (index, or recovery row), shape (num_points, num_hc), m."""
        U = self.U.reshape(self.num_points, self.harmonics.num_hc, self.num_dofs)
        return U[:, :, dof] if np.ndim(dof) == 0 else U @ np.asarray(dof)

    def amplitude(self, dof: int, k: int = 1) -> np.ndarray:
        """Amplitude of harmonic k of one DOF along the branch, m."""
        return self.harmonics.amplitude(self.coefficients(dof).T, k)

    def half_peak_to_peak(self, dof: int, *, samples: int = 512) -> np.ndarray:
        """Half the peak-to-peak displacement over one period, m (sampled finely)."""
        fine = Harmonics(self.harmonics.H, max(samples, self.harmonics.N))
        u_t = fine.to_time(self.coefficients(dof).T)
        return 0.5 * (u_t.max(axis=0) - u_t.min(axis=0))

    def peak(self, name: str) -> tuple[float, float]:
        """(omega, amplitude) of the largest first-harmonic amplitude of an output: located to the
        Newton tolerance by the FRF (analysis.peaks) when it did, else parabola-refined."""
        located = self.info.get("peaks", {}).get(name)
        if located is not None:
            return located.omega, located.amplitude
        return parabola_peak(self.omega, self.amplitude(self.outputs[name]))

    @property
    def stable(self) -> np.ndarray | None:
        """Stable or not per point (Hill's method, analysis.stability), None where not computed."""
        return self.info.get("arrays", {}).get("stable")

    def state_fractions(self) -> np.ndarray:
        """Fraction of the period in each state, shape (num_points, num_pairs, 3)."""
        return np.stack([(self.states == s).mean(axis=1) for s in range(3)], axis=-1)


def truncation_summary(err, amplitude: float, omega: float, index: int) -> dict:
    """summary.json's record of an analysis.convergence.PeakError of the peak (omega, amplitude) of
    the output ``index``: the changes to the (H2, N2) peak (better minus this) and of the RMS at
    omega, or why there are none (null, not NaN)."""
    at = err.at_omega
    out = {"to_harmonics": at.harmonics_to.H, "to_samples": at.harmonics_to.N, "connected": at.connected,
           "amp1_m": None, "omega_rad_s": None, "rms_at_omega_m": float(at.rms[index]) if at.connected else None}
    if err.peak is not None:
        out.update(amp1_m=err.peak.amplitude - amplitude, omega_rad_s=err.peak.omega - omega)
    if err.reason:
        out["reason"] = err.reason
    return out


def parabola_peak(omega: np.ndarray, amp: np.ndarray) -> tuple[float, float]:
    """(omega, amplitude) of the largest amplitude, refined by the parabola through it and its two
    neighbours when that parabola has its top within one step of the point."""
    i = int(np.argmax(amp))
    if 0 < i < amp.size - 1:
        w = omega[i - 1 : i + 2]
        c = np.polyfit(w - w[1], amp[i - 1 : i + 2], 2)
        if c[0] < 0:
            dw = -c[1] / (2 * c[0])
            if abs(dw) <= max(abs(w[2] - w[1]), abs(w[1] - w[0])):
                return float(w[1] + dw), float(np.polyval(c, dw))
    return float(omega[i]), float(amp[i])


def _check_finite(name: str, a: np.ndarray):
    bad = ~np.isfinite(a)
    if bad.any():
        idx = np.argwhere(bad)[0]
        raise OutputError(f"{name} holds a non-finite value at index {tuple(int(i) for i in idx)}; nothing written")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path: Path, write):
    """Write ``path`` through a temporary file in its folder, renamed into place once complete (a
    run stopped half-way leaves the old file or none).  The file gets the permissions of any file
    the user creates (0666 less the umask; mkstemp alone gives 0600)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix)
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def atomic_write_text(path: Path, text: str):
    atomic_write(Path(path), lambda p: Path(p).write_text(text))


def write_table(rows: list[dict], path: Path):
    """A list of flat dicts as CSV (header from the first row), written atomically."""
    import csv

    def write(p):
        with open(p, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            for r in rows:
                w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})

    atomic_write(Path(path), write)


def save_frf(frf: FrequencyResponse, out: Path, *, summary: dict) -> dict:
    """Write frf.csv, branch.npz and summary.json into ``out``.  Returns the summary written."""
    out = Path(out)
    _check_finite("omega", frf.omega)
    _check_finite("harmonic coefficients U", frf.U)
    names = list(frf.outputs)
    cols = [frf.omega, frf.omega / (2 * np.pi)]
    header = ["omega_rad_s", "freq_Hz"]
    for name in names:
        dof = frf.outputs[name]
        cols += [frf.amplitude(dof), frf.half_peak_to_peak(dof)]
        header += [f"{name}_amp1_m", f"{name}_halfp2p_m"]
    table = np.column_stack(cols)
    atomic_write(out / "frf.csv", lambda p: np.savetxt(p, table, delimiter=",", header=",".join(header),
                                                        comments="", fmt="%.12e"))

    def write_npz(p):
        with open(p, "wb") as fh:
            np.savez_compressed(
                fh, omega=frf.omega, U=frf.U, iterations=frf.iterations, states=frf.states,
                H=frf.harmonics.H, N=frf.harmonics.N, num_dofs=frf.num_dofs,
                dof_names=np.array(frf.dof_names, dtype=str), pair_names=np.array(frf.pair_names, dtype=str),
                output_names=np.array(names, dtype=str), **output_arrays(frf.outputs, frf.num_dofs),
                state_names=np.array(STATE_NAMES), layout=np.array("harmonic-major: U[j*n + dof], j=0 const, 2k-1 cos k, 2k sin k"),
                **({k: np.asarray(frf.info[k]) for k in ("pair_coords", "pair_area_m2") if k in frf.info}),
                **{k: np.asarray(v) for k, v in frf.info.get("arrays", {}).items()})

    atomic_write(out / "branch.npz", write_npz)
    peaks = {}
    for name in names:
        w, a = frf.peak(name)
        peaks[name] = {"omega_rad_s": w, "freq_Hz": w / (2 * np.pi), "amp1_m": a}
        located = frf.info.get("peaks", {}).get(name)
        if located is not None:  # how it was found: solved between the points, or the range's edge
            peaks[name].update(located=located.located, edge=located.edge, solves=located.solves,
                               residual=located.residual, **({"reason": located.reason} if located.reason else {}))
            if located.located:  # the top is at most this share of amp1_m above it (analysis.peaks)
                peaks[name]["located_to_rel"] = located.tolerance
        changes = frf.info.get("peak_changes", {})
        if name in changes:  # an auto sweep's error bar of the peak (analysis.frf.peak_change)
            peaks[name]["change_at_higher_H_m"] = changes[name]
        err = frf.info.get("peak_errors", {}).get(name)
        if err is not None:  # the same peak at (3H, 2N): the estimate of this one's truncation error
            peaks[name]["truncation_error"] = truncation_summary(err, a, w, list(frf.outputs).index(name))
    summary = dict(summary)
    summary.update({"num_points": int(frf.num_points), "newton_iterations_total": int(frf.iterations.sum()),
                    "peaks": peaks})
    if "continuation" in frf.info:  # refused steps, corners passed, steps redone (continue_branch)
        summary["continuation"] = dict(frf.info["continuation"])
    he = frf.info.get("arrays", {}).get("harmonic_error")
    if he is not None:
        summary["harmonic_error"] = {"max": float(he.max()), "at_omega_rad_s": float(frf.omega[int(np.argmax(he))]),
                                     **({"warning": frf.info["harmonic_warning"]} if "harmonic_warning" in frf.info
                                        else {})}
    if "stability" in frf.info:
        stab = {"status": frf.info["stability"]}
        if frf.stable is not None:
            a = frf.info["arrays"]
            pair = ~frf.stable & (a["floquet_leading_imag"] > 1e-6 * np.abs(frf.omega))
            stab.update(unstable_points=int((~frf.stable).sum()),
                        unstable_by_complex_pair=int(pair.sum()),
                        folds=int(frf.info["arrays"]["fold"].sum()),
                        stability_changes=int(frf.info["arrays"]["stability_change"].sum()))
            if "floquet_method" in a:  # how many points' exponents carry the contact laws' memory
                stab["points_by_method"] = {m: int((a["floquet_method"] == m).sum())
                                            for m in np.unique(a["floquet_method"])}
        summary["stability"] = stab
    atomic_write(out / "summary.json", lambda p: Path(p).write_text(json.dumps(summary, indent=2, default=_json)))
    return summary


def first_harmonic_amplitude(U: np.ndarray, harmonics: Harmonics, out) -> np.ndarray:
    """First-harmonic amplitude of an output (a coordinate index, or a recovery row over the
    coordinates) at every point of a branch U (points, num_hc * q), m."""
    q = U.shape[1] // harmonics.num_hc
    c, s = U[:, harmonics.cos(1, q)], U[:, harmonics.sin(1, q)]
    if np.ndim(out):
        return np.hypot(c @ out, s @ out)
    return np.hypot(c[:, out], s[:, out])


def output_arrays(outputs: dict, num_dofs: int) -> dict:
    """How a branch.npz names its outputs: ``output_dofs`` (an index per output) where every output
    is a DOF, else ``output_recovery`` (a row over the coordinates per output)."""
    names = list(outputs)
    if all(np.ndim(outputs[k]) == 0 for k in names):
        return {"output_dofs": np.array([outputs[k] for k in names])}
    return {"output_recovery": np.array([np.broadcast_to(outputs[k], (num_dofs,)) if np.ndim(outputs[k])
                                         else np.eye(num_dofs)[outputs[k]] for k in names])}


def _json(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o)}")


def load_branch(path: Path) -> dict:
    """Read branch.npz back into a dict of arrays."""
    with np.load(Path(path), allow_pickle=False) as z:
        return {k: z[k] for k in z.files}
