"""A result for a notebook: its per-tip table as a pandas DataFrame, a compact HTML view, and
the full pressure map over the scene.

:meth:`ContactResult.to_dataframe` and ``ContactResult._repr_html_`` (what Jupyter shows for
a result at the end of a cell) call these; :func:`pressure_map_over` assembles the pressure
of every patch onto one grid.

Recipe: the full pressure map over the scene
--------------------------------------------
A two-scale result holds its pressure on one small grid per tip (``result.fields``, each a
:class:`~twoscale.results.PressureField` with its ``grid``). To see the whole scene at once::

    import twoscale
    from twoscale.display import pressure_map_over
    res = twoscale.solve(scene)
    P, extent = pressure_map_over(res)            # MPa, on one grid covering every patch
    import matplotlib.pyplot as plt
    plt.imshow(P, origin="lower", extent=extent)  # x right, y up, mm
    plt.colorbar(label="pressure (MPa)")

``pressure_map_over(res, grid=...)`` puts it on a grid of your own instead (aligned with the
patches, i.e. the same cell size ``h`` and cell centres on the same lattice, as
:meth:`twoscale.grid.Grid.covering` builds). The map of a scene of many tips far apart is mostly
zeros: its size is reported before it is allocated (:data:`MAX_CELLS`).
"""

from __future__ import annotations

import html

import numpy as np

from .grid import Grid

#: Cells :func:`pressure_map_over` builds before refusing (8 bytes each: 400 MB).
MAX_CELLS = 50_000_000
#: Tips listed by the HTML view (the most loaded first).
HTML_TIPS = 10


def result_rows(result, tips=None) -> list[dict]:
    """One dict per tip (columns of ``asperities.csv``; positions only with ``tips``)."""
    if tips is not None:
        from .io.asperity_csv import asperity_rows

        return asperity_rows(result, getattr(tips, "asperities", tips))
    s, macro = result.asperities, result.macro_forces
    rows = []
    for k in range(result.n_asperities):
        f, a = float(s.forces[k]), float(s.contact_areas[k])
        row = {
            "asperity": k + 1,
            "force_N": f,
            "contact_area_mm2": a,
            "max_pressure_MPa": float(s.max_pressures[k]),
            "mean_pressure_MPa": f / a if a > 0 else 0.0,
        }
        if macro is not None:
            row["macro_force_N"] = float(macro[k])
        rows.append(row)
    return rows


def result_frame(result, tips=None):
    """The per-tip table as a pandas DataFrame indexed by the tip number (from 1)."""
    try:
        import pandas as pd
    except ImportError as exc:  # pandas is not a dependency of the solver
        raise ImportError(f"ContactResult.to_dataframe needs pandas ({exc}): pip install pandas") from exc
    return pd.DataFrame(result_rows(result, tips)).set_index("asperity")


def headline(result) -> list[tuple[str, str]]:
    """(what, value) pairs of the numbers a reader looks for first."""
    out = []
    if result.title:
        out.append(("solved", result.title))
    out.append(("method", result.method if result.solver == result.method else f"{result.method} ({result.solver})"))
    out.append(("total load", f"{result.total_load:.5g} N"))
    out.append(("approach", f"{result.penetration:.5g} mm"))
    if result.tilt is not None:
        out.append(("tilt (alpha, beta)", f"{tilt_text(result)} rad"))
    area = f"{result.contact_area:.4g} mm2"
    if result.contact_ratio is not None:
        area += (
            f" = {100 * result.contact_ratio:.3g} % of the nominal {result.nominal_area:.4g} mm2"
            f" ({result.nominal_area_basis})"
        )
    out.append(("contact area", area))
    out.append(("converged", "yes" if result.converged else f"NO: {result.message}"))
    return out


def result_html(result) -> str:
    """A compact HTML view: the headline numbers, then the most loaded tips."""
    e = html.escape
    rows = "".join(
        f"<tr><th style='text-align:left'>{e(k)}</th><td style='text-align:left'>{e(v)}</td></tr>"
        for k, v in headline(result)
    )
    tips = result_rows(result)
    order = sorted(tips, key=lambda r: -r["force_N"])[:HTML_TIPS]
    head = "".join(f"<th>{e(c)}</th>" for c in order[0]) if order else ""
    body = "".join(
        "<tr>" + "".join(f"<td>{v:.4g}</td>" if isinstance(v, float) else f"<td>{v}</td>" for v in r.values()) + "</tr>"
        for r in order
    )
    more = (
        (f"<p>the {len(order)} most loaded of {len(tips)} tips; all of them: <code>result.to_dataframe()</code></p>")
        if len(tips) > len(order)
        else ""
    )
    return (
        f"<div><b>ContactResult</b><table>{rows}</table>"
        f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>{more}</div>"
    )


def pressure_map_over(result, grid: Grid | None = None) -> tuple[np.ndarray, tuple]:
    """The pressure of every field of ``result`` on one grid (MPa), and its extent.

    Parameters
    ----------
    result : ContactResult
    grid : Grid, optional
        Aligned with the result's fields (same ``h``, centres on the same lattice). Default:
        the smallest grid covering every field.

    Returns
    -------
    P : (ny, nx) array, MPa (zero where no field covers a cell)
    extent : (x0, x1, y0, y1), mm
        The cells' outer edges, as ``matplotlib.pyplot.imshow(P, origin="lower", extent=extent)`` takes it.

    Raises
    ------
    ValueError
        A grid of more than :data:`MAX_CELLS` cells (the message gives its size).
    """
    if grid is None:
        g0 = result.fields[0].grid
        x0 = min(f.grid.x0 for f in result.fields)
        y0 = min(f.grid.y0 for f in result.fields)
        x1 = max(f.grid.x0 + (f.grid.nx - 1) * f.grid.h for f in result.fields)
        y1 = max(f.grid.y0 + (f.grid.ny - 1) * f.grid.h for f in result.fields)
        nx, ny = int(round((x1 - x0) / g0.h)) + 1, int(round((y1 - y0) / g0.h)) + 1
        if nx * ny > MAX_CELLS:
            raise ValueError(
                f"the map over every patch would have {nx} x {ny} cells ({8e-9 * nx * ny:.2g} GB); "
                f"give a smaller grid= (at most {MAX_CELLS:,} cells)"
            )
        grid = Grid(x0, y0, g0.h, nx, ny)
    elif grid.size > MAX_CELLS:
        raise ValueError(f"grid has {grid.nx} x {grid.ny} cells, more than {MAX_CELLS:,}")
    h = grid.h
    extent = (grid.x0 - h / 2, grid.x0 + (grid.nx - 0.5) * h, grid.y0 - h / 2, grid.y0 + (grid.ny - 0.5) * h)
    return result.pressure_on(grid), extent


__all__ = ["result_rows", "result_frame", "result_html", "headline", "pressure_map_over"]


def tilt_text(result, spec: str = ".4g") -> str:
    """``"alpha, beta"`` of a tilted result, each shown as 0 when it moves no point of the
    tips' extent by more than 1e-6 of the approach (a solver's round-off, not a tilt)."""
    if result.tilt is None:
        return ""
    tips = max((abs(f.grid.x0) + f.grid.nx * f.grid.h for f in result.fields), default=1.0)
    tips = max(tips, max((abs(f.grid.y0) + f.grid.ny * f.grid.h for f in result.fields), default=1.0))
    floor = 1e-6 * abs(result.penetration) / tips
    return ", ".join("0" if abs(t) <= floor else format(t, spec) for t in result.tilt)
