"""Figures of a rolling run, from plain arrays (no result object needed).

* :func:`plot_signals`: a signal (the total load under penetration control, the approach
  under load control), the contact area and (when given) the drag against time, stacked
  panels;
* :func:`plot_band_levels`: third-octave levels against the bands' nominal labels (force
  levels in Hz, texture levels in wavelength);
* :func:`plot_space_time`: the pressure summed across y, for every shift (vertical) and
  body x (horizontal): a stone crossing the footprint draws a line of slope one.

Each takes ``ax=`` (``axes=`` for the stacked panels) and returns the Figure; the file
writers :func:`signals_figure`, :func:`bands_figure`, :func:`space_time_figure` compose
them into PNG files with the version and scene metadata (:func:`~twoscale.plot._figure.save_png`).
"""

from __future__ import annotations

from pathlib import Path
import numpy as np

from ._figure import figure_and_axes, new_figure, save_png
from .labels import X_MM, join_title, scene_text, set_fitted_title
from .scale import robust_scale
from .style import NO_CAPTION, PLAIN, Caption, FigureStyle

TIME_S = "time (s)"
SHIFT_MM = "shift of the road (mm)"
AREA_MM2 = "contact area (mm$^2$)"
DRAG_N = "drag (N)"
#: Colour of the space-time picture: the pressure summed across y times the cell size.
LINE_LOAD = "line load: pressure summed across y (N/mm)"


def _vector(name: str, values, n: int | None = None) -> np.ndarray:
    v = np.asarray(values, dtype=float).ravel()
    if n is not None and v.size != n:
        raise ValueError(f"{name} has {v.size} values, expected {n}")
    return v


def plot_signals(
    time_s,
    signal,
    contact_area_mm2,
    *,
    signal_label: str = "total load (N)",
    drag_N=None,
    axes=None,
    title: str | None = None,
    style: FigureStyle = PLAIN,
):
    """A signal, the contact area and (given ``drag_N``) the drag against time, on stacked
    panels sharing the time axis.

    Parameters
    ----------
    time_s, signal, contact_area_mm2 : (M,) arrays
        Times (s), the signal (unit in ``signal_label``) and the contact area (mm^2).
    signal_label : str, default "total load (N)"
        Axis label of the upper panel (``"approach (mm)"`` under load control).
    drag_N : (M,) array, optional
        The drag (N, the road on the body along +x): a third panel, with its mean over the
        run dashed (the hysteresis friction of a viscoelastic body).
    axes : two (three with ``drag_N``) matplotlib Axes, optional
        Draw into these; default a new Figure of ``style.size`` inches.
    title : str, optional
    style : FigureStyle, optional
        ``size`` ((7.0, 5.0) inches, (7.0, 7.0) with the drag), ``dpi`` (100).
    """
    t = _vector("time_s", time_s)
    panels = [
        (_vector("signal", signal, t.size), signal_label),
        (_vector("contact_area_mm2", contact_area_mm2, t.size), AREA_MM2),
    ]
    if drag_N is not None:
        panels.append((_vector("drag_N", drag_N, t.size), DRAG_N))
    if axes is None:
        fig = new_figure(style.pick("size", (7.0, 5.0 if len(panels) == 2 else 7.0)), style.pick("dpi", 100))
        axes = fig.subplots(len(panels), 1, sharex=True)
    else:
        fig = getattr(axes[0].figure, "figure", axes[0].figure)
    marker = "." if t.size <= 200 else None
    for ax, (values, label) in zip(axes, panels):
        ax.plot(t, values, lw=1.0, marker=marker, ms=3)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    if drag_N is not None:
        mean = float(np.mean(panels[2][0]))
        axes[2].axhline(mean, color="0.3", lw=1.0, ls="--", label=f"mean {mean:.4g} N")
        axes[2].axhline(0.0, color="0.6", lw=0.6)
        axes[2].legend(loc="best", fontsize="small")
    axes[len(panels) - 1].set_xlabel(TIME_S)
    if title:
        set_fitted_title(axes[0], title)
    return fig


def plot_band_levels(
    nominal,
    level_dB,
    *,
    ax=None,
    band_label: str = "third-octave band (Hz)",
    level_label: str = "level (dB re 1 N)",
    highlight: tuple[float, float] | None = None,
    title: str | None = None,
    style: FigureStyle = PLAIN,
):
    """Third-octave levels as bars over the bands' nominal labels.

    Parameters
    ----------
    nominal, level_dB : (B,) arrays
        Nominal band labels (Hz, or mm for texture wavelengths) and levels (dB); a band of
        zero power (``-inf``) has no bar.
    band_label, level_label : str
        Axis labels, e.g. ``"wavelength (mm)"`` and ``"texture level (dB re 1 um)"``.
    highlight : (low, high), optional
        Shade the bands whose labels lie in this range (e.g. 315-2000 Hz, the bands
        rolling-noise models take); a legend names the range.
    title : str, optional
    style : FigureStyle, optional
        ``size`` ((7.0, 4.0) inches), ``dpi`` (100).
    """
    fig, ax = figure_and_axes(ax, style.pick("size", (7.0, 4.0)), style.pick("dpi", 100), rect=(0.12, 0.2, 0.84, 0.7))
    labels = _vector("nominal", nominal)
    level = _vector("level_dB", level_dB, labels.size)
    position = np.arange(labels.size)
    finite = np.isfinite(level)
    floor = 10.0 * np.floor(level[finite].min() / 10.0) - 10.0 if finite.any() else 0.0
    if highlight is not None:
        inside = position[(labels >= min(highlight)) & (labels <= max(highlight))]
        if inside.size:
            unit = band_label[band_label.rfind("(") + 1 : -1] if band_label.endswith(")") else ""
            span = f"{min(highlight):g}-{max(highlight):g} {unit}".strip()
            ax.axvspan(inside[0] - 0.5, inside[-1] + 0.5, color="0.92", zorder=0, label=f"shaded: {span}")
            ax.legend(loc="upper right", fontsize="small")
    ax.bar(position[finite], level[finite] - floor, bottom=floor, width=0.8, color="C0", zorder=2)
    ax.set_xticks(position)
    ax.set_xticklabels([f"{v:g}" for v in labels], rotation=90 if labels.size > 12 else 0, fontsize=8)
    ax.set_xlim(-0.6, labels.size - 0.4)
    if finite.any():
        ax.set_ylim(floor, 5.0 * np.ceil(level[finite].max() / 5.0) + 5.0)
    if not labels.size:
        ax.text(
            0.5,
            0.5,
            "no band holds 3 FFT bins: the signal is too short",
            transform=ax.transAxes,
            ha="center",
            va="center",
        )
    ax.set_xlabel(band_label)
    ax.set_ylabel(level_label)
    ax.grid(axis="y", alpha=0.3, zorder=1)
    if title:
        set_fitted_title(ax, title)
    return fig


def _uniform(v: np.ndarray) -> bool:
    step = np.diff(v)
    return v.size >= 2 and bool(np.all(step > 0)) and np.allclose(step, step[0], rtol=1e-6)


def plot_space_time(
    shifts_mm,
    x_mm,
    pressure,
    *,
    ax=None,
    colour_label: str = LINE_LOAD,
    title: str | None = None,
    style: FigureStyle = PLAIN,
):
    """The pressure summed across y for every shift (vertical) and body x (horizontal).

    Parameters
    ----------
    shifts_mm : (M,) array
        Shifts of the road, mm (increasing).
    x_mm : (K,) array
        Body x of the columns, mm (increasing).
    pressure : (M, K) array
        Pressure summed across y at each shift and x, times the cell size (the line
        load, N/mm; another quantity with its own ``colour_label``); zero is
        drawn white, and the colour scale ends at the 99th percentile when one peak
        would flatten it (:func:`~twoscale.plot.robust_scale`).
    title : str, optional
    style : FigureStyle, optional
        ``cmap`` ("viridis"), ``size`` ((6.4, 5.6) inches), ``dpi`` (100).
    """
    cmap = style.pick("cmap", "viridis")
    s, x = _vector("shifts_mm", shifts_mm), _vector("x_mm", x_mm)
    p = np.asarray(pressure, dtype=float)
    if p.shape != (s.size, x.size):
        raise ValueError(f"pressure has shape {p.shape}, expected (shifts, x) = {(s.size, x.size)}")
    fig, ax = figure_and_axes(ax, style.pick("size", (6.4, 5.6)), style.pick("dpi", 100), rect=(0.13, 0.1, 0.72, 0.82))
    scale = robust_scale(p)
    shown = np.ma.masked_less_equal(p, 0.0)
    if _uniform(s) and _uniform(x):
        hx, hs = 0.5 * (x[1] - x[0]), 0.5 * (s[1] - s[0])
        image = ax.imshow(
            shown,
            extent=(x[0] - hx, x[-1] + hx, s[0] - hs, s[-1] + hs),
            origin="lower",
            aspect="auto",
            norm=scale.norm(),
            cmap=cmap,
            interpolation="nearest",
        )
    else:
        image = ax.pcolormesh(x, s, shown, shading="nearest", norm=scale.norm(), cmap=cmap, rasterized=True)
    bar = fig.colorbar(image, ax=ax, extend=scale.extend)
    bar.set_label(colour_label if not scale.clipped else f"{colour_label}, clipped: peak {scale.peak:.3g}")
    ax.set_xlabel(f"body {X_MM}")
    ax.set_ylabel(SHIFT_MM)
    if title:
        set_fitted_title(ax, title)
    return fig


def signals_figure(
    path,
    time_s,
    signal,
    contact_area_mm2,
    *,
    signal_label: str = "total load (N)",
    drag_N=None,
    caption: Caption = NO_CAPTION,
    style: FigureStyle = PLAIN,
) -> Path:
    """Write :func:`plot_signals` to ``path`` (PNG); the title names the caption's scene and
    body (``style.dpi`` default 110)."""
    title = join_title(scene_text(caption.scene, caption.name), "rolling signals")
    fig = plot_signals(
        time_s,
        signal,
        contact_area_mm2,
        signal_label=signal_label,
        drag_N=drag_N,
        title=title,
        style=FigureStyle(dpi=style.pick("dpi", 110)),
    )
    fig.tight_layout(rect=(0, 0.02, 1, 1))
    return save_png(fig, path, title=title, scene=caption.scene)


def bands_figure(
    path,
    nominal,
    level_dB,
    *,
    level_label: str = "force level (dB re 1 N)",
    band_label: str = "third-octave band (Hz)",
    highlight: tuple[float, float] | None = (315.0, 2000.0),
    caption: Caption = NO_CAPTION,
    style: FigureStyle = PLAIN,
) -> Path:
    """Write :func:`plot_band_levels` to ``path`` (PNG), 315-2000 Hz shaded by default
    (``style.dpi`` default 110)."""
    title = join_title(scene_text(caption.scene, caption.name), "third-octave levels")
    fig = plot_band_levels(
        nominal,
        level_dB,
        band_label=band_label,
        level_label=level_label,
        highlight=highlight,
        title=title,
        style=FigureStyle(dpi=style.pick("dpi", 110)),
    )
    legend = fig.axes[0].get_legend()
    if legend is not None and highlight == (315.0, 2000.0):  # say why these bands
        legend.get_texts()[0].set_text(legend.get_texts()[0].get_text() + ", the rolling-noise bands")
    return save_png(fig, path, title=title, scene=caption.scene)


def space_time_figure(
    path,
    shifts_mm,
    x_mm,
    pressure,
    *,
    colour_label: str = LINE_LOAD,
    caption: Caption = NO_CAPTION,
    style: FigureStyle = PLAIN,
) -> Path:
    """Write :func:`plot_space_time` to ``path`` (PNG; ``style.dpi`` default 110)."""
    title = join_title(scene_text(caption.scene, caption.name), "pressure across the footprint")
    fig = plot_space_time(
        shifts_mm, x_mm, pressure, colour_label=colour_label, title=title, style=FigureStyle(dpi=style.pick("dpi", 110))
    )
    return save_png(fig, path, title=title, scene=caption.scene)
