"""The preconditioner :func:`~twoscale.reference.cg.solve_cg` hands the kernel: the caller's
(:class:`_Custom`) or the operator's approximate inverse."""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..pk.products import OneRowInverse


def _preconditioner(cg, custom, op):
    """``precondition(v, on)`` for the kernel: the caller's (``custom``, made once from
    ``cg.preconditioner`` for both stages) or the operator's approximate inverse, or None."""
    if not cg.precondition:
        return None
    if custom is not None:
        return _Custom(custom)
    inverse = op.preconditioner()
    return None if inverse is None else OneRowInverse(inverse)


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
