"""The Polonsky-Keer kernel's fused passes (twoscale.pk.gap, twoscale.pk.projection)
against the formulas they replace, written out here on random data: the KKT residual in
two reductions, the projected gap from the masked gap, the masks' 0/1 floats and the
loaded cells counted per row. The fused passes must give the same numbers to the bit
where the arithmetic is the same (the kernel's iterates do not move)."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale.pk.gap import GapBuffers
from twoscale.pk.projection import SHORT_ROW, kkt_residual, masked_sum, row_count


def _rows(n: int, seed: int):
    """Gaps and pressures on three rows: some cells loaded, every cell loaded, none."""
    rng = np.random.default_rng(seed)
    p = np.maximum(rng.standard_normal((3, n)), 0.0)
    p[1] = rng.random(n) + 0.1
    p[2] = 0.0
    g = rng.standard_normal((3, n)) * 1e-3
    return p, g


@pytest.mark.parametrize("n", [50, SHORT_ROW + 1000])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_kkt_residual_in_two_reductions_is_the_written_out_one(n, seed):
    """Largest |g| on the loaded cells and largest -g elsewhere over the scale, written
    with np.where: the same numbers exactly (maxima and minima do not round)."""
    p, g = _rows(n, seed)
    on = p > 0.0
    scale = np.array([2.0, 0.5, 1.0])
    worst_on = np.where(on, np.abs(g), 0.0).max(axis=1)
    worst_off = np.where(on, 0.0, -g).max(axis=1)
    written = np.maximum(np.maximum(worst_on, worst_off), 0.0) / scale
    assert np.array_equal(kkt_residual(g, g * on, on, None, scale), written)
    # with free cells (not checked off the contact) the residual keeps its own pass
    free = np.zeros_like(on)
    free[:, ::3] = True
    free &= ~on
    worst_free = np.where(on | free, 0.0, -g).max(axis=1)
    written_free = np.maximum(np.maximum(worst_on, worst_free), 0.0) / scale
    assert np.array_equal(kkt_residual(g, g * on, on, free, scale, np.empty_like(g)), written_free)


@pytest.mark.parametrize("n", [50, SHORT_ROW + 1000])
def test_the_projected_gap_under_load_control_is_the_mean_removed_over_the_loaded_cells(n):
    """``g = u + z`` less its mean over the loaded cells (0 where none is loaded: the mean
    over an empty set counts one cell), ``g_on`` g there and 0 elsewhere: against the
    formulas written out (to rounding: the sums' order differs), and the weights are the
    loaded cells as floats on long rows, the bools themselves on short ones."""
    p, u = _rows(n, 3)
    z = np.random.default_rng(4).standard_normal((3, n)) * 1e-3
    on = p > 0.0
    buffers = GapBuffers()
    g, m, got_on, g_on, count, w = buffers.gap(p, u, z, 1, np.ones((n, 1)), None, None)
    count_written = np.maximum(on.sum(axis=1), 1)
    mean = np.where(on, u + z, 0.0).sum(axis=1) / count_written
    assert np.array_equal(got_on, on) and np.array_equal(count, count_written)
    assert np.allclose(m[:, 0], mean, rtol=1e-12, atol=1e-18)
    assert np.allclose(g, u + z - mean[:, None], rtol=1e-12, atol=1e-15)
    assert np.array_equal(g_on, np.where(on, g, 0.0))
    if n > SHORT_ROW:
        assert w.dtype == float and np.array_equal(w, on.astype(float))
    else:
        assert w is got_on
    # kept: a second check writes into the same arrays
    g2 = buffers.gap(p, u, z, 1, np.ones((n, 1)), None, None)[0]
    assert g2 is g


@pytest.mark.parametrize("n", [50, SHORT_ROW + 1000])
def test_a_masked_sum_by_the_float_weights_is_the_one_by_the_bools(n):
    p, v = _rows(n, 5)
    on = p > 0.0
    assert np.array_equal(masked_sum(v, on.astype(float) if n > SHORT_ROW else on), masked_sum(v, on))
    assert np.allclose(masked_sum(v, on), np.where(on, v, 0.0).sum(axis=1), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("rows", [1, 3, 9])
def test_the_loaded_cells_counted_per_row(rows):
    on = np.random.default_rng(rows).random((rows, 777)) < 0.3
    on[0] = False
    counts = row_count(on)
    assert counts.dtype == np.int64
    assert np.array_equal(counts, on.sum(axis=1))
    assert np.array_equal(counts, [sum(bool(x) for x in row) for row in on])
