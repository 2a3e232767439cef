"""The preconditioner :func:`~twoscale.reference.cg.solve_cg` hands the kernel: the caller's
(:class:`_Custom`) or the operator's approximate inverse."""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..influence.circulant import CirculantInverse
from ..pk.coarse import SquaresCorrection
from ..pk.products import OneRowInverse


def _preconditioner(cg, custom, op, table: Callable[[], np.ndarray] | None = None):
    """``precondition(v, on)`` for the kernel: the caller's (``custom``, made once from
    ``cg.preconditioner`` for both stages) or the operator's approximate inverse, or None;
    with ``table`` (the operator's ``coarse_table``, made on call; None: none) the inverse with its coarse
    correction (:class:`~twoscale.pk.coarse.SquaresCorrection`)."""
    if not cg.precondition:
        return None
    if custom is not None:
        return _Custom(custom)
    inverse = op.preconditioner()
    if inverse is None:
        return None
    values = table() if table is not None and isinstance(inverse, CirculantInverse) else None
    if values is not None:
        return SquaresCorrection(inverse, values, inverse.source.shape)
    return OneRowInverse(inverse)


class _Custom:
    """``precondition(v, on)`` by a caller's preconditioner (one row), and on a part of the
    grid by the preconditioner's own ``on_part(cells)`` if it has one
    (:meth:`twoscale.pk.compact.Part.precondition`)."""

    def __init__(self, custom):
        self.custom = custom

    def __call__(self, v: np.ndarray, on: np.ndarray) -> np.ndarray:
        return self.custom.apply(v[0], on[0])[None]

    def on_part(self, cells: np.ndarray) -> Callable | None:
        own = getattr(self.custom, "on_part", None)
        if own is None:
            return None
        apply = own(cells)
        return lambda v, on: apply(v[0], on[0])[None]
