"""CSV files of the study: header on the first line; the program version, the units and the
parameters in the ``.csv-metadata.json`` beside each (:mod:`twoscale.io.tables`), so a
table can be read back and the run rebuilt."""

from __future__ import annotations

import pathlib

import numpy as np

from ..io.tables import write_table
from .cases import MAP_SPACINGS
from .run import StudyResult

ERROR_COLUMNS = (
    "d_over_2R",
    "err_p0_percent",
    "err_p_percent",
    "sweeps",
    "blocks",
    "macro_iterations",
    "patch_growths",
    "t_twoscale_s",
    "t_macro_s",
    "t_micro_s",
    "t_reference_s",
    "cells_twoscale",
    "cells_reference",
    "total_load_N",
    "mean_pressure_MPa",
    "converged",
)


def _record(study: StudyResult, layout: str, what: str) -> dict:
    case = study.cases[layout][0].case
    return {
        "study": f"paper study ({what}), layout {layout}",
        "units": {"length": "mm", "force": "N", "pressure": "MPa"},
        "parameters": {
            "E_MPa": case.material.E,
            "nu": case.material.nu,
            "R_mm": case.R,
            "approach_mm": case.penetration,
            "h_mm": case.h,
            "indenters": "exact spheres",
        },
        "quick": study.quick,
        "reference_solver": f"{study.reference_method} on the same lattice",
    }


def _write(out: pathlib.Path, name: str, record: dict, columns, rows) -> list[pathlib.Path]:
    return write_table(out, name, (dict(zip(columns, r)) for r in rows), columns, title=record["study"], record=record)


def error_rows(study: StudyResult, layout: str) -> list[tuple]:
    """One row per d/2R: the fig. 6 indicators, sweeps and blocks, timings and sizes."""
    rows = []
    for r in study.cases[layout]:
        ts, macro, micro = r.twoscale, r.twoscale.details.macro, r.twoscale.details.micro
        # blocks of the sweeps: patches apart, or merged where contacts are close
        rows.append(
            (
                r.case.spacing,
                r.err_p0_percent,
                r.err_p_percent,
                r.sweeps,
                len(ts.fields),
                ts.iterations["macro"],
                micro.growths,
                ts.timings_s["total"],
                macro.seconds,
                micro.seconds,
                r.reference_seconds,
                ts.n_cells,
                int(np.count_nonzero(r.reference_cells)),
                ts.total_load,
                r.mean_pressure,
                ts.converged,
            )
        )
    return rows


def write_csv(study: StudyResult, out: pathlib.Path) -> list[pathlib.Path]:
    """errors_<layout>.csv (fig. 6), profile_<layout>.csv (fig. 5), map_<layout>_<s>.csv (figs. 3-4)."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for layout, results in study.cases.items():
        written.extend(
            _write(
                out,
                f"errors_{layout}",
                _record(study, layout, "fig. 6 errors"),
                ERROR_COLUMNS,
                error_rows(study, layout),
            )
        )
        rows = [(r.case.spacing, float(x), float(v)) for r in results for x, v in zip(*r.profile())]
        written.extend(
            _write(
                out,
                f"profile_{layout}",
                _record(study, layout, "fig. 5 pressure on the vertical line of the upper asperity"),
                ("d_over_2R", "r_over_R", "p_over_pm"),
                rows,
            )
        )
        for r in results:
            if r.case.spacing not in MAP_SPACINGS[layout]:
                continue
            X, Y = r.grid.centres()
            on = r.pressure > 0
            rows = zip(X[on] / r.case.R, Y[on] / r.case.R, r.pressure[on] / r.mean_pressure)
            written.extend(
                _write(
                    out,
                    f"map_{layout}_{r.case.spacing:g}",
                    _record(study, layout, f"fig. 3-4 pressure map, d/2R = {r.case.spacing:g}"),
                    ("x_over_R", "y_over_R", "p_over_pm"),
                    rows,
                )
            )
    return written
