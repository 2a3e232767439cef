"""Pressure-sensor model, comparison indicators and measured data (docs/method.md section 5).

The paper's pressure sensor is a grid of 44 x 44 square cells of 1.9 mm; each cell
reports the mean pressure over its area. A computed pressure lives on micro cells
(side ``h``) that do not line up with the sensor cells, so :meth:`Sensor.average`
integrates the exact overlap of every micro cell with every sensor cell: the force on
the sensor equals the force of the computed pressure on the part of the plane the
sensor covers.

Indicators (paper section 4.3):

* ``e_M = 100 sum_k |P_k - Pref_k|^2 / sum_k |Pref_k|^2`` on tip forces (percent);
* ``e_m = 100 sum_i |p_i - pref_i|^2 / sum_i |pref_i|^2`` on sensor cells (percent).

Measured data: CSV of tip forces (``x,y,force`` or ``index,force``) and CSV of a sensor
map (``ny`` rows of ``nx`` pressures, MPa). Pivot centring from measured forces is the
paper's eq. 13.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from .grid import Grid
from .results import ContactResult

#: Sensor-cell sets over which :func:`e_m` sums.
E_M_CELLS = ("loaded", "reference")


@dataclass(frozen=True)
class Sensor:
    """A rectangular pressure sensor of square cells.

    Parameters
    ----------
    nx, ny : int, default 44
        Number of sensor cells along x and y.
    cell : float, default 1.9
        Side of a sensor cell, mm.
    centre : (float, float), default (0, 0)
        Centre of the sensor in scene coordinates, mm.
    """

    nx: int = 44
    ny: int = 44
    cell: float = 1.9
    centre: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("nx", "ny"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"sensor.{name} must be an integer >= 1, got {v!r}")
        if not (isinstance(self.cell, (int, float)) and math.isfinite(self.cell) and self.cell > 0):
            raise ValueError(f"sensor.cell must be a finite number > 0 (mm), got {self.cell!r}")
        c = tuple(self.centre)
        if len(c) != 2 or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in c):
            raise ValueError(f"sensor.centre must be two finite numbers (mm), got {self.centre!r}")
        object.__setattr__(self, "centre", (float(c[0]), float(c[1])))

    @property
    def grid(self) -> Grid:
        """The sensor cells as a :class:`~twoscale.grid.Grid` (cell centres, side ``cell``)."""
        x0 = self.centre[0] - 0.5 * (self.nx - 1) * self.cell
        y0 = self.centre[1] - 0.5 * (self.ny - 1) * self.cell
        return Grid(x0, y0, float(self.cell), int(self.nx), int(self.ny))

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.ny), int(self.nx))

    def average_field(self, grid: Grid, pressure: np.ndarray) -> np.ndarray:
        """Mean pressure on each sensor cell of a pressure given on ``grid``.

        Parameters
        ----------
        grid : Grid
            The cells carrying ``pressure`` (any cell size and position).
        pressure : (grid.ny, grid.nx) array
            Uniform pressure on each cell, MPa.

        Returns
        -------
        (ny, nx) array, MPa
            Sensor-cell means: the exact integral of the piecewise-constant pressure over
            each sensor cell divided by the cell area.
        """
        p = np.asarray(pressure, dtype=float)
        if p.shape != grid.shape:
            raise ValueError(f"pressure has shape {p.shape}, grid is {grid.shape}")
        if not np.all(np.isfinite(p)):
            raise ValueError("pressure contains non-finite values")
        s = self.grid
        ox = _overlaps(s.x0, s.h, s.nx, grid.x0, grid.h, grid.nx)  # (sensor nx, micro nx), mm
        oy = _overlaps(s.y0, s.h, s.ny, grid.y0, grid.h, grid.ny)
        # overlap area of micro cell (j, i) with sensor cell (J, I) is oy[J, j] * ox[I, i]
        return (oy @ p @ ox.T) / (s.h * s.h)

    def average(self, result: ContactResult) -> np.ndarray:
        """Mean computed pressure on each sensor cell, (ny, nx) array in MPa.

        ``result`` is a ContactResult or anything with its ``fields`` (e.g. what
        :func:`twoscale.io.vtk.read_vtk` returns).

        Every pressure patch of ``result`` is integrated exactly over the sensor cells
        (overlaps of micro and sensor cells), so ``average(result).sum() * cell**2``
        equals ``result.total_load`` whenever the sensor covers the contact.
        """
        out = np.zeros(self.shape)
        for f in result.fields:
            out += self.average_field(f.grid, f.pressure)
        return out

    def force(self, sensor_pressure: np.ndarray) -> float:
        """Total force of a sensor map, N (sum of cell means times cell area)."""
        return float(np.sum(sensor_pressure) * self.cell * self.cell)


def _overlaps(a0: float, a: float, na: int, b0: float, b: float, nb: int) -> np.ndarray:
    """Lengths (mm) of the overlaps of 1-D cells: ``na`` cells of side ``a`` centred at
    ``a0 + a*I`` against ``nb`` cells of side ``b`` centred at ``b0 + b*i``."""
    alo = a0 + a * np.arange(na) - 0.5 * a
    blo = b0 + b * np.arange(nb) - 0.5 * b
    lo = np.maximum(alo[:, None], blo[None, :])
    hi = np.minimum(alo[:, None] + a, blo[None, :] + b)
    return np.clip(hi - lo, 0.0, None)


# ---------------------------------------------------------------------- indicators
def _pair(P, P_ref, what: str) -> tuple[np.ndarray, np.ndarray]:
    P = np.asarray(P, dtype=float)
    R = np.asarray(P_ref, dtype=float)
    if P.shape != R.shape:
        raise ValueError(f"{what}: shapes differ, {P.shape} against reference {R.shape}")
    if P.size == 0:
        raise ValueError(f"{what}: empty arrays")
    for name, a in (("values", P), ("reference", R)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{what}: {name} contain non-finite numbers")
    return P, R


def e_M(P: Sequence[float], P_ref: Sequence[float]) -> float:
    """Macro-scale indicator on tip forces, percent (paper section 4.3).

    ``e_M = 100 sum_k |P_k - Pref_k|^2 / sum_k |Pref_k|^2``.

    Parameters
    ----------
    P : (N,) array
        Forces to judge, N.
    P_ref : (N,) array
        Reference (e.g. measured) forces, N, same asperity order; not all zero.
    """
    P, R = _pair(P, P_ref, "e_M")
    den = float(np.sum(R * R))
    if den == 0.0:
        raise ValueError("e_M: the reference forces are all zero")
    return 100.0 * float(np.sum((P - R) ** 2)) / den


def e_m(p: np.ndarray, p_ref: np.ndarray, *, cells: str = "loaded") -> float:
    """Micro-scale indicator on sensor-cell pressures, percent (paper section 4.3).

    ``e_m = 100 sum_i |p_i - pref_i|^2 / sum_i |pref_i|^2`` over loaded sensor cells.

    Parameters
    ----------
    p, p_ref : arrays of one shape
        Sensor-cell pressures to judge and the reference (e.g. measured), MPa.
    cells : {"loaded", "reference"}, default "loaded"
        Which cells are summed: ``"loaded"`` every cell where either map is non-zero
        (a cell loaded in only one map counts as a difference); ``"reference"`` only the
        cells loaded in the reference (as when the measured map has been thresholded
        and only its loaded cells are trusted).
    """
    if cells not in E_M_CELLS:
        raise ValueError(f"e_m: cells must be one of {E_M_CELLS}, got {cells!r}")
    p, r = _pair(p, p_ref, "e_m")
    mask = (r != 0) if cells == "reference" else ((r != 0) | (p != 0))
    den = float(np.sum(r[mask] ** 2))
    if den == 0.0:
        raise ValueError("e_m: the reference pressure is zero on every sensor cell")
    return 100.0 * float(np.sum((p[mask] - r[mask]) ** 2)) / den


# ---------------------------------------------------------------------- pivot centring
def pivot_from_forces(tips: np.ndarray, forces: Sequence[float], *, total: float | None = None) -> tuple[float, float]:
    """Pivot position from measured tip forces (paper eq. 13).

    ``x0 = sum_k x_k P_k / Pbar``, ``y0 = sum_k y_k P_k / Pbar``.

    Parameters
    ----------
    tips : (N, 2) array
        Tip positions, mm.
    forces : (N,) array
        Measured tip forces, N (>= 0).
    total : float, optional
        Total load Pbar, N; default the sum of ``forces``.
    """
    t = np.asarray(tips, dtype=float)
    f = np.asarray(forces, dtype=float)
    if t.ndim != 2 or t.shape[1] != 2:
        raise ValueError(f"tips must have shape (N, 2), got {t.shape}")
    if f.shape != (t.shape[0],):
        raise ValueError(f"forces must have shape ({t.shape[0]},), got {f.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(f))):
        raise ValueError("tips and forces must be finite")
    if np.any(f < 0):
        raise ValueError(f"forces must be >= 0 (N), got min {f.min()!r}")
    P = float(f.sum()) if total is None else float(total)
    if not (math.isfinite(P) and P > 0):
        raise ValueError(f"total load must be finite and > 0 (N), got {P!r}")
    return float(t[:, 0] @ f / P), float(t[:, 1] @ f / P)


def centred_tips(tips: np.ndarray, forces: Sequence[float], *, total: float | None = None) -> np.ndarray:
    """Tips shifted by ``(-x0, -y0)`` so the pivot of eq. 13 is the origin, (N, 2) mm."""
    x0, y0 = pivot_from_forces(tips, forces, total=total)
    return np.asarray(tips, dtype=float) - np.array([x0, y0])


def forces_from_map(
    sensor_map: np.ndarray, tips: np.ndarray, *, sensor: Sensor = Sensor(), radius: float | None = None
) -> np.ndarray:
    """Tip forces integrated from a sensor pressure map (as the paper did for its measurements).

    Each loaded sensor cell goes to the nearest tip (its centre's distance), and a tip's
    force is the sum of its cells' pressure times the cell area.

    Parameters
    ----------
    sensor_map : (ny, nx) array
        Sensor-cell pressures, MPa.
    tips : (N, 2) array
        Tip positions, mm.
    sensor : Sensor, default ``Sensor()``
    radius : float, optional
        Only cells whose centre is within ``radius`` (mm) of their tip count (e.g. the
        indenters' base radius); default no limit.

    Returns
    -------
    (N,) array of forces, N.
    """
    P = np.asarray(sensor_map, dtype=float)
    if P.shape != sensor.shape:
        raise ValueError(f"sensor map has shape {P.shape}, the sensor is {sensor.shape}")
    t = np.asarray(tips, dtype=float)
    if t.ndim != 2 or t.shape[1] != 2 or len(t) == 0:
        raise ValueError(f"tips must have shape (N, 2) with N >= 1, got {t.shape}")
    if radius is not None and not (math.isfinite(radius) and radius > 0):
        raise ValueError(f"radius must be finite and > 0 (mm), got {radius!r}")
    X, Y = sensor.grid.centres()
    loaded = P != 0
    d2 = (X[loaded][:, None] - t[None, :, 0]) ** 2 + (Y[loaded][:, None] - t[None, :, 1]) ** 2
    nearest = np.argmin(d2, axis=1)
    keep = np.ones(len(nearest), bool) if radius is None else d2[np.arange(len(nearest)), nearest] <= radius**2
    area = sensor.cell * sensor.cell
    return area * np.bincount(nearest[keep], weights=P[loaded][keep], minlength=len(t))


# ---------------------------------------------------------------------- measured data
@dataclass(frozen=True)
class MeasuredForces:
    """Tip forces read from a CSV file.

    Attributes
    ----------
    force : (N,) array, N, in asperity order.
    tips : (N, 2) array of mm, or None when the file gives indices only.
    """

    force: np.ndarray
    tips: np.ndarray | None


def _data_rows(path: Path) -> list[tuple[int, list[str]]]:
    """Non-empty, non-comment CSV rows with their 1-based line numbers."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"cannot read {path}: {exc.strerror or exc}") from None
    rows = []
    for lineno, row in enumerate(csv.reader(text.splitlines()), start=1):
        cells = [c.strip() for c in row]
        if not any(cells) or cells[0].startswith("#"):
            continue
        rows.append((lineno, cells))
    return rows


def _number(s: str, path, lineno: int, column: str) -> float:
    try:
        v = float(s)
    except ValueError:
        raise ValueError(f"{path}:{lineno}: column {column!r} is not a number: {s!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{path}:{lineno}: column {column!r} is not finite: {s!r}")
    return v


def read_tip_forces(path: str | Path, *, n_asperities: int | None = None) -> MeasuredForces:
    """Read measured tip forces from a CSV file.

    The first data row is a header naming the columns: ``x,y,force`` (tip positions in
    mm and forces in N, rows in asperity order), ``asperity,force`` (the asperity's
    number from 1, as in every table and file the program writes; each of 1..N exactly
    once), or ``index,force`` (the same from 0, as Python counts). Blank lines and lines
    starting with ``#`` are skipped.

    Parameters
    ----------
    path : path-like
    n_asperities : int, optional
        When given, the number of rows must equal it.

    Raises
    ------
    ValueError
        Naming the file, line and column of anything malformed.
    """
    rows = _data_rows(Path(path))
    if not rows:
        raise ValueError(f"{path}: no data (expected a header 'x,y,force', 'asperity,force' or 'index,force')")
    (hline, header), body = rows[0], rows[1:]
    cols = [c.lower() for c in header]
    if cols not in (["x", "y", "force"], ["asperity", "force"], ["index", "force"]):
        raise ValueError(
            f"{path}:{hline}: header must be 'x,y,force', 'asperity,force' or 'index,force', got {','.join(header)!r}"
        )
    if not body:
        raise ValueError(f"{path}: header but no rows")
    vals = []
    for lineno, cells in body:
        if len(cells) != len(cols):
            raise ValueError(f"{path}:{lineno}: expected {len(cols)} columns, got {len(cells)}")
        vals.append([_number(c, path, lineno, name) for c, name in zip(cells, cols)])
        if vals[-1][-1] < 0:
            raise ValueError(f"{path}:{lineno}: force must be >= 0 (N), got {cells[-1]!r}")
    a = np.array(vals)
    if n_asperities is not None and len(a) != n_asperities:  # before the numbering, which counts the rows
        raise ValueError(f"{path}: {len(a)} forces for a scene of {n_asperities} asperities")
    if cols[0] in ("asperity", "index"):
        first = 1 if cols[0] == "asperity" else 0
        idx = a[:, 0] - first
        n = len(idx)
        if np.any(idx != np.round(idx)) or sorted(idx.astype(int).tolist()) != list(range(n)):
            raise ValueError(
                f"{path}: {cols[0]} must be the integers {first}..{n - 1 + first}, each once; got {a[:, 0].tolist()}"
            )
        force = np.zeros(n)
        force[idx.astype(int)] = a[:, 1]
        tips = None
    else:
        force, tips = a[:, 2].copy(), a[:, :2].copy()
    return MeasuredForces(force, tips)


def read_sensor_map(path: str | Path, *, sensor: Sensor = Sensor(), first_row: str = "ymin") -> np.ndarray:
    """Read a measured sensor pressure map from a CSV file.

    Parameters
    ----------
    path : path-like
        ``sensor.ny`` rows of ``sensor.nx`` comma-separated pressures, MPa (>= 0);
        no header; blank lines and ``#`` lines skipped.
    sensor : Sensor, default ``Sensor()`` (44 x 44 cells of 1.9 mm)
    first_row : {"ymin", "ymax"}, default "ymin"
        Whether the file's first row is the sensor row of smallest y (array order) or of
        largest y (as a picture is printed, top row first).

    Returns
    -------
    (ny, nx) array, MPa, row j at ``y = sensor.grid.y[j]``.
    """
    if first_row not in ("ymin", "ymax"):
        raise ValueError(f"first_row must be 'ymin' or 'ymax', got {first_row!r}")
    rows = _data_rows(Path(path))
    if len(rows) != sensor.ny:
        raise ValueError(f"{path}: {len(rows)} rows, the sensor has ny = {sensor.ny}")
    out = np.empty(sensor.shape)
    for j, (lineno, cells) in enumerate(rows):
        if len(cells) != sensor.nx:
            raise ValueError(f"{path}:{lineno}: {len(cells)} values, the sensor has nx = {sensor.nx}")
        out[j] = [_number(c, path, lineno, f"{i}") for i, c in enumerate(cells)]
    if np.any(out < 0):
        j, i = np.argwhere(out < 0)[0]
        raise ValueError(f"{path}: negative pressure {out[j, i]!r} MPa in row {j}, column {i}")
    return out[::-1].copy() if first_row == "ymax" else out
