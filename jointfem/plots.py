"""Plots (matplotlib, Agg backend: no display needed).  Imported lazily by the CLI."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .results import FrequencyResponse


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_frf(frf: FrequencyResponse, path: Path, *, title: str = "") -> Path:
    """FRF of every output (first-harmonic amplitude and half peak-to-peak, m, against Hz), and
    below it the share of contact pairs sticking, slipping and separated along the branch."""
    plt = _pyplot()
    has_contact = frf.states.shape[-1] > 0
    fig, axes = plt.subplots(2 if has_contact else 1, 1, figsize=(7.5, 6.5 if has_contact else 4.2), sharex=True,
                             squeeze=False, gridspec_kw={"height_ratios": [3, 1.2]} if has_contact else None)
    ax = axes[0, 0]
    f_hz = frf.omega / (2 * np.pi)
    for name, dof in frf.outputs.items():
        line, = ax.plot(f_hz, frf.amplitude(dof), label=f"{name}: 1st harmonic")
        ax.plot(f_hz, frf.half_peak_to_peak(dof), "--", color=line.get_color(), lw=1, label=f"{name}: half peak-to-peak")
    ax.set_ylabel("amplitude [m]")
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title)
    if has_contact:
        fr = frf.state_fractions().mean(axis=1)  # (points, 3)
        ax2 = axes[1, 0]
        # lines, not a stack: a branch that folds back in frequency must stay readable
        for k, (name, color) in enumerate((("stick", "#4c9a2a"), ("slip", "#f0a30a"), ("separated", "#c8102e"))):
            ax2.plot(f_hz, fr[:, k], color=color, label=name)
        ax2.set_ylim(-0.02, 1.02)
        ax2.set_ylabel("share of\npair-time")
        ax2.legend(fontsize=7, loc="center left", ncol=3)
    axes[-1, 0].set_xlabel("frequency [Hz]")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_levels(curves: list[tuple[str, FrequencyResponse]], output: str, path: Path, *, title: str = "") -> Path:
    """Several FRFs of one output (e.g. forcing levels), amplitude normalised by the force."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for label, frf in curves:
        ax.plot(frf.omega / (2 * np.pi), frf.amplitude(frf.outputs[output]), label=label)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"{output} receptance [m/N]")
    ax.set_yscale("log")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return Path(path)
