"""The routed near pairs of many targets at once (:mod:`twoscale.micro.spectral_pairs`).

Checks: on random patches (sizes, places, owned cells and pressures drawn at random, the
dense blocks' size small so that most pairs take the spectral route) the stacked sums of
many targets equal each target's own sum by its routes (:meth:`Coupling._sum`) to
rounding, and the exact displacement from the full Love kernel (the provider's dense
blocks); the per-vector transforms they keep serve a later call with the same vectors; an
engine made again after a merge takes over the routes of the patches it keeps (the same
operators, the same sums as a fresh engine's, a reverse pair's view only with its pair).
"""

import numpy as np
import pytest

from helpers import lattice_patches

from twoscale import Material
from twoscale.influence import HalfSpace
from twoscale.micro.blocks import Coupling
from twoscale.micro.spectral_pairs import route_sums

HS = HalfSpace(Material(10.0, 0.5))
H = 0.02


def _values(rng, patches):
    vals = [rng.random(int(pt.owned.sum())) * (rng.random(int(pt.owned.sum())) < 0.6) for pt in patches]
    vals[1] = np.zeros_like(vals[1])
    return vals


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_stacked_route_sums_equal_each_targets_own_and_the_kernels(seed):
    rng = np.random.default_rng(seed)
    patches = lattice_patches(rng, 16, 2.0, H)
    values = _values(rng, patches)
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


def test_a_new_engine_takes_over_the_routes_of_the_patches_it_keeps():
    # after a merge the engine is made again for the merged patches: the pairs of patches
    # both engines hold keep their routes (the same operator objects), and the sums by
    # them equal a fresh engine's and the kernel's; a reverse pair's view only with its pair
    rng = np.random.default_rng(7)
    patches = lattice_patches(rng, 12, 1.5, H)
    values = _values(rng, patches)
    kw = dict(dense_max_entries=2_000, separated_rtol=None)
    old = Coupling(HS, patches, **kw)
    work = [(k, [l for l in range(len(patches)) if l != k]) for k in range(len(patches))]
    route_sums(old, work, values)
    assert any(r[1] is not None and not r[2] for r in old._routes.values()), "some views of reverse pairs"
    keep = [0, 2, 3, 5, 7, 8, 9, 11]  # the others merged away: the new engine's order
    now = [patches[i] for i in keep]
    index = {i: j for j, i in enumerate(keep)}
    new, fresh = Coupling(HS, now, **kw), Coupling(HS, now, **kw)
    new.keep_pairs(old, index)
    for (k, l), route in old._routes.items():
        if k in index and l in index:
            assert new._routes[(index[k], index[l])][1] is route[1]
    assert not [key for key in new._routes if None in key]
    assert new._route_bytes == sum(r[2] for r in new._routes.values())
    vals = [values[i] for i in keep]
    sub = [(k, [l for l in range(len(now)) if l != k]) for k in range(len(now))]
    got, want = route_sums(new, sub, vals), route_sums(fresh, sub, vals)
    assert got.keys() == want.keys()
    for k in got:
        assert np.abs(got[k] - want[k]).max() <= 1e-13 * np.abs(want[k]).max()
    # no room for operators: only the routes without bytes of their own whose pair came too
    tight = Coupling(HS, now, cache_bytes=0.0, **kw)
    tight.keep_pairs(old, index)
    assert tight._route_bytes == 0.0
    assert all(r[1] is None for r in tight._routes.values())
