"""Plots (matplotlib, Agg backend: no display needed).  Imported lazily by the CLI."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .results import FrequencyResponse


STATE_COLORS = (("stick", "#4c9a2a"), ("slip", "#f0a30a"), ("separated", "#c8102e"))  # frf.png, backbone.png


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def finish(fig, ax, path: Path, *, title: str = "", legend_size: int = 8, title_size: float | None = None,
           dpi: int = 120) -> Path:
    """Grid, legend and title on ``ax``, then save ``fig`` as a PNG and close it (write_png)."""
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=legend_size)
    if title:
        ax.set_title(title, **({} if title_size is None else {"fontsize": title_size}))
    fig.tight_layout()
    return write_png(fig, path, dpi=dpi)


def readable_axes(ax, *, hz: str | None = "x") -> None:
    """What a reader needs to take a number off ``ax``: the frequency also in rad/s, the unit of the
    scene's inputs, on a secondary axis facing the one in Hz (``hz``: "x" puts it on top, "y" on the
    right; None where no axis is a frequency), and labels on the minor ticks of each log axis that
    spans up to two decades (matplotlib labels only the decades once an axis spans more than one: a
    range from 0.02 to 0.5 showed just 1e-1).  Call it once the scales are set: set_xscale and
    set_yscale replace the formatters."""
    from matplotlib.ticker import LogFormatterSciNotation

    if hz is not None:
        to_rad_s = (lambda f: 2 * np.pi * f, lambda w: w / (2 * np.pi))
        rad_s = (ax.secondary_xaxis("top", functions=to_rad_s) if hz == "x"
                 else ax.secondary_yaxis("right", functions=to_rad_s))
        (rad_s.set_xlabel if hz == "x" else rad_s.set_ylabel)("omega [rad/s]", fontsize=8)
        rad_s.tick_params(labelsize=7)
    for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
        if axis.get_scale() == "log":
            axis.set_minor_formatter(LogFormatterSciNotation(labelOnlyBase=False, minor_thresholds=(2, 0.5)))
            ax.tick_params(axis=name, which="minor", labelsize=7)


def plot_unconverged(ax, x, y, bad, *, label: str, **kw):
    """A thick dotted line over the points flagged ``bad`` (and the segments next to them): where
    the harmonic truncation estimate says the branch is not converged in H."""
    on = bad | np.append(bad[1:], False) | np.append(False, bad[:-1])
    ax.plot(x, np.where(on, y, np.nan), ls=":", lw=3, label=label, **kw)


def plot_branch(ax, x, y, stable, *, label: str, **kw):
    """A branch as a line, solid where it is stable and dashed where it is not, each unstable point
    marked (short unstable runs on a fold are shorter than a dash); solid where the stability is
    unknown.  A segment is stable when both its end points are."""
    if stable is None:
        return ax.plot(x, y, label=label, **kw)[0]
    stable = np.asarray(stable, bool)
    seg = stable[:-1] & stable[1:]
    on_s, on_u = np.zeros(stable.size, bool), np.zeros(stable.size, bool)
    on_s[:-1] |= seg
    on_s[1:] |= seg
    on_u[:-1] |= ~seg
    on_u[1:] |= ~seg
    line = ax.plot(x, np.where(on_s, y, np.nan), label=label, **kw)[0]
    if on_u.any():
        kw = dict(kw, color=line.get_color())
        kw.pop("ls", None)
        ax.plot(x, np.where(on_u, y, np.nan), ls="--", marker="o", ms=2.5, markevery=list(np.flatnonzero(~stable)),
                label=f"{label} (unstable)", **kw)
    return line


def plot_error_bars(ax, frf: FrequencyResponse, name: str, f_hz, a, *, color) -> None:
    """An auto sweep's error bars (harmonics = "auto"): at each point checked, the change of the
    first-harmonic amplitude when it is solved at H + 2 (branch.npz ``amplitude_change_m``), and at
    the located peak the largest of those next to it (summary.json ``change_at_higher_H_m``).  On
    a log axis a bar is cut just above zero."""
    change = frf.info.get("arrays", {}).get("amplitude_change_m")
    if change is None:
        return
    c = np.abs(np.asarray(change)[:, list(frf.outputs).index(name)])
    m = np.isfinite(c)
    if m.any():
        ax.errorbar(f_hz[m], a[m], yerr=np.vstack([np.minimum(c[m], 0.999 * a[m]), c[m]]), fmt="none",
                    ecolor=color, alpha=0.5, lw=0.8, capsize=1.5, label=f"{name}: change at H + 2 (error bar)")
    peak, bar = frf.info.get("peaks", {}).get(name), frf.info.get("peak_changes", {}).get(name)
    if peak is not None and peak.located and bar is not None:
        ax.errorbar([peak.omega / (2 * np.pi)], [peak.amplitude], yerr=[[min(bar, 0.999 * peak.amplitude)], [bar]],
                    fmt="o", ms=3.5, color=color, capsize=3,
                    label=f"{name}: peak {peak.amplitude:.5e} ± {bar:.1e} m")


def plot_frf(frf: FrequencyResponse, path: Path, *, title: str = "", harmonic_tol: float = 0.05) -> Path:
    """FRF of every output (first-harmonic amplitude and half peak-to-peak, m, against Hz), and
    below it the share of contact pairs sticking, slipping and separated along the branch.  As
    ``plot_levels``: dashed where unstable, the label saying where stability was not computed, and
    dotted over the points whose truncation estimate exceeds ``harmonic_tol``; an auto sweep's error
    bars (``plot_error_bars``)."""
    plt = pyplot()
    has_contact = frf.states.shape[-1] > 0
    fig, axes = plt.subplots(2 if has_contact else 1, 1, figsize=(7.5, 6.5 if has_contact else 4.2), sharex=True,
                             squeeze=False, gridspec_kw={"height_ratios": [3, 1.2]} if has_contact else None)
    ax = axes[0, 0]
    f_hz = frf.omega / (2 * np.pi)
    he = frf.info.get("arrays", {}).get("harmonic_error")
    bad = None if he is None or np.max(he) <= harmonic_tol else np.asarray(he) > harmonic_tol
    for name, dof in frf.outputs.items():
        label = f"{name}: 1st harmonic" + ("" if frf.stable is not None else " (stability not computed)")
        a = frf.amplitude(dof)
        line = plot_branch(ax, f_hz, a, frf.stable, label=label)
        ax.plot(f_hz, frf.half_peak_to_peak(dof), ":", color=line.get_color(), lw=1, label=f"{name}: half peak-to-peak")
        if bad is not None:
            plot_unconverged(ax, f_hz, a, bad, color=line.get_color(), alpha=0.6,
                             label=f"{name}: H = {frf.harmonics.H} not converged (truncation estimate "
                                   f"up to {np.max(he):.3g} > {harmonic_tol:g})")
        plot_error_bars(ax, frf, name, f_hz, a, color=line.get_color())
    ax.set_ylabel("amplitude [m]")
    ax.set_yscale("log")
    readable_axes(ax)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title, fontsize=10)
    if has_contact:
        fr = frf.state_fractions().mean(axis=1)  # (points, 3)
        ax2 = axes[1, 0]
        # lines, not a stack: a branch that folds back in frequency must stay readable
        for k, (name, color) in enumerate(STATE_COLORS):
            ax2.plot(f_hz, fr[:, k], color=color, label=name)
        ax2.set_ylim(-0.02, 1.02)
        ax2.set_ylabel("share of\npair-time")
        ax2.legend(fontsize=7, loc="center left", ncol=3)
        sizes = frf.info.get("arrays", {}).get("rom_size")
        if sizes is not None and np.ptp(sizes) > 0:
            # an adaptive ROM: its size along the branch, on a second axis
            ax3 = ax2.twinx()
            ax3.step(f_hz, sizes, where="mid", color="0.35", lw=1, ls=":", label="ROM size")
            ax3.set_ylabel("ROM size", color="0.35")
            ax3.legend(fontsize=7, loc="center right")
    axes[-1, 0].set_xlabel("frequency [Hz]")
    fig.tight_layout()
    return write_png(fig, path, dpi=120)


def plot_levels(curves: list[tuple[str, FrequencyResponse]], output: str, path: Path, *, title: str = "",
                harmonic_tol: float = 0.05) -> Path:
    """Several FRFs of one output (e.g. forcing levels), amplitude normalised by the force.

    Each is drawn as ``plot_branch`` draws it (dashed where unstable; solid where its stability
    was not computed, which the label then says), and dotted over the points whose harmonic
    truncation estimate (branch.npz ``harmonic_error``) exceeds ``harmonic_tol``."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for name, frf in curves:
        f, a = frf.omega / (2 * np.pi), frf.amplitude(frf.outputs[output])
        label = name if frf.stable is not None else f"{name} (stability not computed)"
        line = plot_branch(ax, f, a, frf.stable, label=label)
        he = frf.info.get("arrays", {}).get("harmonic_error")
        if he is not None and np.max(he) > harmonic_tol:
            plot_unconverged(ax, f, a, np.asarray(he) > harmonic_tol, color=line.get_color(),
                             label=f"{name}: H = {frf.harmonics.H} not converged (truncation "
                                   f"estimate up to {np.max(he):.2f} > {harmonic_tol:g})")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"{output} receptance [m/N]")
    ax.set_yscale("log")
    readable_axes(ax)
    return finish(fig, ax, path, title=title)


def plot_compare(results, output: str, frf_path: Path, pareto_path: Path, *, title: str = "") -> tuple[Path, Path]:
    """Overlaid FRFs of every method, and the largest curve error against the online time."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    for i, r in enumerate(results):
        if r.failure:
            continue
        f = r.frf
        plot_branch(ax, f.omega / (2 * np.pi), f.amplitude(f.outputs[output]), f.stable,
                    label=f"{r.spec.label} (size {r.size_max})", lw=2.2 if i == 0 else 1.1, zorder=1 if i == 0 else 2,
                    **({"color": "k"} if i == 0 else {}))
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"{output}: 1st harmonic amplitude [m]")
    readable_axes(ax)
    finish(fig, ax, frf_path, title=title, legend_size=7)

    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for r in results[1:]:
        if r.failure:
            continue
        err = max(r.curve_err_pct, 1e-6)
        ax.loglog(r.online_s, err, "o")
        ax.annotate(f"{r.spec.label} ({r.size_max})", (r.online_s, err), fontsize=7, xytext=(4, 3),
                    textcoords="offset points")
    ax.axvline(results[0].online_s, color="k", ls="--", lw=1,
               label=f"{results[0].spec.label} reference ({results[0].online_s:.1f} s)")
    ax.set_xlabel("online time [s]")
    ax.set_ylabel("largest curve error [% of peak]")
    readable_axes(ax, hz=None)
    return Path(frf_path), finish(fig, ax, pareto_path, title=title, legend_size=7)


def write_png(fig, path: Path, *, dpi: int) -> Path:
    """Save ``fig`` as a PNG through a temporary file (results.atomic_write: a run stopped half-way
    leaves the old picture or none), and close it."""
    from .results import atomic_write

    path = Path(path)
    atomic_write(path, lambda p: fig.savefig(p, dpi=dpi, format="png"))
    pyplot().close(fig)
    return path


def plot_force(response, force_N: float, path: Path, *, title: str = "") -> Path:
    """A force sweep (analysis.force): each output's first-harmonic amplitude against the force
    amplitude, ``force_N`` times the sweep's scale, log-log."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for n in response.outputs:
        ax.loglog(response.scale * force_N, response.amplitude(n), label=n)
    ax.set_xlabel("force amplitude [N]")
    ax.set_ylabel("first-harmonic amplitude [m]")
    readable_axes(ax, hz=None)
    return finish(fig, ax, path, title=title, title_size=10, dpi=100)


def plot_backbone(bb, path: Path, *, title: str = "") -> Path:
    """A nonlinear mode (analysis.nma.Backbone): frequency (Hz) and modal damping ratio against the
    amplitude at its output (log axis), and below the share of pair-time per contact state."""
    plt = pyplot()
    has_contact = bb.states.shape[-1] > 0
    n = 3 if has_contact else 2
    fig, axes = plt.subplots(n, 1, figsize=(7.0, 2.6 * n + 0.6), sharex=True, squeeze=False)
    a = bb.amplitude
    ax = axes[0, 0]
    ax.semilogx(a, bb.omega / (2 * np.pi), color="C0")
    ax.set_ylabel("frequency [Hz]")
    ax.set_title(title, fontsize=10)
    ax = axes[1, 0]
    ax.semilogx(a, bb.zeta, color="C3")
    ax.set_ylabel("damping ratio [-]")
    if has_contact:
        from .contact.law import SEPARATED, SLIP, STICK

        st = bb.states
        ax = axes[2, 0]
        for code, (name, color) in zip((STICK, SLIP, SEPARATED), STATE_COLORS):
            ax.semilogx(a, (st == code).mean(axis=(1, 2)), color=color, label=name)
        ax.set_ylim(-0.02, 1.02)
        ax.set_ylabel("share of\npair-time")
        ax.legend(fontsize=7, ncol=3, loc="center left")
    for k, row in enumerate(axes[:, 0]):
        readable_axes(row, hz="y" if k == 0 else None)
        row.grid(True, which="both", alpha=0.3)
    axes[-1, 0].set_xlabel(f"first-harmonic amplitude at {bb.output} [m]")
    fig.tight_layout()
    return write_png(fig, path, dpi=120)


def plot_compare_backbones(results, path: Path, *, title: str = "") -> Path:
    """Every method's backbone of a comparison (analysis.nma.compare_backbones): frequency (Hz, and
    rad/s on the right) and damping ratio against the amplitude at the output, log."""
    plt = pyplot()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7.0, 6.0), sharex=True)
    for r in results:
        if r.backbone is None:
            continue
        bb = r.backbone
        a1.semilogx(bb.amplitude, bb.omega / (2 * np.pi), label=r.label)
        a2.semilogx(bb.amplitude, bb.zeta, label=r.label)
    a1.set_ylabel("frequency [Hz]")
    a2.set_ylabel("damping ratio [-]")
    a2.set_xlabel(f"first-harmonic amplitude at {results[0].backbone.output} [m]")
    readable_axes(a1, hz="y")
    readable_axes(a2, hz=None)
    for ax in (a1, a2):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    a1.set_title(title, fontsize=10)
    fig.tight_layout()
    return write_png(fig, path, dpi=110)


def plot_synthesized(bb, synth: dict, path: Path, *, frf: dict | None = None, output: str | None = None,
                     title: str = "") -> Path:
    """The forced response synthesised from a backbone (analysis.nma.synthesize_frf), with the
    backbone itself, and a forced sweep's branch (load_branch of its branch.npz) where given."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 4.4))
    hz = 1.0 / (2 * np.pi)
    # the backbone up to twice the synthesised peak: beyond it no forcing of this level reaches
    top = 2.0 * synth["peak_amplitude"] if np.isfinite(synth["peak_amplitude"]) else np.inf
    keep = bb.amplitude <= top
    ax.plot(bb.omega[keep] * hz, bb.amplitude[keep], color="0.4", lw=1, label="backbone")
    for k, side in enumerate(("below", "above")):
        ax.plot(synth["omega"][k] * hz, synth["amplitude"], color="C1", label="synthesised (single mode)"
                if k == 0 else None)
    if frf is not None and output is not None:
        names = [str(s) for s in frf["output_names"]]
        if output in names:
            j = names.index(output)
            from .harmonics import Harmonics
            from .results import first_harmonic_amplitude

            out = frf["output_recovery"][j] if "output_recovery" in frf else int(frf["output_dofs"][j])
            amp = first_harmonic_amplitude(frf["U"], Harmonics(int(frf["H"]), int(frf["N"])), out)
            ax.plot(frf["omega"] * hz, amp, "k--", lw=1, label="forced sweep (HBM)")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"first-harmonic amplitude at {bb.output} [m]")
    ax.set_yscale("log")
    readable_axes(ax)
    return finish(fig, ax, path, title=title)
