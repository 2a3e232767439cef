"""The near pairs' displacement on whole patches, many at once (:mod:`twoscale.micro.whole_patches`).

Checks: on random patches (sizes, places, owned cells and pressures drawn at random; the
dense blocks' size small so that most pairs take the spectral route, and some dense blocks
kept) the whole-patch displacements of many patches together equal each patch's own,
target by target through its pairs' routes (:meth:`Coupling._sum`, whole patch) and the
kept blocks, to rounding; and the exact displacement from the full Love kernel (the
provider's dense blocks of the whole patches); cut in several runs they are the same.
"""

import numpy as np
import pytest

from helpers import lattice_patches

from twoscale import Material
from twoscale.influence import HalfSpace
from twoscale.micro import whole_patches
from twoscale.micro.farfield import FarFieldCoupling
from twoscale.micro.localblock import whole_patch

HS = HalfSpace(Material(10.0, 0.5))
H = 0.02


def _engine(patches):
    return FarFieldCoupling(HS, patches, far_tol=0.3, dense_max_entries=10_000, separated_rtol=None)


def _one_by_one(engine, k, values):
    """Patch ``k``'s near displacement target by target: kept blocks, then ``_sum``."""
    pt, u, rest = engine.patches[k], np.zeros(engine.patches[k].grid.shape), []
    for l in engine.near(k):
        v = values[int(l)]
        if not v.any():
            continue
        M = engine._ops.get((k, int(l)))
        if M is None:
            rest.append(int(l))
        else:
            u += whole_patch(HS, pt, M @ v, engine.patches[int(l)], v)
    routed = engine._sum(k, rest, values, whole=True) if rest else None
    return u if routed is None else u + routed


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_whole_patches_together_equal_each_patchs_own_and_the_kernels(seed, monkeypatch):
    rng = np.random.default_rng(seed)
    patches = lattice_patches(rng, 30, 1.5, H, largest=20)
    values = [rng.random(int(pt.owned.sum())) * (rng.random(int(pt.owned.sum())) < 0.6) for pt in patches]
    values[1] = np.zeros_like(values[1])
    together, alone = _engine(patches), _engine(patches)
    for engine in (together, alone):  # the same kept dense blocks in both
        for k in range(len(patches)):
            for l in engine.near(k):
                engine._dense(k, int(l))
    assert together._ops, "some pairs keep a dense block"
    ks = [k for k in range(len(patches)) if rng.random() < 0.8]
    got = whole_patches.near_on_patches(together, ks, values)
    kinds = [together._route(k, int(l))[0] for k in ks for l in together.near(k) if values[int(l)].any()]
    assert kinds.count("spectral") > 0.3 * len(kinds)
    assert sorted(got) == ks
    for k in ks:
        want = _one_by_one(alone, k, values)
        scale = max(np.abs(want).max(), 1e-300)
        assert np.abs(got[k] - want).max() <= 1e-12 * scale
        pk = patches[k]
        exact = np.zeros(pk.grid.size)
        for l in together.near(k):
            pl = patches[int(l)]
            exact += HS.grid_matrix(pk.grid, pl.grid)[:, pl.owned.ravel()] @ values[int(l)]
        assert np.abs(got[k] - exact.reshape(pk.grid.shape)).max() <= 1e-10 * scale
    # cut in runs of a few targets: the same sums
    monkeypatch.setattr(whole_patches, "PART_CELLS", 600)
    cut = whole_patches.near_on_patches(_engine(patches), ks, values)
    for k in ks:
        assert np.abs(cut[k] - got[k]).max() <= 1e-12 * max(np.abs(got[k]).max(), 1e-300)
