"""The far field's point operator kept through a grown and a merged patch
(:mod:`twoscale.micro.kept_points`), against the sum of point forces made term by term."""

import numpy as np
import scipy.sparse as sp

from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.micro.farfield import LaggedFarField, all_source_nodes, all_stencils
from twoscale.micro.kept_points import KeptPointOperator
from twoscale.micro.patches import Patch

HS = HalfSpace(Material(10.0, 0.5))
H = 0.05


def _patch(k, x, y, n, members=()):
    g = Grid.covering(x - 0.5 * n * H, x + 0.5 * n * H, y - 0.5 * n * H, y + 0.5 * n * H, H)
    return Patch(k, g, np.zeros(g.shape), np.full(g.shape, k), members)


def _scattered(count=300, seed=3):
    """``count`` patches of 5 x 5 cells on a jittered lattice of 0.6 mm (near pairs: the
    neighbours), enough for the half-space's fast (Ewald) point operator."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(count)))
    xy = 0.6 * np.argwhere(np.ones((side, side)))[:count] + rng.uniform(-0.1, 0.1, (count, 2))
    return [_patch(k, x, y, 5) for k, (x, y) in enumerate(xy)]


def _exact(far: LaggedFarField, forces: np.ndarray) -> np.ndarray:
    """The far field's stencil sums term by term: every source of every patch that is
    neither the target's patch nor near it, Boussinesq's 1/(pi E* r)."""
    t, s = all_stencils(far.patches), all_source_nodes(far.patches)
    dx, dy = t[:, None, 0] - s[None, :, 0], t[:, None, 1] - s[None, :, 1]
    with np.errstate(divide="ignore"):  # a patch's centre node is on its own stencil: left out
        G = 1.0 / (np.pi * HS.E_star * np.hypot(dx, dy))
    near = (far.near_pattern() + sp.identity(len(far.patches))).toarray() > 0
    G[np.kron(near, np.ones((9, 9), bool))] = 0.0
    return G @ forces


def _check(far: LaggedFarField, seed: int) -> None:
    op = far._point_operator()
    assert isinstance(op, KeptPointOperator)  # not built again
    forces = np.random.default_rng(seed).random((9 * len(far.patches), 2))
    exact = _exact(far, forces)
    assert np.abs(op.apply(forces) - exact).max() < 2e-6 * np.abs(exact).max()


def test_the_point_operator_is_kept_through_a_grown_patch():
    patches = _scattered()
    far = LaggedFarField(HS, patches, far_tol=0.3)
    built = far._point_operator()
    assert not isinstance(built, KeptPointOperator)
    x, y = np.mean(patches[7].grid.centres()[0]), np.mean(patches[7].grid.centres()[1])
    far.replace(7, _patch(7, x, y, 9))
    _check(far, 1)
    assert far._point_operator().base is built


def test_the_point_operator_is_kept_through_a_merge():
    patches = _scattered()
    far = LaggedFarField(HS, patches, far_tol=0.3)
    built = far._point_operator()
    # patches 3 and 4 become one (a new patch object), the others stay the same objects
    (x3, y3), (x4, y4) = (np.mean(patches[k].grid.points(), axis=0) for k in (3, 4))
    merged = _patch(3, 0.5 * (x3 + x4), 0.5 * (y3 + y4), 18, members=(3, 4))
    after = patches[:3] + [merged] + patches[5:]
    again = LaggedFarField(HS, after, far_tol=0.3)
    again.keep_pairs(far, {k: k - (k > 4) for k in range(len(patches)) if k not in (3, 4)})
    _check(again, 2)
    assert again._point_operator().base is built


def test_the_kept_weights_take_the_bytes_the_estimate_counts_per_owned_cell():
    # patches whose asperity owns part of their cells (a neighbour the rest): after a
    # refresh and a sweep's far-field products the far field keeps, per patch, the source
    # weights and the owned rows of the interpolation (not the owned cells' centres); their
    # bytes are KEPT_BYTES_PER_OWNED_CELL per owned cell, what the memory estimate counts
    from twoscale.micro.sources import KEPT_BYTES_PER_OWNED_CELL

    rng = np.random.default_rng(5)
    patches = []
    for k, pt in enumerate(_scattered(60)):
        owner = np.where(rng.random(pt.grid.shape) < 0.7, k, -1)
        owner[2, 2] = k
        patches.append(Patch(k, pt.grid, pt.height, owner))
    far = LaggedFarField(HS, patches, far_tol=0.3)
    values = [rng.random(int(pt.owned.sum())) for pt in patches]
    far.refresh(values)
    for k in range(len(patches)):
        far._far(k, values, whole=False)
    owned = sum(int(pt.owned.sum()) for pt in patches)
    assert owned < sum(pt.grid.size for pt in patches)
    kept = [far._sources, {k: w for k, w in far._weights.items() if k[0] != "shape"}]
    assert [len(d) for d in kept] == [len(patches)] * 2 and not far._cells
    assert sum(a.nbytes for d in kept for a in d.values()) == KEPT_BYTES_PER_OWNED_CELL * owned


def test_an_operator_built_anew_does_not_hold_the_earlier_one_through_its_build():
    # every patch replaced: too many changed for the kept operator, so it is built again,
    # and the earlier one is let go before (not held alongside the new one's build)
    import gc
    import weakref

    patches = _scattered()
    far = LaggedFarField(HS, patches, far_tol=0.3)
    earlier = weakref.ref(far._point_operator())
    gc.collect()
    for k, pt in enumerate(patches):
        far.replace(k, Patch(k, pt.grid, pt.height.copy(), pt.owner.copy()))
    seen = []
    build = HS.point_operator

    class Watching:
        def __getattr__(self, name):
            return getattr(HS, name)

        def point_operator(self, *args, **kwargs):
            gc.collect()
            seen.append(earlier() is None)
            return build(*args, **kwargs)

    far.provider = Watching()
    op = far._point_operator()
    assert seen == [True] and not isinstance(op, KeptPointOperator)
    forces = np.random.default_rng(4).random((9 * len(far.patches), 1))
    exact = _exact(far, forces)
    assert np.abs(op.apply(forces) - exact).max() < 2e-6 * np.abs(exact).max()
