"""Near pairs past the dense blocks' budget (twoscale.micro.near_window): the products
gathered from one kernel window equal the pairs' dense blocks (Love's closed form) and the
FFT operators, on the owned cells and on the whole patch, and the coupling takes them
instead of an FFT operator."""

import numpy as np

from twoscale.grid import Grid
from twoscale.indenters import Asperity
from twoscale.influence.halfspace import HalfSpace
from twoscale.material import Material
from twoscale.micro.blocks import Coupling, scatter
from twoscale.micro.near_window import GATHER_MAX_ENTRIES, NearWindow
from twoscale.micro.pair_entries import WINDOW_MAX_ENTRIES
from twoscale.micro.patches import make_patch

HS = HalfSpace(Material(E=10.0, nu=0.3))
H = 0.1


def _patches(seed: int):
    rng = np.random.default_rng(seed)
    tips = rng.uniform(-2.0, 2.0, size=(6, 2))
    asps = [Asperity(x=x, y=y, z=0.0, R=3.0) for x, y in tips]
    out = []
    for k, (x, y) in enumerate(tips):
        wx, wy = rng.uniform(0.5, 1.2, size=2)  # patches of different shapes, overlapping
        out.append(make_patch(k, Grid.covering(x - wx, x + wx, y - wy, y + wy, H), asps))
    return out


def _loaded(rng, n: int, columns: int = 0) -> np.ndarray:
    v = rng.random((n, columns) if columns else n)
    v[rng.random(n) < 0.4] = 0.0  # cells out of contact carry nothing
    return v


def test_gathered_products_equal_the_dense_blocks_and_the_fft_operators():
    for seed in range(3):
        patches = _patches(seed)
        rng = np.random.default_rng(10 + seed)
        window = NearWindow(HS)
        for k, pk in enumerate(patches):
            for l, pl in enumerate(patches):
                if k == l or not pl.owned.any() or not pk.owned.any():
                    continue
                ik, il = np.flatnonzero(pk.owned.ravel()), np.flatnonzero(pl.owned.ravel())
                v = _loaded(rng, len(il))
                dense = HS.grid_matrix(pk.grid, pl.grid)
                got = window.product(k, pk, l, pl, v)
                np.testing.assert_allclose(got, dense[np.ix_(ik, il)] @ v, rtol=1e-12, atol=1e-15)
                whole = window.product(k, pk, l, pl, v, whole=True)
                fft = HS.grid_operator(pk.grid, pl.grid).apply(scatter(pl, v))
                np.testing.assert_allclose(whole, fft, rtol=1e-9, atol=1e-12 * np.abs(fft).max())
                V = _loaded(rng, len(il), columns=3)
                np.testing.assert_allclose(
                    window.product(k, pk, l, pl, V), dense[np.ix_(ik, il)] @ V, rtol=1e-12, atol=1e-15
                )
        assert window.reach > 0


def test_the_coupling_gathers_the_pairs_past_its_budget_and_makes_no_fft_operator():
    patches = _patches(4)
    rng = np.random.default_rng(5)
    values = [_loaded(rng, int(p.owned.sum())) for p in patches]
    none_kept = Coupling(HS, patches, cache_bytes=0.0, separated_rtol=None)
    kept = Coupling(HS, patches, separated_rtol=None)
    for k in range(len(patches)):
        b = rng.random(int(patches[k].owned.sum()))
        np.testing.assert_allclose(none_kept.rhs(k, values, b), kept.rhs(k, values, b), rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(
            none_kept.patch_displacement(k, values), kept.patch_displacement(k, values), rtol=1e-9, atol=1e-14
        )
    assert not none_kept._ops and kept._ops  # the first kept no dense block, the second did
    assert not none_kept._fft  # and made no FFT operator for the pairs
    assert none_kept._window is not None and none_kept._window.reach > 0


def test_a_pair_too_large_to_gather_is_left_to_the_other_route():
    pk = make_patch(0, Grid.covering(-3.0, 3.0, -3.0, 3.0, 0.02), [Asperity(0.0, 0.0, 0.0, 100.0)])
    pl = make_patch(0, Grid.covering(2.0, 8.0, -3.0, 3.0, 0.02), [Asperity(5.0, 0.0, 0.0, 100.0)])
    n = int(pl.owned.sum())
    assert int(pk.owned.sum()) * n > GATHER_MAX_ENTRIES
    assert NearWindow(HS).product(0, pk, 1, pl, np.ones(n)) is None
    off_lattice = make_patch(0, Grid.covering(2.01, 2.5, 0.0, 0.5, 0.02), [Asperity(2.2, 0.2, 0.0, 1.0)])
    small = make_patch(0, Grid.covering(0.0, 0.5, 0.0, 0.5, 0.02), [Asperity(0.2, 0.2, 0.0, 1.0)])
    window = NearWindow(HS)
    assert window.product(0, small, 1, off_lattice, np.ones(int(off_lattice.owned.sum()))) is None


def test_one_gather_of_several_sources_is_the_sum_of_their_products():
    patches = _patches(7)
    rng = np.random.default_rng(8)
    window = NearWindow(HS)
    values = [_loaded(rng, int(p.owned.sum())) for p in patches]
    k = next(k for k, p in enumerate(patches) if p.owned.any())
    sources = [(l, patches[l], values[l]) for l in range(len(patches)) if l != k and patches[l].owned.any()]
    assert len(sources) > 2
    ik = np.flatnonzero(patches[k].owned.ravel())
    expected = sum(
        HS.grid_matrix(patches[k].grid, pl.grid)[np.ix_(ik, np.flatnonzero(pl.owned.ravel()))] @ v
        for _, pl, v in sources
    )
    # a window not made yet is made to the pairs' reach (they took an FFT route before)
    np.testing.assert_allclose(window.total(k, patches[k], sources), expected, rtol=1e-12, atol=1e-15)
    for l, pl, v in sources:
        window.product(k, patches[k], l, pl, v)
    np.testing.assert_allclose(window.total(k, patches[k], sources), expected, rtol=1e-12, atol=1e-15)


def test_a_pair_past_the_largest_window_is_left_to_the_other_route_after_a_near_one():
    """A window made for a near pair, then a pair farther apart than the largest window
    reaches (500 cells): the window grew to its largest size and gathered out of its
    bounds (an IndexError in a tilted 16-tip solve); now the far pair gets None."""
    largest = (int(np.sqrt(WINDOW_MAX_ENTRIES)) - 1) // 2
    tips = [Asperity(0.0, 0.0, 0.0, 3.0), Asperity(1.5, 0.0, 0.0, 3.0), Asperity((largest + 20) * H, 0.0, 0.0, 3.0)]
    patches = [make_patch(k, Grid.covering(a.x - 0.5, a.x + 0.5, -0.5, 0.5, H), tips) for k, a in enumerate(tips)]
    window = NearWindow(HS)
    ik, il = np.flatnonzero(patches[0].owned.ravel()), np.flatnonzero(patches[1].owned.ravel())
    v = np.ones(len(il))
    near = window.product(0, patches[0], 1, patches[1], v)
    np.testing.assert_allclose(near, HS.grid_matrix(patches[0].grid, patches[1].grid)[np.ix_(ik, il)] @ v, rtol=1e-12)
    assert window.product(0, patches[0], 2, patches[2], np.ones(int(patches[2].owned.sum()))) is None
    assert window.reach < largest  # the near pair's window kept
