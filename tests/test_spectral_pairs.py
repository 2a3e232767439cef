"""The routed near pairs of many targets at once (:mod:`twoscale.micro.spectral_pairs`).

Checks: on random patches (sizes, places, owned cells and pressures drawn at random, the
dense blocks' size small so that most pairs take the spectral route) the stacked sums of
many targets equal each target's own sum by its routes (:meth:`Coupling._sum`) to
rounding, and the exact displacement from the full Love kernel (the provider's dense
blocks); the per-vector transforms they keep serve a later call with the same vectors.
"""

import numpy as np
import pytest

from helpers import lattice_patches, lattice_values

from twoscale import Material
from twoscale.influence import HalfSpace
from twoscale.micro.blocks import Coupling
from twoscale.micro.spectral_pairs import route_sums

HS = HalfSpace(Material(10.0, 0.5))
H = 0.02


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_stacked_route_sums_equal_each_targets_own_and_the_kernels(seed):
    rng = np.random.default_rng(seed)
    patches = lattice_patches(rng, 16, 2.0, H)
    values = lattice_values(rng, patches)
    kw = dict(dense_max_entries=2_000, separated_rtol=None)  # most pairs on the spectral route
    one, many = Coupling(HS, patches, **kw), Coupling(HS, patches, **kw)
    work = [(k, [l for l in range(len(patches)) if l != k and rng.random() < 0.6]) for k in range(len(patches))]
    got = route_sums(many, work, values)
    kinds = [many._route(k, l)[0] for k, ls in work for l in ls if values[l].any()]
    assert kinds.count("spectral") > 0.5 * len(kinds)
    for k, ls in work:
        want = one._sum(k, ls, values, whole=False)
        if want is None:
            assert k not in got
            continue
        assert np.abs(got[k] - want).max() <= 1e-13 * np.abs(want).max()
        pk = patches[k]
        exact = sum(
            HS.grid_matrix(pk.grid, patches[l].grid)[np.ix_(pk.owned.ravel(), patches[l].owned.ravel())] @ values[l]
            for l in ls
        )
        assert np.abs(got[k] - exact).max() <= 1e-10 * np.abs(exact).max()
    # the same vectors again: their kept transforms serve, the same sums to the bit
    again = route_sums(many, work, values)
    assert again.keys() == got.keys() and all(np.array_equal(again[k], got[k]) for k in got)
