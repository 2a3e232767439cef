"""PNG figures of the paper's study (figs. 3-6); the only module of the study drawing.

Each panel is a function that takes ``ax=`` and returns the Figure (:func:`plot_map`,
:func:`plot_profiles`, :func:`plot_errors`); :func:`write_figures` composes them. Every
case runs on the elastic half-space, as in the paper. The maps keep the paper's dotted
circles of radius R (the spheres' bases) and its fixed scale 0 to 1.6 p_m.
"""

from __future__ import annotations

import pathlib

import numpy as np

from ..plot._figure import figure_and_axes, new_figure, save_png
from .cases import MAP_SPACINGS
from .run import StudyResult


def plot_map(r, *, ax=None, colourbar: bool = True):
    """One case's pressure over its mean, p / p_m, in x/R, y/R (0 to 1.6 as in the
    paper), with the spheres' bases dotted. Returns the Figure."""
    from matplotlib.patches import Circle
    from matplotlib.ticker import MaxNLocator

    fig, ax = figure_and_axes(ax, (4.6, 4.2), 120, rect=(0.14, 0.1, 0.66, 0.8))
    R, g = r.case.R, r.grid
    ext = [v / R for v in g.bounds]
    p = np.ma.masked_where(r.pressure <= 0, r.pressure / r.mean_pressure)
    im = ax.imshow(p, origin="lower", extent=ext, vmin=0.0, vmax=1.6, cmap="viridis")
    for a in r.case.asperities:
        ax.add_patch(Circle((a.x / R, a.y / R), 1.0, fill=False, ls=":", color="0.4"))
    ax.set_xlim(ext[0], ext[1])
    ax.set_ylim(ext[2], ext[3])
    ax.set_aspect("equal")
    ax.set_title(f"d/2R = {r.case.spacing:g}", fontsize=9)
    ax.xaxis.set_major_locator(MaxNLocator(nbins=2, symmetric=True))  # narrow panels: few ticks
    ax.yaxis.set_major_locator(MaxNLocator(nbins=4))
    ax.set_xlabel("x/R")
    ax.set_ylabel("y/R")
    if colourbar:
        fig.colorbar(im, ax=ax, label="p / p_m")
    return fig


def plot_profiles(study: StudyResult, layout: str, *, ax=None):
    """p / p_m along the vertical line through the upper asperity, one line per
    spacing d/2R. Returns the Figure."""
    fig, ax = figure_and_axes(ax, (5.5, 4.0), 120, rect=(0.12, 0.12, 0.84, 0.78))
    for r in study.cases[layout]:
        x, v = r.profile()
        ax.plot(x, v, marker=".", label=f"d/2R = {r.case.spacing:g}")
    ax.set_xlabel("r/R")
    ax.set_ylabel("p / p_m")
    ax.set_title(f"{layout} spheres on the half-space: upper asperity, vertical line", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(lw=0.3)
    return fig


def plot_errors(study: StudyResult, layout: str, *, ax=None):
    """Errors of the macro step's start (p0) and of the two-scale pressure (p) against
    the reference pressure, in percent, per spacing; labels: sweeps. Returns the Figure."""
    fig, ax = figure_and_axes(ax, (5.5, 4.0), 120, rect=(0.12, 0.12, 0.84, 0.78))
    rs = study.cases[layout]
    s = [r.case.spacing for r in rs]
    ax.semilogy(s, [r.err_p0_percent for r in rs], "o-", label="100 ||p0 - pr|| / ||pr||")
    ax.semilogy(s, [max(r.err_p_percent, 1e-12) for r in rs], "s-", label="100 ||p - pr|| / ||pr||")
    ax.axhline(0.1, color="0.5", ls="--", lw=0.8, label="acceptance 0.1 %")
    for r in rs:
        ax.annotate(
            f"{r.sweeps}", (r.case.spacing, r.err_p_percent), fontsize=7, textcoords="offset points", xytext=(3, 3)
        )
    ax.set_xlabel("d/2R")
    ax.set_ylabel("error (%)")
    ax.set_title(f"{layout} spheres on the half-space (labels: sweeps)", fontsize=9)
    ax.legend(fontsize=8)
    return fig


def _maps(study: StudyResult, layout: str, path: pathlib.Path, title: str) -> pathlib.Path:
    chosen = [r for r in study.cases[layout] if r.case.spacing in MAP_SPACINGS[layout]]
    W, H = 4.2 * len(chosen) + 1.2, 4.4
    fig = new_figure((W, H), 120)
    axes = [fig.add_axes([(0.6 + 4.2 * k) / W, 0.45 / H, 3.6 / W, 3.5 / H]) for k in range(len(chosen))]
    for ax, r in zip(axes, chosen):
        plot_map(r, ax=ax, colourbar=False)
    fig.colorbar(axes[0].images[0], cax=fig.add_axes([(W - 0.75) / W, 0.45 / H, 0.15 / W, 3.5 / H]), label="p / p_m")
    fig.suptitle(title, fontsize=10)
    return save_png(fig, path, title=title)


def _pair(study: StudyResult, draw, path: pathlib.Path, title: str) -> pathlib.Path:
    layouts = list(study.cases)
    fig = new_figure((5.5 * len(layouts), 4.0), 120)
    for k, layout in enumerate(layouts):
        draw(study, layout, ax=fig.add_axes([(k + 0.12) / len(layouts), 0.12, 0.8 / len(layouts), 0.76]))
    return save_png(fig, path, title=title)


def write_figures(study: StudyResult, out: pathlib.Path) -> list[pathlib.Path]:
    """fig3_two_maps.png, fig4_seven_maps.png, fig5_profiles.png, fig6_errors.png."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    if "two" in study.cases:
        written.append(_maps(study, "two", out / "fig3_two_maps.png", "Two spheres on the half-space, d = 0.05 R"))
    if "seven" in study.cases:
        written.append(_maps(study, "seven", out / "fig4_seven_maps.png", "Seven spheres on the half-space, d = 0.1 R"))
    written.append(_pair(study, plot_profiles, out / "fig5_profiles.png", "pressure profiles (paper fig. 5)"))
    written.append(_pair(study, plot_errors, out / "fig6_errors.png", "two-scale errors (paper fig. 6)"))
    return written
