"""PNG figures of the study (figs. 3-6); the only module of the study importing matplotlib."""
from __future__ import annotations

import pathlib

import numpy as np

from .cases import MAP_SPACINGS
from .run import StudyResult


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _maps(study: StudyResult, layout: str, path: pathlib.Path, title: str) -> pathlib.Path:
    plt = _plt()
    chosen = [r for r in study.cases[layout] if r.case.spacing in MAP_SPACINGS[layout]]
    from matplotlib.ticker import MaxNLocator

    # constrained layout keeps the suptitle, the panel titles and the colour bar apart
    fig, axes = plt.subplots(1, len(chosen), figsize=(4.2 * len(chosen), 4.4), squeeze=False,
                             layout="constrained")
    im = None
    for ax, r in zip(axes[0], chosen):
        R, g = r.case.R, r.grid
        ext = [v / R for v in g.bounds]
        p = np.ma.masked_where(r.pressure <= 0, r.pressure / r.mean_pressure)
        im = ax.imshow(p, origin="lower", extent=ext, vmin=0.0, vmax=1.6, cmap="viridis")
        for a in r.case.asperities:
            ax.add_patch(plt.Circle((a.x / R, a.y / R), 1.0, fill=False, ls=":", color="0.4"))
        ax.set_xlim(ext[0], ext[1])
        ax.set_ylim(ext[2], ext[3])
        ax.set_aspect("equal")
        ax.set_title(f"d/2R = {r.case.spacing:g}")
        ax.xaxis.set_major_locator(MaxNLocator(nbins=2, symmetric=True))   # narrow panels: few ticks
        ax.yaxis.set_major_locator(MaxNLocator(nbins=4))
        ax.set_xlabel("x/R")
        ax.set_ylabel("y/R")
    fig.colorbar(im, ax=list(axes[0]), label="p / p_m")
    fig.suptitle(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _profiles(study: StudyResult, path: pathlib.Path) -> pathlib.Path:
    plt = _plt()
    layouts = list(study.cases)
    fig, axes = plt.subplots(1, len(layouts), figsize=(5.5 * len(layouts), 4.0), squeeze=False)
    for ax, layout in zip(axes[0], layouts):
        for r in study.cases[layout]:
            x, v = r.profile()
            ax.plot(x, v, marker=".", label=f"d/2R = {r.case.spacing:g}")
        ax.set_xlabel("r/R")
        ax.set_ylabel("p / p_m")
        ax.set_title(f"{layout} spheres: upper asperity, vertical line")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _errors(study: StudyResult, path: pathlib.Path) -> pathlib.Path:
    plt = _plt()
    layouts = list(study.cases)
    fig, axes = plt.subplots(1, len(layouts), figsize=(5.5 * len(layouts), 4.0), squeeze=False)
    for ax, layout in zip(axes[0], layouts):
        rs = study.cases[layout]
        s = [r.case.spacing for r in rs]
        ax.semilogy(s, [r.err_p0_percent for r in rs], "o-", label="100 ||p0 - pr|| / ||pr||")
        ax.semilogy(s, [max(r.err_p_percent, 1e-12) for r in rs], "s-", label="100 ||p - pr|| / ||pr||")
        ax.axhline(0.1, color="0.5", ls="--", lw=0.8, label="acceptance 0.1 %")
        for r in rs:
            ax.annotate(f"{r.sweeps}", (r.case.spacing, r.err_p_percent), fontsize=7,
                        textcoords="offset points", xytext=(3, 3))
        ax.set_xlabel("d/2R")
        ax.set_ylabel("error (%)")
        ax.set_title(f"{layout} spheres (labels: sweeps)")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def write_figures(study: StudyResult, out: pathlib.Path) -> list[pathlib.Path]:
    """fig3_two_maps.png, fig4_seven_maps.png, fig5_profiles.png, fig6_errors.png."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    if "two" in study.cases:
        written.append(_maps(study, "two", out / "fig3_two_maps.png", "Two spheres, d = 0.05 R"))
    if "seven" in study.cases:
        written.append(_maps(study, "seven", out / "fig4_seven_maps.png", "Seven spheres, d = 0.1 R"))
    written.append(_profiles(study, out / "fig5_profiles.png"))
    written.append(_errors(study, out / "fig6_errors.png"))
    return written
