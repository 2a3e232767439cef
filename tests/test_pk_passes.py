"""The Polonsky-Keer kernel's KKT residual with a few free cells by their flat indices
(twoscale.pk.projection) against the one written out here over every cell, on random rows:
the same numbers to the bit (the kernel's iterates do not move)."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale.pk.projection import SHORT_ROW, free_cells, kkt_residual


@pytest.mark.parametrize("fraction", [0.001, 0.5])
def test_the_kkt_residual_with_free_cells_by_index_is_the_one_by_the_mask(fraction):
    """Few free cells go by their flat indices, many by the mask: the same residual, and
    the one written out with np.where."""
    rng = np.random.default_rng(3)
    n = SHORT_ROW + 1000
    p = np.maximum(rng.standard_normal((3, n)), 0.0)
    g = rng.standard_normal((3, n)) * 1e-3
    on = p > 0.0
    free = (rng.random((3, n)) < fraction) & ~on
    scale = np.array([2.0, 0.5, 1.0])
    taken = free_cells(free)
    assert (taken.dtype == bool) == (fraction > 0.1)
    worst_on = np.where(on, np.abs(g), 0.0).max(axis=1)
    worst_off = np.where(on | free, 0.0, -g).max(axis=1)
    written = np.maximum(np.maximum(worst_on, worst_off), 0.0) / scale
    by_mask = kkt_residual(g, g * on, on, free, scale, np.empty_like(g))
    by_index = kkt_residual(g, g * on, on, taken, scale, np.empty_like(g))
    assert np.array_equal(by_index, written) and np.array_equal(by_mask, written)
