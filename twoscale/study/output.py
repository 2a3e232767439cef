"""CSV files of the study; each starts with comment lines recording the program version,
the units and the parameters, so a table can be read back and the run rebuilt."""
from __future__ import annotations

import csv
import pathlib

import numpy as np

from .._version import __version__
from .cases import MAP_SPACINGS
from .run import StudyResult

ERROR_COLUMNS = ("d_over_2R", "err_p0_percent", "err_p_percent", "sweeps", "blocks", "macro_iterations",
                 "patch_growths", "t_twoscale_s", "t_macro_s", "t_micro_s", "t_reference_s",
                 "cells_twoscale", "cells_reference", "total_load_N", "mean_pressure_MPa", "converged")


def _header(study: StudyResult, layout: str, what: str) -> list[str]:
    case = study.cases[layout][0].case
    return [f"# twoscale {__version__}: paper study ({what}), layout {layout}",
            f"# units: mm, N, MPa; E = {case.material.E} MPa, nu = {case.material.nu}, R = {case.R} mm, "
            f"approach d = {case.penetration} mm, cell h = {case.h} mm, exact spheres",
            f"# quick = {study.quick}; reference solver = {study.reference_method} on the same lattice"]


def _write(path: pathlib.Path, header: list[str], columns, rows) -> pathlib.Path:
    with open(path, "w", newline="", encoding="utf-8") as fh:
        for line in header:
            fh.write(line + "\n")
        w = csv.writer(fh)
        w.writerow(columns)
        w.writerows(rows)
    return path


def error_rows(study: StudyResult, layout: str) -> list[tuple]:
    """One row per d/2R: the fig. 6 indicators, sweeps and blocks, timings and sizes."""
    rows = []
    for r in study.cases[layout]:
        ts, macro, micro = r.twoscale, r.twoscale.details.macro, r.twoscale.details.micro
        # blocks of the sweeps: patches apart, or merged where contacts are close
        rows.append((r.case.spacing, r.err_p0_percent, r.err_p_percent, r.sweeps, len(ts.fields),
                     ts.iterations["macro"], micro.growths, ts.timings_s["total"], macro.seconds, micro.seconds,
                     r.reference_seconds,
                     ts.n_cells, int(np.count_nonzero(r.reference_cells)), ts.total_load, r.mean_pressure,
                     ts.converged))
    return rows


def write_csv(study: StudyResult, out: pathlib.Path) -> list[pathlib.Path]:
    """errors_<layout>.csv (fig. 6), profile_<layout>.csv (fig. 5), map_<layout>_<s>.csv (figs. 3-4)."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for layout, results in study.cases.items():
        written.append(_write(out / f"errors_{layout}.csv", _header(study, layout, "fig. 6 errors"),
                              ERROR_COLUMNS, error_rows(study, layout)))
        rows = [(r.case.spacing, float(x), float(v)) for r in results for x, v in zip(*r.profile())]
        written.append(_write(out / f"profile_{layout}.csv",
                              _header(study, layout, "fig. 5 pressure on the vertical line of the upper asperity"),
                              ("d_over_2R", "r_over_R", "p_over_pm"), rows))
        for r in results:
            if r.case.spacing not in MAP_SPACINGS[layout]:
                continue
            X, Y = r.grid.centres()
            on = r.pressure > 0
            rows = zip(X[on] / r.case.R, Y[on] / r.case.R, r.pressure[on] / r.mean_pressure)
            written.append(_write(out / f"map_{layout}_{r.case.spacing:g}.csv",
                                  _header(study, layout, f"fig. 3-4 pressure map, d/2R = {r.case.spacing:g}"),
                                  ("x_over_R", "y_over_R", "p_over_pm"), rows))
    return written
