"""The caller's own test on the constrained CG (``solve_cg``'s ``stop``), brought to the
cells the kernel iterates on."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np

from ..pk.compact import Part


class CellsStop(Protocol):
    """``solve_cg``'s ``stop``: called before each step (the kernel's
    :class:`~twoscale.pk.Tolerance` ``stop``) as ``stop(iteration, residual, values)``,
    ``values`` the pressure (MPa) on those of its ``cells`` (an (ny, nx) bool array on the
    surface's grid) the CG iterates on (the others carry none); True ends the CG, not
    converged (e.g. to enlarge the grid when pressure has settled on its edge)."""

    cells: np.ndarray

    def __call__(self, iteration: int, residual: float, values: np.ndarray) -> bool: ...


def row_stop(stop: CellsStop, part: Part | None) -> Callable:
    """``stop`` as the kernel's test on its row (the part's cells, or every cell): the
    row's pressure gathered on ``stop.cells``."""
    on = stop.cells.ravel() if part is None else stop.cells.ravel()[part.cells]
    at = np.flatnonzero(on)
    return lambda it, res, p: stop(it, res, p[at])


def on_window(stop: CellsStop | None, window) -> CellsStop | None:
    """``stop`` on a ``window`` (a pair of slices) of its grid: the grid cropped below the
    approach (its cells off the crop never touch)."""
    return None if stop is None else _Window(stop, stop.cells[window])


@dataclass(frozen=True)
class _Window:
    test: CellsStop
    cells: np.ndarray

    def __call__(self, iteration: int, residual: float, values: np.ndarray) -> bool:
        return self.test(iteration, residual, values)
