"""Regular grids of square cells (the micro-scale discretisation).

Fields on a grid are numpy arrays of shape ``(ny, nx)``: row index = y, column = x.
Cell ``(j, i)`` has its centre at ``(x0 + i*h, y0 + j*h)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np


@dataclass(frozen=True)
class Grid:
    """Rectangle of ``ny x nx`` square cells of side ``h``.

    Parameters
    ----------
    x0, y0 : float
        Centre of cell (0, 0), mm.
    h : float
        Cell side, mm (> 0).
    nx, ny : int
        Number of cells along x and y (>= 1).
    """

    x0: float
    y0: float
    h: float
    nx: int
    ny: int

    def __post_init__(self) -> None:
        if not (math.isfinite(self.h) and self.h > 0):
            raise ValueError(f"grid cell size h must be finite and > 0 (mm), got {self.h!r}")
        if int(self.nx) < 1 or int(self.ny) < 1:
            raise ValueError(f"grid needs nx, ny >= 1, got nx={self.nx!r}, ny={self.ny!r}")

    # ------------------------------------------------------------------ constructors
    @classmethod
    def covering(
        cls, xmin: float, xmax: float, ymin: float, ymax: float, h: float, *, anchor: tuple[float, float] = (0.0, 0.0)
    ) -> "Grid":
        """Smallest grid of cell size ``h`` whose cells cover the box, with cell
        centres on the lattice ``anchor + h * Z^2`` (so grids built with the same
        ``h`` and anchor are aligned and can exchange cells)."""
        ax, ay = anchor
        i0 = math.floor((xmin - ax) / h + 0.5)
        i1 = math.ceil((xmax - ax) / h - 0.5)
        j0 = math.floor((ymin - ay) / h + 0.5)
        j1 = math.ceil((ymax - ay) / h - 0.5)
        i1, j1 = max(i1, i0), max(j1, j0)
        return cls(ax + i0 * h, ay + j0 * h, h, i1 - i0 + 1, j1 - j0 + 1)

    # ------------------------------------------------------------------ geometry
    @property
    def shape(self) -> tuple[int, int]:
        return (self.ny, self.nx)

    @property
    def size(self) -> int:
        return self.nx * self.ny

    @property
    def x(self) -> np.ndarray:
        """Cell-centre x coordinates, shape (nx,), mm."""
        return self.x0 + self.h * np.arange(self.nx)

    @property
    def y(self) -> np.ndarray:
        """Cell-centre y coordinates, shape (ny,), mm."""
        return self.y0 + self.h * np.arange(self.ny)

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Cell-centre coordinates ``(X, Y)``, each of shape (ny, nx), mm (read-only: computed
        once per grid, the solvers ask for them on every sweep)."""
        return self._centres

    @cached_property
    def _centres(self) -> tuple[np.ndarray, np.ndarray]:
        X, Y = np.meshgrid(self.x, self.y)
        X.setflags(write=False)
        Y.setflags(write=False)
        return X, Y

    def points(self) -> np.ndarray:
        """Cell centres as an array of shape (ny*nx, 2), row-major (x fastest)."""
        X, Y = self.centres()
        return np.column_stack([X.ravel(), Y.ravel()])

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """Outer edges ``(xmin, xmax, ymin, ymax)`` of the cells, mm."""
        hh = 0.5 * self.h
        return (
            self.x0 - hh,
            self.x0 + (self.nx - 1) * self.h + hh,
            self.y0 - hh,
            self.y0 + (self.ny - 1) * self.h + hh,
        )

    def offset_in(self, parent: "Grid") -> tuple[int, int]:
        """Integer offset ``(di, dj)`` of this grid's cell (0,0) in an aligned ``parent``."""
        if not math.isclose(self.h, parent.h, rel_tol=1e-12):
            raise ValueError(f"grids have different cell sizes {self.h} and {parent.h}")
        di = (self.x0 - parent.x0) / self.h
        dj = (self.y0 - parent.y0) / self.h
        ri, rj = round(di), round(dj)
        if abs(di - ri) > 1e-6 or abs(dj - rj) > 1e-6:
            raise ValueError("grids are not aligned on the same lattice")
        return int(ri), int(rj)

    def window_in(self, parent: "Grid") -> tuple[slice, slice]:
        """The (rows, columns) slices of this grid's cells in an aligned ``parent``."""
        di, dj = self.offset_in(parent)
        return slice(dj, dj + self.ny), slice(di, di + self.nx)

    def embed_in(self, values: np.ndarray, parent: "Grid") -> np.ndarray:
        """``values`` on this grid placed on an aligned ``parent`` that contains it, zero
        elsewhere (e.g. a pressure carried to a larger grid as a warm start)."""
        out = np.zeros(parent.shape)
        out[self.window_in(parent)] = values
        return out

    def subgrid(self, i0: int, j0: int, nx: int, ny: int) -> "Grid":
        """The aligned sub-grid starting at cell ``(j0, i0)`` of this grid."""
        return Grid(self.x0 + i0 * self.h, self.y0 + j0 * self.h, self.h, nx, ny)


def offsets_in(grids, parent: Grid) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`Grid.offset_in` of many ``grids`` at once, by the same arithmetic: the integer
    offsets ``(di, dj)`` (two int64 arrays) of their cells (0, 0) in an aligned ``parent``."""
    x0 = np.array([g.x0 for g in grids], dtype=float)
    y0 = np.array([g.y0 for g in grids], dtype=float)
    h = np.array([g.h for g in grids], dtype=float)
    if np.any(np.abs(h - parent.h) > 1e-12 * np.maximum(np.abs(h), abs(parent.h))):
        raise ValueError(f"grids have cell sizes other than {parent.h}")
    di, dj = (x0 - parent.x0) / h, (y0 - parent.y0) / h
    ri, rj = np.rint(di), np.rint(dj)
    if np.any(np.abs(di - ri) > 1e-6) or np.any(np.abs(dj - rj) > 1e-6):
        raise ValueError("grids are not aligned on the same lattice")
    return ri.astype(np.int64), rj.astype(np.int64)


def covering_grids(xmin, xmax, ymin, ymax, h: float, *, anchor: tuple[float, float] = (0.0, 0.0)) -> list[Grid]:
    """:meth:`Grid.covering` of many boxes at once (arrays of their edges, mm), by the same
    arithmetic."""
    ax, ay = anchor
    if not all(np.all(np.isfinite(v)) for v in (xmin, xmax, ymin, ymax)):
        raise ValueError("a box to cover has an edge that is not finite")
    i0 = np.floor((np.asarray(xmin, dtype=float) - ax) / h + 0.5)
    i1 = np.maximum(np.ceil((np.asarray(xmax, dtype=float) - ax) / h - 0.5), i0)
    j0 = np.floor((np.asarray(ymin, dtype=float) - ay) / h + 0.5)
    j1 = np.maximum(np.ceil((np.asarray(ymax, dtype=float) - ay) / h - 0.5), j0)
    columns = (ax + i0 * h, ay + j0 * h, (i1 - i0 + 1).astype(np.int64), (j1 - j0 + 1).astype(np.int64))
    return [Grid(x0, y0, h, nx, ny) for x0, y0, nx, ny in zip(*(c.tolist() for c in columns))]
