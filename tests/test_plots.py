"""The pictures the commands write (issue 50, item 8): a reader must be able to take a number off
each.  Every frequency axis in Hz has omega in rad/s, the unit of the scene's inputs, on a secondary
axis, and every log axis has at least two labelled ticks inside its limits.  Each picture is drawn
from a small real result (the SDOF Jenkins oscillator, demos/sdof_jenkins.toml, at H = 3) and looked
at as it is saved."""
from __future__ import annotations

import matplotlib.figure
import numpy as np
import pytest

from conftest import ROOT
from jointfem.cli import main

SCENE = str(ROOT / "demos" / "sdof_jenkins.toml")
FAST = ["--harmonics", "3", "--samples", "64", "--quiet"]


def record_pictures(monkeypatch) -> dict:
    """{picture name: matplotlib Figure} of every picture saved from now on.  The figure is taken
    after its savefig, which draws it: its tick labels and the limits of its secondary axes are
    then those of the file."""
    figures = {}
    savefig = matplotlib.figure.Figure.savefig

    def spy(fig, path, *a, **k):
        savefig(fig, path, *a, **k)
        # by the picture's name: atomic_write saves "force.png" as ".force.png.<random>.png", the state
        # map "states_branch.png" as "states_branch.tmp.png", before renaming it
        figures[str(path).rsplit("/", 1)[-1].lstrip(".").split(".")[0] + ".png"] = fig

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", spy)
    return figures


@pytest.fixture
def saved(monkeypatch):
    """The pictures saved by the test (record_pictures)."""
    return record_pictures(monkeypatch)


def labelled_ticks(axis) -> list[tuple[float, str]]:
    """(position, text) of the tick labels a reader sees on ``axis`` (major and minor) inside its
    limits."""
    lo, hi = sorted(axis.get_view_interval())
    k = 0 if axis.axis_name == "x" else 1
    seen = {(t.get_position()[k], t.get_text()) for minor in (False, True) for t in axis.get_ticklabels(minor=minor)
            if t.get_visible() and t.get_text()}
    return sorted((x, s) for x, s in seen if lo * (1 - 1e-9) <= x <= hi * (1 + 1e-9))


def assert_log_axes_readable(ax):
    """Each log axis of ``ax`` shows at least two labelled ticks inside its limits."""
    for axis in (ax.xaxis, ax.yaxis):
        if axis.get_scale() == "log":
            ticks = labelled_ticks(axis)
            assert len(ticks) >= 2, (axis.axis_name, axis.get_view_interval(), ticks)


def assert_rad_s(ax, hz: str):
    """``ax`` has one secondary axis in rad/s facing its axis in Hz (``hz``: "x" or "y") whose
    scale is 2 pi times the Hz: its limits are 2 pi times those in Hz, and a frequency f in Hz and
    2 pi f on the secondary axis stand at the same place on the screen.  Returns that axis."""
    label = (lambda c: c.get_xlabel()) if hz == "x" else (lambda c: c.get_ylabel())
    rad_s = [c for c in ax.child_axes if "rad/s" in label(c)]
    assert len(rad_s) == 1, [label(c) for c in ax.child_axes]
    sec = rad_s[0]
    lim, sec_lim = (ax.get_xlim(), sec.get_xlim()) if hz == "x" else (ax.get_ylim(), sec.get_ylim())
    np.testing.assert_allclose(sec_lim, 2 * np.pi * np.asarray(lim), rtol=1e-12)
    k = 0 if hz == "x" else 1
    f = np.linspace(*lim, 5)

    def screen(a, values):
        """Where ``values`` on ``a``'s frequency axis stand on the screen (along that axis)."""
        other = np.full_like(values, a.get_ylim()[0] if hz == "x" else a.get_xlim()[0])
        return a.transData.transform(np.column_stack([values, other] if hz == "x" else [other, values]))[:, k]

    np.testing.assert_allclose(screen(sec, 2 * np.pi * f), screen(ax, f), atol=1e-6)
    # and its own ticks are labelled, at least two of them in its limits
    assert len(labelled_ticks(sec.xaxis if hz == "x" else sec.yaxis)) >= 2
    return sec


def test_force_picture_labels_both_log_axes_between_decades(tmp_path, saved):
    """force.png (`jointfem force`, plots.plot_force): a sweep from 0.02 to 0.4 N at 1.2 rad/s, all
    stuck (0.036 to 0.71 m), spans 1.3 decades in force and in amplitude with only 1e-1 as a decade
    inside either axis: without labels between the decades neither could be read."""
    assert main(["force", SCENE, "--omega", "1.2", "--scale", "0.1", "2.0", "--out", str(tmp_path / "f"), *FAST]) == 0
    (ax,) = saved["force.png"].axes
    assert ax.get_xscale() == ax.get_yscale() == "log"
    for lo, hi in (ax.get_xlim(), ax.get_ylim()):
        assert [d for d in (0.01, 0.1, 1.0) if lo < d < hi] == [0.1], (lo, hi)  # one decade inside
    assert_log_axes_readable(ax)
    # the labels name their ticks: 0.2 N is written as 2 x 10^-1 where it stands
    assert any(abs(x - 0.2) < 1e-12 and r"2\times10^{-1}" in s for x, s in labelled_ticks(ax.xaxis))


@pytest.fixture(scope="module")
def backbone_pictures(tmp_path_factory):
    """{name: Figure} of `jointfem nma` on the oscillator from 0.3 to 5 m (stuck below 1 m, then
    slipping: 0.225 Hz down to about 0.17 Hz)."""
    with pytest.MonkeyPatch.context() as mp:
        figures = record_pictures(mp)
        out = tmp_path_factory.mktemp("nma")
        assert main(["nma", SCENE, "--set", "nma.amplitude_range=[0.3, 5.0]", "--out", str(out), *FAST]) == 0
    return figures


def test_backbone_picture_gives_its_frequency_in_rad_s_and_labels_its_amplitude(backbone_pictures):
    """backbone.png (plots.plot_backbone): the frequency (y, Hz) has omega in rad/s on the right,
    2 pi times the Hz; the amplitude axis that the rows share spans 1.3 decades with only 1 m as a
    decade inside, and is labelled between them."""
    fig = backbone_pictures["backbone.png"]
    top, *rest = fig.axes
    sec = assert_rad_s(top, "y")
    # the stuck mode, sqrt(k + kt) = sqrt(2) rad/s, at 0.225 Hz: inside both axes' limits
    assert top.get_ylim()[0] < np.sqrt(2) / (2 * np.pi) < top.get_ylim()[1]
    assert sec.get_ylim()[0] < np.sqrt(2) < sec.get_ylim()[1]
    bottom = rest[-1]
    assert all(ax.get_shared_x_axes().joined(ax, bottom) for ax in fig.axes)
    lo, hi = bottom.get_xlim()
    assert bottom.get_xscale() == "log" and [d for d in (0.1, 1.0, 10.0) if lo < d < hi] == [1.0], (lo, hi)
    assert_log_axes_readable(bottom)


def test_synthesized_frf_picture_gives_its_frequency_in_rad_s(backbone_pictures):
    """frf_synthesized.png (plots.plot_synthesized): omega in rad/s on top of the Hz, as frf.png,
    and its log amplitude axis labelled at two ticks or more."""
    (ax,) = backbone_pictures["frf_synthesized.png"].axes
    sec = assert_rad_s(ax, "x")
    assert sec.get_xlim()[0] < np.sqrt(2) < sec.get_xlim()[1]  # the stuck mode, 1.414 rad/s, in view
    assert ax.get_yscale() == "log"
    assert_log_axes_readable(ax)


def test_compare_backbone_picture_gives_its_frequency_in_rad_s_and_labels_its_amplitude(tmp_path, saved):
    """compare_backbone.png (`compare --analysis nma`, plots.plot_compare_backbones): as backbone.png,
    omega in rad/s on the right of the Hz and the shared amplitude axis (0.3 to 5 m) labelled between
    its decades."""
    assert main(["compare", SCENE, "--analysis", "nma", "--methods", "penalty:1:0", "--set",
                 "nma.amplitude_range=[0.3, 5.0]", "--out", str(tmp_path / "c"), *FAST]) == 0
    top, bottom = saved["compare_backbone.png"].axes
    assert [t.get_text() for t in top.get_legend().get_texts()] == ["full", "penalty:1"]
    sec = assert_rad_s(top, "y")
    assert sec.get_ylim()[0] < np.sqrt(2) < sec.get_ylim()[1]
    lo, hi = bottom.get_xlim()
    assert bottom.get_shared_x_axes().joined(top, bottom)
    assert bottom.get_xscale() == "log" and [d for d in (0.1, 1.0, 10.0) if lo < d < hi] == [1.0], (lo, hi)
    assert_log_axes_readable(bottom)


def test_state_map_of_a_sweep_gives_its_frequency_in_rad_s(tmp_path, saved):
    """states_branch.png of a frequency sweep (`jointfem plot`, viz.plot_state_map) has its columns
    at Hz as frf.png: both carry omega in rad/s on top, 2 pi times the Hz, over the sweep's 0.5 to 2
    rad/s (the scene's omega_range)."""
    out = tmp_path / "s"
    assert main(["frf", SCENE, "--out", str(out), *FAST]) == 0
    assert main(["plot", str(out), "--quiet"]) == 0
    for name in ("frf.png", "states_branch.png"):
        ax = saved[name].axes[0]
        sec = assert_rad_s(ax, "x")
        lo, hi = sec.get_xlim()
        assert lo <= 0.5 and 2.0 <= hi < 2.5, (name, lo, hi)


def test_levels_picture_gives_its_frequency_in_rad_s_and_labels_its_log_axis(tmp_path, saved):
    """levels.png (plots.plot_levels, demos/jointed_beam_levels.py), of sweeps at 0.1 N (stuck) and
    0.3 N (slipping about its peak): omega in rad/s on top of the Hz, and at least two labelled
    ticks on its log receptance axis."""
    from jointfem.analysis.frf import SweepOptions, compute_frf
    from jointfem.harmonics import Harmonics
    from jointfem.models.lumped import create_lumped
    from jointfem.plots import plot_levels

    from conftest import sdof

    sweeps = [(f"{F:g} N", compute_frf(create_lumped(sdof(F)), SweepOptions(0.5, 2.0, Harmonics(3, 64))))
              for F in (0.1, 0.3)]
    plot_levels(sweeps, "m.x", tmp_path / "levels.png")
    (ax,) = saved["levels.png"].axes
    sec = assert_rad_s(ax, "x")
    assert sec.get_xlim()[0] <= 0.5 and 2.0 <= sec.get_xlim()[1] < 2.5
    assert ax.get_yscale() == "log"
    assert_log_axes_readable(ax)


def test_compare_pictures_give_rad_s_and_label_the_pareto_log_axes(tmp_path, saved):
    """compare_frf.png (plots.plot_compare) has omega in rad/s on top of the Hz; compare_pareto.png,
    log-log, labels at least two ticks on each axis.  The online times are set to 0.3 s (the
    reference) and 0.02 s (the ROM), 1.2 decades with only 0.1 s as a decade inside, so that the
    time axis does not depend on the machine's speed."""
    import dataclasses

    from jointfem.analysis.compare import compare, parse_method
    from jointfem.analysis.frf import SweepOptions
    from jointfem.harmonics import Harmonics
    from jointfem.models.lumped import create_lumped
    from jointfem.plots import plot_compare
    from jointfem.rom import RomOptions

    from conftest import sdof

    results = compare(create_lumped(sdof(0.2)), [parse_method("penalty:1:0", RomOptions())],
                      SweepOptions(0.5, 2.0, Harmonics(3, 64)), output="m.x")
    assert [r.spec.label for r in results] == ["full", "penalty:1"] and not results[1].failure
    results = [dataclasses.replace(r, online_s=t) for r, t in zip(results, (0.3, 0.02))]
    plot_compare(results, "m.x", tmp_path / "compare_frf.png", tmp_path / "compare_pareto.png")
    (ax,) = saved["compare_frf.png"].axes
    sec = assert_rad_s(ax, "x")
    assert sec.get_xlim()[0] <= 0.5 and 2.0 <= sec.get_xlim()[1] < 2.5
    (ax,) = saved["compare_pareto.png"].axes
    assert ax.get_xscale() == ax.get_yscale() == "log"
    lo, hi = ax.get_xlim()
    assert [d for d in (0.01, 0.1, 1.0) if lo < d < hi] == [0.1], (lo, hi)
    assert_log_axes_readable(ax)
