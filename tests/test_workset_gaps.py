"""The working set's gaps on whole patches: the growth check asks for some patches, the
result for all of them at the same pressures; a patch's gap is made once for both.

Checks: after :meth:`WorkingSet.gaps_of` on two of three patches, :meth:`WorkingSet.gaps`
makes only the third one's displacement and returns, for every patch, the gap a fresh
working set makes; new pressures (a replaced block vector) make them all again.
"""

from types import SimpleNamespace

import numpy as np

from twoscale.grid import Grid
from twoscale.micro.workset import WorkingSet


class _Coupling:
    """Displacement of patch ``k`` from the others: a fixed field per patch, counted."""

    def __init__(self, fields):
        self.fields, self.calls = fields, []

    def patch_displacement(self, k, values):
        self.calls.append(k)
        return self.fields[k] * (1.0 + sum(float(np.sum(v)) for v in values))


def _state(fields):
    patches, blocks = [], []
    for k, u in enumerate(fields):
        grid = Grid.covering(k, k + 1.0, 0.0, 1.0, 0.25)
        patches.append(SimpleNamespace(grid=grid, height=np.full(grid.shape, 0.1 * k)))
        blocks.append(SimpleNamespace(patch_product=lambda p, u=u: 0.5 * u))
    return WorkingSet(None, [], patches, _Coupling(fields), dense_max_cells=10, blocks=blocks)


def test_the_growth_checks_gaps_are_kept_for_the_results():
    rng = np.random.default_rng(3)
    fields = [rng.random(Grid.covering(0.0, 1.0, 0.0, 1.0, 0.25).shape) for _ in range(3)]
    p = [np.array([0.0]), np.array([1.0]), np.array([2.0])]
    theta, pivot = (0.05, 0.01, -0.02), (0.5, 0.5)
    state = _state(fields)
    some = state.gaps_of([0, 2], p, theta, pivot)
    assert sorted(state.coupling.calls) == [0, 2]
    every = state.gaps(p, theta, pivot)
    assert sorted(state.coupling.calls) == [0, 1, 2]
    fresh = _state(fields).gaps(p, theta, pivot)
    for k in range(3):
        np.testing.assert_array_equal(every[k], fresh[k])
    assert every[0] is some[0] and every[2] is some[2]
    # block 1's vector replaced: every patch's displacement depends on it, all made again
    q = [p[0], np.array([3.0]), p[2]]
    again = state.gaps(q, theta, pivot)
    assert sorted(state.coupling.calls) == [0, 0, 1, 1, 2, 2]
    assert not np.array_equal(again[0], every[0])
