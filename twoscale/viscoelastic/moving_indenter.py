"""Rigid indenters that move along +x under a body, for :func:`twoscale.viscoelastic.moving.solve_moving`.

The body (and the memory grid, fixed in it) stays; the indenter is shifted: a point of the
indenter at ``x`` appears at body ``x + shift`` (a road moving under a tread). Two kinds:

* :class:`MovingAsperities`: indenters given as tips (spheres, paraboloids, or the basins of
  a height map, :class:`twoscale.surface.indenter.MapAsperity`), each moved by ``shift``;
  both step solvers run on them (the two-scale method needs tips).
* :class:`MovingHeights`: any height field, given as a function of the indenter's own
  coordinates returning the recess (mm, ``inf`` where no material) and the owner (asperity
  index, -1 where none); the full-grid reference runs on it.

Any object with the methods of :class:`MovingIndenter` will do (e.g. a road whose stones
are kept only inside a tyre's footprint).

Both may add a ``face``: a height (mm) fixed in the body (a tyre's curvature, ``x^2 / 2R``),
added to the gap but not moved and not part of the slope. ``slope_x`` is the slope along x
of the moving surface's recess at the cell centres, central differences (one-sided next to
cells without material): the drag is ``h^2 sum p slope_x`` (:mod:`.moving`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable, Protocol, Sequence

import numpy as np

from ..grid import Grid
from ..indenters import Asperity, Surface, surface_on


class MovingIndenter(Protocol):
    """What :func:`twoscale.viscoelastic.moving.solve_moving` asks of a moving indenter."""

    @property
    def n_asperities(self) -> int:
        """Asperities the per-tip figures are reported for (the owners' range)."""

    def tips(self, shift: float) -> tuple | None:
        """The asperities at ``shift`` (mm) for the two-scale solver, in a fixed order and
        number; None when the indenter has no tips (then only the reference runs)."""

    def surface(self, grid: Grid, shift: float) -> tuple[Surface, np.ndarray]:
        """The rigid surface on ``grid`` at ``shift`` (recess mm, ``inf`` where no material,
        owners; any fixed face included) and the slope along x of its moving part."""

    def face_on(self, grid: Grid) -> np.ndarray:
        """The fixed face's height on ``grid`` (mm; zeros when none): the two-scale steps
        add it to each tip and patch cell as they add the history displacement."""


def slope_x(height: np.ndarray, h: float) -> np.ndarray:
    """``d height / dx`` (dimensionless) at the cell centres of a field of recesses (mm,
    ``inf`` where no material; 0 there), central where both neighbours have material."""
    diff = np.full(height.shape, np.nan)
    with np.errstate(invalid="ignore"):
        diff[:, :-1] = (height[:, 1:] - height[:, :-1]) / h
    ok = np.isfinite(diff)
    fwd = np.where(ok, diff, 0.0)
    bwd = np.zeros_like(fwd)
    bwd[:, 1:] = fwd[:, :-1]
    ok_b = np.zeros_like(ok)
    ok_b[:, 1:] = ok[:, :-1]
    n = ok.astype(float) + ok_b
    return np.where(n > 0, (fwd + bwd) / np.maximum(n, 1.0), 0.0)


def _face_on(face, grid: Grid) -> np.ndarray:
    if face is None:
        return np.zeros(grid.shape)
    X, Y = grid.centres()
    return np.asarray(face(X, Y), dtype=float) * np.ones(grid.shape)


def shifted(a: Asperity, shift: float, moved: dict) -> Asperity:
    """``a`` moved by ``shift`` along x; a height map's basins move with their shared map
    (``moved`` holds the moved map of each, so that they are still sampled together)."""
    basins = getattr(a, "basins", None)
    if basins is None:
        return dataclasses.replace(a, x=a.x + shift)
    if id(basins) not in moved:
        g = basins.grid
        moved[id(basins)] = dataclasses.replace(basins, grid=Grid(g.x0 + shift, g.y0, g.h, g.nx, g.ny))
    return dataclasses.replace(a, x=a.x + shift, basins=moved[id(basins)])


@dataclass(frozen=True, eq=False)
class MovingAsperities:
    """Tips moved along +x by the shift (module docstring).

    Parameters
    ----------
    asperities : sequence of Asperity
        At shift 0, mm.
    face : callable (X, Y) -> mm, optional
        A height fixed in the body, added to every cell's (not seen by the macro step's
        laws, only as the history displacement is: per tip and per patch cell).
    """

    asperities: Sequence[Asperity]
    face: Callable | None = None

    @property
    def n_asperities(self) -> int:
        return len(self.asperities)

    def tips(self, shift: float) -> tuple:
        """The asperities at ``shift`` (mm)."""
        moved: dict = {}
        return tuple(shifted(a, shift, moved) for a in self.asperities)

    def surface(self, grid: Grid, shift: float) -> tuple[Surface, np.ndarray]:
        """The rigid surface on ``grid`` at ``shift`` (face included) and the slope along x
        of the moving part."""
        s = surface_on(grid, self.tips(shift))
        slope = slope_x(s.height, grid.h)
        if self.face is None:
            return s, slope
        return Surface(grid, s.height + _face_on(self.face, grid), s.owner, s.n_asperities), slope

    def face_on(self, grid: Grid) -> np.ndarray:
        return _face_on(self.face, grid)


@dataclass(frozen=True, eq=False)
class MovingHeights:
    """A height field moved along +x by the shift (module docstring).

    Parameters
    ----------
    field : callable (X, Y) -> (recess, owner)
        In the indenter's own coordinates (mm): recess (mm, larger is farther from the
        body, ``inf`` where no material) and owning asperity (0-based, -1 where none).
    n_asperities : int
        Asperities the owners number.
    face : callable (X, Y) -> mm, optional
        A height fixed in the body (module docstring).
    """

    field: Callable
    n_asperities: int
    face: Callable | None = None

    def tips(self, shift: float):
        return None

    def surface(self, grid: Grid, shift: float) -> tuple[Surface, np.ndarray]:
        X, Y = grid.centres()
        height, owner = self.field(X - shift, Y)
        height = np.where(owner >= 0, np.asarray(height, dtype=float), np.inf)
        slope = slope_x(height, grid.h)
        surf = Surface(grid, height + _face_on(self.face, grid), np.asarray(owner, dtype=np.int64), self.n_asperities)
        return surf, slope

    def face_on(self, grid: Grid) -> np.ndarray:
        return _face_on(self.face, grid)

    @classmethod
    def from_map(cls, recess: np.ndarray, labels: np.ndarray, grid: Grid, *, face=None) -> MovingHeights:
        """A sampled map (recess mm with ``inf`` or NaN where missing, basin labels from 0,
        -1 where none) on ``grid`` at shift 0: linear in x between samples (the shift need
        not be a multiple of the spacing), nearest sample in y; no material off the map."""
        rec = np.where(np.isfinite(recess), recess, np.inf)
        lab = np.where(np.isfinite(recess), labels, -1).astype(np.int64)

        def field(X, Y):
            fx = (np.asarray(X) - grid.x0) / grid.h
            j = np.rint((np.asarray(Y) - grid.y0) / grid.h).astype(np.int64)
            i0 = np.floor(fx).astype(np.int64)
            w = fx - i0
            inside = (i0 >= 0) & (i0 + 1 < grid.nx) & (j >= 0) & (j < grid.ny)
            jc, ia, ib = np.clip(j, 0, grid.ny - 1), np.clip(i0, 0, grid.nx - 1), np.clip(i0 + 1, 0, grid.nx - 1)
            with np.errstate(invalid="ignore"):
                z = np.where(w > 0, (1 - w) * rec[jc, ia] + w * rec[jc, ib], rec[jc, ia])
            own = np.where(w < 0.5, lab[jc, ia], lab[jc, ib])
            ok = inside & np.isfinite(z)
            return np.where(ok, z, np.inf), np.where(ok, own, -1)

        n = int(lab.max()) + 1 if lab.size and lab.max() >= 0 else 0
        return cls(field, n, face)


__all__ = ["MovingAsperities", "MovingHeights", "MovingIndenter", "shifted", "slope_x"]
