"""A warm start of the micro step: the pressure of a neighbouring solve, moved with its tips.

Consecutive solves of nearly the same scene (a second solve, the next position of a road
rolling under the body, the next time step of a load history) have nearly the same pressure
around each tip. :class:`PressureStart` keeps, for every asperity of a previous solve, the
cells it loaded (as lattice offsets from its tip) and their pressure; on a new solve each
asperity's cells are moved with its tip (to the nearest cell), cut to the new patch and
scaled by the ratio of the tip's new macro force to its previous one. The block iterations then start from it in place
of the paper's eq. 7 (which still starts the asperities the previous solve did not load),
and the union CG starts from it on its box. The answer is the same to the tolerances: only
the start changes; a start close to the answer saves the eq. 7 solves and most sweeps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..grid import Grid


@dataclass(frozen=True)
class PressureStart:
    """Pressure of a previous solve, by asperity, in lattice offsets from its tip.

    Attributes
    ----------
    h : float
        Cell side of the previous solve, mm (a start only serves a solve at the same h).
    owner : (M,) int array
        Asperity (previous numbering, 0-based) of each loaded cell, sorted.
    di, dj : (M,) int arrays
        Cell offset from the asperity's tip along x and y, cells (rounded).
    pressure : (M,) array, MPa
    starts : (N + 1,) int array
        Asperity k's cells are ``starts[k]:starts[k + 1]``.
    forces : (N,) array, N
        The previous macro force of each asperity: a new solve scales asperity k's
        pressure by its new macro force over this one (the macro step's error, a few
        percent of a tip's force where contacts interact strongly, cancels; the pressure
        itself is the previous micro step's).
    """

    h: float
    owner: np.ndarray
    di: np.ndarray
    dj: np.ndarray
    pressure: np.ndarray
    starts: np.ndarray
    forces: np.ndarray

    @classmethod
    def from_fields(cls, fields, tips: np.ndarray, h: float, forces: np.ndarray) -> "PressureStart":
        """The start the pressure ``fields`` (PressureField, owner numbered like ``tips``,
        (N, 2) mm) give; ``forces``: the macro forces of that solve, N."""
        tips = np.asarray(tips, dtype=float).reshape(-1, 2)
        owner, di, dj, p = [], [], [], []
        for f in fields:
            mine = (f.pressure > 0) & (f.owner >= 0)
            if not mine.any():
                continue
            j, i = np.nonzero(mine)
            k = f.owner[mine]
            X, Y = f.grid.x0 + i * f.grid.h, f.grid.y0 + j * f.grid.h
            owner.append(k)
            di.append(np.rint((X - tips[k, 0]) / h).astype(np.int64))
            dj.append(np.rint((Y - tips[k, 1]) / h).astype(np.int64))
            p.append(f.pressure[mine])
        cat = lambda v, t: np.concatenate(v).astype(t) if v else np.zeros(0, t)
        owner_a, di_a, dj_a, p_a = cat(owner, np.int64), cat(di, np.int64), cat(dj, np.int64), cat(p, float)
        order = np.argsort(owner_a, kind="stable")
        owner_a, di_a, dj_a, p_a = owner_a[order], di_a[order], dj_a[order], p_a[order]
        starts = np.searchsorted(owner_a, np.arange(len(tips) + 1))
        return cls(float(h), owner_a, di_a, dj_a, p_a, starts, np.asarray(forces, dtype=float).copy())

    @property
    def n_asperities(self) -> int:
        return len(self.starts) - 1

    def loaded(self, k: int) -> bool:
        """The previous solve loaded asperity ``k`` (previous numbering)."""
        return 0 <= k < self.n_asperities and self.starts[k + 1] > self.starts[k]

    def cells(self, k: int, tip: tuple[float, float], grid: Grid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Asperity ``k``'s cells moved to ``tip`` (mm) on ``grid``: ``(i, j, p)`` of those inside."""
        s = slice(self.starts[k], self.starts[k + 1])
        i = self.di[s] + int(np.rint((tip[0] - grid.x0) / grid.h))
        j = self.dj[s] + int(np.rint((tip[1] - grid.y0) / grid.h))
        inside = (i >= 0) & (i < grid.nx) & (j >= 0) & (j < grid.ny)
        return i[inside], j[inside], self.pressure[s][inside]

    def on_patch(self, patch, previous: int, tip: tuple[float, float], force: float) -> np.ndarray | None:
        """The start on ``patch``'s owned cells for its asperity, previously numbered
        ``previous``, now at ``tip``, scaled to carry ``force`` N; None when there is none."""
        scale = self.scale(previous, force)
        if scale is None:
            return None
        out = np.zeros(patch.grid.shape)
        i, j, p = self.cells(previous, tip, patch.grid)
        out[j, i] = p * scale
        out[~patch.owned] = 0.0
        return out[patch.owned] if np.any(out > 0) else None

    def scale(self, k: int, force: float) -> float | None:
        """Factor on asperity ``k``'s previous pressure for a new macro force ``force`` N;
        None when it has no start."""
        if not self.loaded(k) or not force > 0 or not self.forces[k] > 0:
            return None
        return float(force / self.forces[k])

    def on_grid(self, grid: Grid, tips: np.ndarray, index: np.ndarray, forces: np.ndarray) -> np.ndarray | None:
        """The start on ``grid`` (one box for every tip), each tip's part scaled to its force;
        None when no tip has one."""
        out = np.zeros(grid.shape)
        for m, k in enumerate(index):
            scale = self.scale(int(k), float(forces[m])) if k >= 0 else None
            if scale is not None:
                i, j, p = self.cells(int(k), (tips[m, 0], tips[m, 1]), grid)
                out[j, i] += p * scale
        return out if np.any(out > 0) else None


@dataclass(frozen=True)
class MicroStart:
    """A :class:`PressureStart` bound to a solve: ``index[m]`` is tip m's number in the
    previous solve (-1: a new tip, started by eq. 7); ``theta_offset``: the previous micro
    step's approach and tilt minus its macro step's (mm, rad, rad)."""

    pressure: PressureStart
    index: np.ndarray
    theta_offset: tuple = (0.0, 0.0, 0.0)

    def theta(self, penetration: float, tilt: tuple | None) -> tuple[float, tuple | None]:
        """The micro step's first approach and tilt under load control: the macro step's
        plus the correction the previous micro step made to its macro step's."""
        d = float(penetration + self.theta_offset[0])
        if tilt is None:
            return d, None
        return d, (float(tilt[0] + self.theta_offset[1]), float(tilt[1] + self.theta_offset[2]))

    def for_patch(self, patch, asperities, forces: np.ndarray) -> np.ndarray | None:
        """Start on a one-asperity ``patch`` (owned cells), or None."""
        m = int(patch.asperity)
        a = asperities[m]
        return self.pressure.on_patch(patch, int(self.index[m]), (a.x, a.y), float(forces[m]))

    def on_grid(self, grid: Grid, asperities, forces: np.ndarray) -> np.ndarray | None:
        """Start on one ``grid`` for every tip (the union CG's box), or None."""
        tips = np.array([[a.x, a.y] for a in asperities], dtype=float).reshape(-1, 2)
        return self.pressure.on_grid(grid, tips, self.index, np.asarray(forces, dtype=float))
