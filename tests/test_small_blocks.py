"""The two-level iteration's small-block paths: kept columns, LAPACK solves, lean products.

Independent answers: the provider's dense Love matrix (``grid_matrix``) for a block's
products and solves; the contact conditions (``p >= 0``, no penetration, zero gap where
loaded) checked with that matrix for the local active-set solve; the point operator for
the coarse step's dense tip compliance; the general route-by-route product (several right-hand
sides) for the far-field coupling's one-vector product; the per-patch stencils and
source nodes for the far field's lattices made in one pass.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.micro import localblock
from twoscale.micro.coarse import CoarseSpace
from twoscale.micro.farfield import FarFieldCoupling, LaggedFarField, all_source_nodes, all_stencils
from twoscale.micro.local import contact_solve
from twoscale.micro.localblock import LocalBlock, whole_patch
from twoscale.micro.patches import Patch
from twoscale.micro.sources import source_nodes

HS = HalfSpace(Material(10.0, 0.5))
H = 0.02


def _patch(k, x0, y0, nx, ny, cut=0):
    """A patch of asperity ``k``; its first ``cut`` columns owned by asperity ``k + 1``."""
    g = Grid(x0, y0, H, nx, ny)
    owner = np.full(g.shape, k)
    owner[:, :cut] = k + 1
    X, Y = g.centres()
    height = ((X - x0 - 0.5 * nx * H) ** 2 + (Y - y0 - 0.5 * ny * H) ** 2) / (2.0 * 2.0)
    return Patch(k, g, height, owner)


def _dense(block):
    """``A_kk`` on the block's owned cells from the provider's dense matrix of its box."""
    idx = np.flatnonzero(block._mask.ravel())
    return HS.grid_matrix(block.box)[np.ix_(idx, idx)]


def test_product_on_an_active_set_is_the_dense_matrix_product(monkeypatch):
    blk = LocalBlock(HS, _patch(0, 0.0, 0.0, 11, 9, cut=2))
    assert blk.dense and blk.matrix is not None and blk._matrix is None  # cut, not stored
    A = _dense(blk)
    rng = np.random.default_rng(0)
    for _ in range(3):  # a new active set each time: its columns made again
        active = rng.random(blk.n) < 0.3
        v = np.where(active, rng.random(blk.n), 0.0)
        assert np.allclose(blk.product_on(active, v), A @ v, rtol=1e-12, atol=1e-15)
        assert np.allclose(blk.product_on(active, 2.0 * v), 2.0 * (A @ v), rtol=1e-12, atol=1e-15)
    # too many entries to keep: the FFT product, the same numbers to rounding
    monkeypatch.setattr(localblock, "COLUMNS_MAX_ENTRIES", 0)
    big = LocalBlock(HS, _patch(0, 0.0, 0.0, 11, 9, cut=2))
    assert np.allclose(big.product_on(active, v), A @ v, rtol=1e-10, atol=1e-15)
    assert big._columns is None


def test_a_dense_blocks_solve_is_the_dense_systems_answer():
    blk = LocalBlock(HS, _patch(0, 0.3, -0.2, 9, 9))
    A = _dense(blk)
    rng = np.random.default_rng(1)
    active = rng.random(blk.n) < 0.5
    A_SS = A[np.ix_(active, active)]
    one = rng.random(int(active.sum()))
    two = rng.random((int(active.sum()), 2))
    assert np.allclose(blk.solve(active, one), np.linalg.solve(A_SS, one), rtol=1e-10)
    assert np.allclose(blk.solve(active, two), np.linalg.solve(A_SS, two), rtol=1e-10)


@pytest.mark.parametrize("cut", [0, 3])
def test_the_local_contact_solve_meets_the_contact_conditions(cut):
    # a paraboloid pressed into one block, with part of the patch owned by a neighbour
    pt = _patch(0, 0.0, 0.0, 15, 15, cut=cut)
    blk = LocalBlock(HS, pt)
    A = _dense(blk)
    z = pt.height[pt.owned]
    b = 0.002 - (z - z.min())  # approach 2 um
    previous = np.zeros(blk.n)
    for _ in range(2):  # from nothing, then from its own answer (the kept columns' path)
        sol = contact_solve(blk, b, previous)
        assert sol.converged
        p = sol.pressure
        gap = A @ p - b
        scale = np.abs(b).max()
        assert p.min() >= 0.0 and np.any(p > 0.0)
        assert gap.min() >= -1e-10 * scale
        assert np.abs(gap[p > 0.0]).max() <= 1e-10 * scale
        previous = p


def test_the_coarse_steps_dense_tip_compliance_is_the_point_operators():
    rng = np.random.default_rng(2)
    tips = rng.uniform(0.0, 5.0, (40, 2))
    tips[7] = tips[3]  # coincident tips contribute nothing to each other, on both paths
    lower = np.zeros((40, 40))
    dense = CoarseSpace(HS, tips, lower, dense_max=100)
    by_operator = CoarseSpace(HS, tips, lower, dense_max=10)
    assert dense.compliance() is not None and by_operator.compliance() is None
    dF = rng.normal(size=40)
    expected = -HS.point_operator(tips, tips).apply(dF)
    assert np.all(np.isfinite(dense.approach_errors(dF)))
    assert np.allclose(dense.approach_errors(dF), expected, rtol=1e-9, atol=0.0)
    assert np.allclose(by_operator.approach_errors(dF), expected, rtol=1e-9, atol=0.0)


def _scattered(seed, n=12):
    rng = np.random.default_rng(seed)
    xy = H * rng.integers(0, 150, (n, 2))  # on one lattice
    sizes = rng.integers(4, 12, (n, 2))
    return [_patch(k, x, y, int(nx), int(ny)) for k, ((x, y), (nx, ny)) in enumerate(zip(xy, sizes))]


@pytest.mark.parametrize("held", [False, True])
def test_the_one_vector_product_is_the_route_by_route_one(held):
    patches = _scattered(3)
    rng = np.random.default_rng(4)
    values = [np.where(rng.random(pt.grid.size) < 0.4, rng.random(pt.grid.size), 0.0) for pt in patches]
    values[5] = np.zeros(patches[5].grid.size)  # an unloaded neighbour is skipped
    engine = (LaggedFarField if held else FarFieldCoupling)(HS, patches, far_tol=0.3)
    assert sum(len(engine.near(k)) for k in range(len(patches))) > 0
    rhs = [rng.random(pt.grid.size) for pt in patches]
    for sweep in range(2):  # the dense pair blocks are made on the first, kept on the second
        for k in range(len(patches)):
            one = engine.rhs(k, values, rhs[k])
            columns = engine.rhs(k, [v[:, None] for v in values], rhs[k][:, None])[:, 0]
            assert np.allclose(one, columns, rtol=1e-12, atol=1e-15)


def test_the_far_fields_lattices_in_one_pass_are_the_per_patch_ones():
    patches = _scattered(5) + [_patch(20, 1.0, 2.0, 1, 1)]
    engine = FarFieldCoupling(HS, patches)
    assert np.array_equal(all_stencils(patches), np.concatenate([engine._stencil(k) for k in range(len(patches))]))
    assert np.array_equal(all_source_nodes(patches), np.concatenate([source_nodes(pt.grid)[0] for pt in patches]))


def test_a_reverse_pairs_dense_block_is_the_direct_block_and_takes_no_memory():
    from twoscale.micro.blocks import Coupling

    a, b = _patch(0, 0.0, 0.0, 9, 7, cut=2), _patch(1, 0.1, 0.04, 8, 10, cut=3)
    engine = Coupling(HS, [a, b])
    forward = engine._dense(0, 1)
    used = engine._bytes
    reverse = engine._dense(1, 0)
    assert engine._bytes == used  # a view of the forward block
    ia, ib = np.flatnonzero(a.owned.ravel()), np.flatnonzero(b.owned.ravel())
    direct = HS.grid_matrix(b.grid, a.grid)[np.ix_(ib, ia)]
    assert np.allclose(reverse, direct, rtol=1e-13, atol=0.0)
    assert np.allclose(forward, HS.grid_matrix(a.grid, b.grid)[np.ix_(ia, ib)], rtol=1e-13, atol=0.0)
    # a patch that changes drops both, and the memory they held
    engine.replace(1, _patch(1, 0.1, 0.04, 9, 10, cut=3))
    assert engine._bytes == 0.0 and not engine._ops


@pytest.mark.parametrize("cut", [0, 3])
def test_whole_patch_displacements_by_kept_blocks_are_the_fft_ones(cut):
    # the growth check's displacement on whole patches (their cells a neighbour owns
    # included): a block's own pressure and its near pairs', against the FFT operators
    patches = [_patch(k, H * (7 * k), H * (3 * k), 10, 9, cut=cut) for k in range(4)]
    engine = LaggedFarField(HS, patches, far_tol=0.3)
    rng = np.random.default_rng(6)
    values = [np.where(rng.random(int(pt.owned.sum())) < 0.5, rng.random(int(pt.owned.sum())), 0.0) for pt in patches]
    for k in range(len(patches)):
        engine.rhs(k, values, np.zeros(len(values[k])))  # makes the near pairs' dense blocks
        assert len(engine.near(k)) and all((k, int(l)) in engine._ops for l in engine.near(k))
        routed = engine._sum(k, [int(l) for l in engine.near(k)], values, whole=True)
        far = engine._far(k, values, whole=True)[:, 0].reshape(patches[k].grid.shape)
        u = engine.patch_displacement(k, values)
        assert np.allclose(u, routed + far, rtol=0.0, atol=1e-12 * np.abs(u).max())
        blk = LocalBlock(HS, patches[k])
        whole = np.zeros(patches[k].grid.shape)
        whole[patches[k].owned] = values[k]
        fft = blk.full_operator().apply(whole)
        assert np.allclose(blk.patch_product(values[k]), fft, rtol=0.0, atol=1e-12 * np.abs(fft).max())
        # a provider whose matrix is not cheap: the loaded cells' cell block
        by_cells = whole_patch(
            SimpleNamespace(cell_block=HS.cell_block), patches[k], fft[patches[k].owned], patches[k], values[k]
        )
        assert np.allclose(by_cells, fft, rtol=0.0, atol=1e-12 * np.abs(fft).max())


def test_a_new_engine_takes_over_the_blocks_of_the_patches_that_did_not_change():
    from twoscale.micro.blocks import Coupling

    a, b, c = (_patch(k, H * 6 * k, 0.0, 8, 8) for k in range(3))
    old = Coupling(HS, [a, b, c])
    kept = old._dense(1, 2)
    old._dense(2, 1)  # a view of it
    old._dense(0, 1)
    d = _patch(3, H * 3, H * 5, 9, 9)
    new = Coupling(HS, [b, c, d])  # a merged away: b and c are patches 0 and 1 now
    new.keep_pairs(old, {1: 0, 2: 1})
    assert new._ops[(0, 1)] is kept and (1, 0) in new._ops and len(new._ops) == 2
    assert new._bytes == kept.nbytes  # the view holds no memory of its own
    ib, ic = np.flatnonzero(b.owned.ravel()), np.flatnonzero(c.owned.ravel())
    assert np.allclose(new._dense(1, 0), HS.grid_matrix(c.grid, b.grid)[np.ix_(ic, ib)], rtol=1e-13, atol=0.0)


def _spread_patch(n=70):
    """A patch whose few owned cells (two 3 x 3 corners) span its whole n x n grid: a box
    whose matrix (8 n^4 bytes) is far larger than the block's."""
    g = Grid(0.0, 0.0, H, n, n)
    owner = np.full(g.shape, 1)
    owner[:3, :3] = owner[-3:, -3:] = 0
    return Patch(0, g, np.zeros(g.shape), owner)


def test_a_block_spread_over_a_large_box_never_makes_the_box_matrix():
    import tracemalloc

    pt = _spread_patch()
    blk = LocalBlock(HS, pt)
    assert blk.dense and blk.box.size == pt.grid.size and blk.n == 18
    X, Y = pt.grid.centres()
    xy = np.column_stack([X[pt.owned], Y[pt.owned]])
    A = HS.cell_block(xy, xy, H)  # Love's cell values: the independent answer
    rng = np.random.default_rng(1)
    active = np.zeros(blk.n, dtype=bool)
    active[[0, 4, 11, 17]] = True
    v = np.where(active, rng.random(blk.n), 0.0)
    box_bytes = 8.0 * blk.box.size**2  # 192 MB: what the columns were once cut from
    bound = 8.0 * (20 * blk.box.size + 50 * blk.n**2)  # centres and a few n x n arrays
    tracemalloc.start()
    try:
        none = blk.product_on(np.zeros(blk.n, dtype=bool), np.zeros(blk.n))
        Av = blk.product_on(active, v)
        x = blk.solve(active, np.ones(int(active.sum())))
        M = blk.matrix
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert bound < box_bytes / 100
    assert peak < bound, (peak, bound)
    assert not none.any()
    assert np.allclose(Av, A @ v, rtol=1e-12, atol=0.0)
    assert np.allclose(A[np.ix_(active, active)] @ x, 1.0, rtol=1e-10)
    assert np.allclose(M, A, rtol=1e-12, atol=0.0)


def test_grid_entries_are_the_grid_matrix_entries_without_the_whole_matrix():
    # the half-space's gather from its offset table, directly and through a solver's caches
    # (which keep the table), against the whole grid matrix cut by np.ix_ and against Love's
    # cell values (the provider's cell_block) at the cells' centres
    from twoscale.influence.cached import CachedBody, OperatorCaches

    rng = np.random.default_rng(5)
    target, source = Grid(0.0, 0.0, 0.05, 7, 5), Grid(0.35, -0.1, 0.05, 4, 9)
    cached = CachedBody(HS, OperatorCaches())
    pairs = [(target, source), (source, target), (target, target)]
    for (t, s), (nr, nc) in zip(pairs * 2, [(10, 6)] * 3 + [(30, 25)] * 3):  # few and many entries
        rows = rng.choice(t.size, nr, replace=False)
        cols = rng.choice(s.size, nc, replace=False)
        whole = HS.grid_matrix(t, s)[np.ix_(rows, cols)]
        assert np.array_equal(HS.grid_entries(t, s, rows, cols), whole)
        assert np.array_equal(cached.grid_entries(t, s, rows, cols), whole)
        love = HS.cell_block(t.points()[rows], s.points()[cols], t.h)
        assert np.allclose(whole, love, rtol=1e-10, atol=0.0)
