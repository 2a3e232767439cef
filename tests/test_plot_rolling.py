"""Figures of a rolling run from plain arrays: what is drawn is what was given."""

import json

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from helpers import png_info
from twoscale import __version__
from twoscale.plot._figure import new_figure
from twoscale.plot.style import Caption, FigureStyle
from twoscale.plot.rolling import (
    bands_figure,
    plot_band_levels,
    plot_signals,
    plot_space_time,
    signals_figure,
    space_time_figure,
)

T = np.linspace(0.0, 0.01, 50)
FORCE = 3000 + 50 * np.sin(2 * np.pi * 800 * T)
AREA = 900 + 20 * np.cos(2 * np.pi * 800 * T)


def test_signals_on_two_stacked_panels_and_into_given_axes(tmp_path):
    fig = plot_signals(T, FORCE, AREA)
    top, bottom = fig.axes[:2]
    np.testing.assert_array_equal(top.lines[0].get_ydata(), FORCE)
    np.testing.assert_array_equal(bottom.lines[0].get_ydata(), AREA)
    assert bottom.get_xlabel() == "time (s)" and "contact area" in bottom.get_ylabel()
    mine = new_figure((5, 4), 50)
    axes = mine.subplots(2, 1)
    assert plot_signals(T, FORCE * 1e-3, AREA, axes=axes, signal_label="approach (mm)") is mine
    assert axes[0].get_ylabel() == "approach (mm)"
    with pytest.raises(ValueError, match="contact_area_mm2 has 3 values, expected 50"):
        plot_signals(T, FORCE, AREA[:3])
    path = signals_figure(
        tmp_path / "signals.png",
        T,
        FORCE,
        AREA,
        caption=Caption(scene={"influence": {"kind": "halfspace"}}, name="road"),
        style=FigureStyle(dpi=50),
    )
    size, text = png_info(path)
    assert size == (350, 250) and text["Software"] == f"twoscale {__version__}"
    assert text["Title"] == "road on the half-space: rolling signals"


def test_signals_with_the_drag_on_a_third_panel_with_its_mean(tmp_path):
    drag = 2.0 + np.sin(2 * np.pi * 800 * T)
    fig = plot_signals(T, FORCE, AREA, drag_N=drag)
    top, middle, bottom = fig.axes
    np.testing.assert_array_equal(bottom.lines[0].get_ydata(), drag)
    assert bottom.get_ylabel() == "drag (N)" and bottom.get_xlabel() == "time (s)" and middle.get_xlabel() == ""
    dashed = [ln for ln in bottom.lines if ln.get_linestyle() == "--"]
    assert len(dashed) == 1 and np.allclose(dashed[0].get_ydata(), drag.mean())
    assert "mean" in bottom.get_legend().get_texts()[0].get_text()
    with pytest.raises(ValueError, match="drag_N has 3 values, expected 50"):
        plot_signals(T, FORCE, AREA, drag_N=drag[:3])
    path = signals_figure(tmp_path / "signals.png", T, FORCE, AREA, drag_N=drag, style=FigureStyle(dpi=50))
    assert png_info(path)[0] == (350, 350)


def test_band_levels_bars_labels_and_highlight(tmp_path):
    nominal = np.array([250.0, 315.0, 400.0, 500.0, 630.0, 800.0, 1000.0, 1250.0, 1600.0, 2000.0, 2500.0])
    level = np.array([61.0, 64.5, 70.2, -np.inf, 68.0, 66.0, 62.0, 60.0, 58.0, 53.3, 47.0])
    fig = plot_band_levels(nominal, level, highlight=(315, 2000))
    ax = fig.axes[0]
    bars = ax.patches[1:]  # the first patch is the shaded span
    # the shading says what it is: it was a grey band without a word
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["shaded: 315-2000 Hz"]
    assert len(bars) == 10  # no bar for the band of zero power
    floor = 30.0  # 10 dB below the lowest level rounded down to 10 dB
    np.testing.assert_allclose([b.get_y() for b in bars], floor)
    np.testing.assert_allclose([b.get_y() + b.get_height() for b in bars], level[np.isfinite(level)])
    assert [t.get_text() for t in ax.get_xticklabels()] == [
        "250",
        "315",
        "400",
        "500",
        "630",
        "800",
        "1000",
        "1250",
        "1600",
        "2000",
        "2500",
    ]
    span = ax.patches[0].get_extents().transformed(ax.transData.inverted())
    assert span.x0 == pytest.approx(0.5) and span.x1 == pytest.approx(9.5)  # bands 315 ... 2000
    path = bands_figure(tmp_path / "bands.png", nominal, level, style=FigureStyle(dpi=40))
    assert png_info(path)[0] == (280, 160)


def test_space_time_draws_the_array_it_is_given(tmp_path):
    shifts = np.arange(-20.0, 20.0, 0.5)
    x = np.arange(-30.0, 30.0, 0.25)
    p = np.maximum(0.0, 1.0 - ((x[None, :] - shifts[:, None]) / 3.0) ** 2)  # a stone at body x = shift
    fig = plot_space_time(shifts, x, p)
    image = fig.axes[0].images[0]
    np.testing.assert_array_equal(image.get_array().filled(0.0), p)
    assert image.get_array().mask[0, 0] and not image.get_array().mask[0, 40]
    assert image.get_extent() == pytest.approx([-30.125, 29.875, -20.25, 19.75])
    assert fig.axes[0].get_ylabel() == "shift of the road (mm)"
    # non-uniform shifts: drawn cell by cell, at the given coordinates
    uneven = plot_space_time(np.r_[0.0, 1.0, 3.0], np.r_[0.0, 0.5], np.ones((3, 2)))
    mesh = uneven.axes[0].collections[0]
    assert mesh.get_array().size == 6
    with pytest.raises(ValueError, match=r"expected \(shifts, x\) = \(80, 240\)"):
        plot_space_time(shifts, x, p.T)
    spiked = p.copy()
    spiked[3, 3] = 1e3  # one peak does not flatten the scale
    path = space_time_figure(
        tmp_path / "st.png", shifts, x, spiked, caption=Caption(scene={"name": "demo"}), style=FigureStyle(dpi=40)
    )
    assert json.loads(png_info(path)[1]["Description"])["scene"] == {"name": "demo"}
    assert "clipped" in plot_space_time(shifts, x, spiked).axes[1].get_ylabel()


@pytest.mark.parametrize("which", ["signals", "bands", "space_time"])
def test_a_study_cases_long_title_stays_inside_the_figure(which):
    """A study case's title (section, body, material, load, speed, body, what is drawn) is
    wider than one line of the axes: it is broken into lines that the figure holds."""
    title = "example@0mm slick visco W=300N 50km/h on the half-space: pressure across the footprint"
    if which == "signals":
        fig = plot_signals(T, FORCE, AREA, title=title)
        ax = fig.axes[0]
    elif which == "bands":
        fig = plot_band_levels([400.0, 500.0], [40.0, 42.0], title=title)
        ax = fig.axes[0]
    else:
        x, s = np.linspace(-10, 10, 21), np.linspace(0, 5, 6)
        fig = plot_space_time(s, x, np.ones((6, 21)), title=title)
        ax = fig.axes[0]
    renderer = fig.canvas.get_renderer()
    box = ax.title.get_window_extent(renderer)
    assert box.x0 >= 0 and box.x1 <= fig.bbox.x1 and box.y1 <= fig.bbox.y1
    assert ax.get_title().replace("\n", " ") == title
