"""A height map: heights sampled on a square lattice, the data every other module of
:mod:`twoscale.surface` passes along.

Rows are y and columns x; cell ``(j, i)`` is centred at ``(x0 + i h, y0 + j h)`` (the
convention of :class:`twoscale.grid.Grid`). Heights are in mm and *larger is closer to
the body* (the summits touch first); missing samples are NaN until conditioning fills
them.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

from ..errors import SurfaceError
from ..grid import Grid


@dataclass(frozen=True, eq=False)
class HeightMap:
    """Heights on a square lattice.

    Parameters
    ----------
    heights : (ny, nx) array, mm
        Larger is closer to the body; NaN where the instrument gave no value.
    h : float
        Spacing of the samples, mm (> 0).
    x0, y0 : float, default 0
        Centre of cell (0, 0), mm.
    source : str, default ""
        Where the heights came from (file name), for messages and records.
    filled : int, default 0
        How many samples were missing (filled by conditioning, or left without material
        with ``fill = "mask"``).
    units : str, default "mm"
        Units the heights were given in before conditioning converted them to mm.
    units_from : str, default ""
        Where ``units`` came from: ``"map"`` (the file, or the :class:`RawMap`, declares
        them), ``"option"`` (``SurfaceOptions.units``, the ``[surface]`` table's
        ``units``), ``"default"`` (nothing said: taken as mm, their relief being
        plausible in mm); ``""`` for a map made here directly.
    measured_spacing : float or None, default None
        Spacing of the samples as measured, mm, when conditioning resampled them to ``h``.
    """

    heights: np.ndarray
    h: float
    x0: float = 0.0
    y0: float = 0.0
    source: str = ""
    filled: int = 0
    units: str = "mm"
    units_from: str = ""
    measured_spacing: float | None = None
    grid: Grid = field(init=False, repr=False)

    def __post_init__(self) -> None:
        z = np.array(self.heights, dtype=float)
        if z.ndim != 2:
            raise SurfaceError(f"{self._name()}: heights must be a 2-D grid, got shape {z.shape}")
        if not (np.isfinite(self.h) and self.h > 0):
            raise SurfaceError(f"{self._name()}: spacing must be a finite number > 0 (mm), got {self.h!r}")
        z.setflags(write=False)
        object.__setattr__(self, "heights", z)
        object.__setattr__(self, "grid", Grid(float(self.x0), float(self.y0), float(self.h), z.shape[1], z.shape[0]))

    def _name(self) -> str:
        return self.source or "height map"

    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape

    @property
    def missing(self) -> np.ndarray:
        """Where the heights are NaN, (ny, nx) bool."""
        return np.isnan(self.heights)

    def digest(self) -> str:
        """Hex digest of the heights and the lattice (a cache key ingredient)."""
        d = hashlib.sha256()
        d.update(f"{self.h!r}|{self.x0!r}|{self.y0!r}|{self.shape}".encode())
        d.update(memoryview(np.ascontiguousarray(self.heights)).cast("B"))  # (its bytes, not a copy)
        return d.hexdigest()
