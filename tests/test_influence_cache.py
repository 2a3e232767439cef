"""Caches of the influence providers: bounded by a running total, LRU, owned.

* :class:`~twoscale.influence.cache.BoundedCache`: the bound holds after every insertion and the
  running total equals the sum of the stored sizes; eviction is least recently used; an
  insertion's cost does not grow with the number of entries (the module-global cache it
  replaces re-summed every entry at each insertion: 20,000 insertions took minutes);
* the caches of Love tables, Chebyshev matrices and operators between patches belong to a
  solver (:class:`~twoscale.influence.cached.OperatorCaches`, seen by the solves through a
  :class:`~twoscale.influence.cached.CachedBody`), never to the body: the half-space's value
  is its material, two solvers never share an entry, and each cache keeps its bound;
* on the half-space a pair operator serves every pair translated from it by whole cells,
  with the product of an operator built for the translated pair itself.
"""

import time

import numpy as np
import pytest

from twoscale import Grid, Material
from twoscale.influence import HalfSpace
from twoscale.influence.cache import BoundedCache
from twoscale.influence.cached import CachedBody, OperatorCaches

MAT = Material(E=10.0, nu=0.3)


def test_bound_holds_and_running_total_is_the_true_sum():
    rng = np.random.default_rng(0)
    cache = BoundedCache(10_000)
    for i in range(3000):
        key = int(rng.integers(0, 500))  # replacements of existing keys too
        cache.put(key, i, int(rng.integers(0, 400)))
        assert cache.nbytes <= cache.max_bytes
        if i % 97 == 0:
            assert cache.nbytes == sum(cache.sizes().values())
        if i % 13 == 0:
            cache.pop(int(rng.integers(0, 500)))
    assert cache.nbytes == sum(cache.sizes().values())
    assert cache.evictions > 0


def test_eviction_is_least_recently_used():
    cache = BoundedCache(3)
    for key in "abc":
        cache.put(key, key.upper(), 1)
    assert cache.get("a") == "A"  # a is now the most recently used
    cache.put("d", "D", 1)
    assert "b" not in cache and list(cache.sizes()) == ["c", "a", "d"]
    assert (cache.hits, cache.evictions) == (1, 1)
    assert cache.get("b") is None and cache.misses == 1


def test_an_entry_larger_than_the_bound_is_not_stored():
    cache = BoundedCache(10)
    cache.put("small", 1, 4)
    assert cache.put("big", 2, 11) == 2
    assert "big" not in cache and "small" in cache and cache.nbytes == 4
    assert cache.pop("small") == 1 and cache.nbytes == 0
    with pytest.raises(ValueError, match="max_bytes"):
        BoundedCache(-1)


@pytest.mark.parametrize("max_bytes", [1e12, 1000])  # everything kept / constant eviction
def test_insertion_cost_does_not_grow_with_the_entries(max_bytes):
    cache = BoundedCache(max_bytes)
    t0 = time.perf_counter()
    for i in range(20_000):
        cache.put(("key", i), i, 8)
    assert time.perf_counter() - t0 < 0.5
    assert cache.nbytes == sum(cache.sizes().values()) <= max_bytes


def test_the_half_space_keeps_nothing_and_two_solvers_do_not_share_entries():
    assert set(vars(HalfSpace(MAT))) == {"material"}  # its value, and nothing else
    a, b = CachedBody(HalfSpace(MAT), OperatorCaches()), CachedBody(HalfSpace(MAT), OperatorCaches())
    assert a.body == b.body and a.kind == "halfspace" and a.material == MAT
    g = Grid(0.0, 0.0, 0.1, 12, 9)
    a.grid_matrix(g)
    assert len(a.caches.tables) == 2 and len(b.caches.tables) == 0  # the table and the quadrant it was cut from
    a.grid_operator(g)  # the same offset table: a hit
    assert a.caches.tables.hits == 1 and b.caches.tables.hits == 0
    assert len(a.caches.operators) == 1 and len(b.caches.operators) == 0

    far = Grid(5.0, 0.0, 0.1, 12, 9)
    op = a.separated_operator(far, g, rtol=1e-6)
    assert op is not None and len(a.caches.operators) == 2 and len(b.caches.operators) == 0
    back = b.separated_operator(g, far, rtol=1e-6)  # b has not seen (far, g): built anew
    assert len(b.caches.operators) == 1
    again = a.separated_operator(g, far, rtol=1e-6)  # a's reverse pair: the transposed operator
    assert len(a.caches.operators) == 2 and a.caches.built == {"fft": 1, "separated": 1}
    p = np.random.default_rng(1).uniform(size=far.shape)
    assert np.allclose(again.apply(p), back.apply(p), rtol=1e-12, atol=0.0)


@pytest.mark.parametrize("kind", ["fft", "separated"])
def test_a_translated_pair_takes_the_operator_over(kind):
    """The same pair moved by whole cells, in the next solve: the operator is the one kept,
    its product equal to a fresh operator's for the moved grids (the arrays depend on the
    relative position only)."""
    body = CachedBody(HalfSpace(MAT), OperatorCaches())
    make = (
        (lambda t, s: body.grid_operator(t, s))
        if kind == "fft"
        else (lambda t, s: body.separated_operator(t, s, rtol=1e-8))
    )
    g, other = Grid(0.0, 0.0, 0.1, 12, 9), Grid(6.0, 0.7, 0.1, 10, 11)
    body.caches.start_solve()
    make(other, g)
    body.caches.start_solve()
    dx, dy = 0.1 * 7, -0.1 * 3
    gm, om = (Grid(q.x0 + dx, q.y0 + dy, q.h, q.nx, q.ny) for q in (g, other))
    moved = make(om, gm)
    assert body.caches.kept == {kind: 1} and body.caches.built == {}
    assert moved.target == om and moved.source == gm
    fresh = (
        HalfSpace(MAT).grid_operator(om, gm) if kind == "fft" else HalfSpace(MAT).separated_operator(om, gm, rtol=1e-8)
    )
    p = np.random.default_rng(2).uniform(size=gm.shape)
    assert np.allclose(moved.apply(p), fresh.apply(p), rtol=1e-13, atol=0.0)


def test_solver_caches_stay_within_their_bounds():
    body = CachedBody(HalfSpace(MAT), OperatorCaches(table_bytes=200_000, operator_bytes=50_000))
    g = Grid(0.0, 0.0, 0.1, 10, 10)
    caches = (body.caches.operators, body.caches.tables)
    for i in range(40):
        body.separated_operator(Grid(4.0 + 0.3 * i, 0.1 * i, 0.1, 10, 10), g, rtol=1e-6)
        body.grid_matrix(Grid(0.1 * i, 0.0, 0.1, 10 + i, 10), g)
        for cache in caches:
            assert cache.nbytes <= cache.max_bytes
            assert cache.nbytes == sum(cache.sizes().values())
    assert all(cache.evictions > 0 for cache in caches)
    assert body.caches.nbytes <= body.caches.max_bytes == 250_000


def test_separated_keys_are_values():
    # operators built separately (no shared arrays) for the same grids have equal keys
    hs1, hs2 = HalfSpace(MAT), HalfSpace(MAT)
    g, far = Grid(0.0, 0.0, 0.1, 12, 9), Grid(5.0, 0.0, 0.1, 12, 9)
    o1, o2 = hs1.separated_operator(far, g, rtol=1e-6), hs2.separated_operator(far, g, rtol=1e-6)
    assert o1.source_key == o2.source_key and o1.target_key == o2.target_key
    c1, c2 = hs1.grid_operator(far, g), hs2.grid_operator(far, g)
    assert c1.source_key == c2.source_key and c1.target_key == c2.target_key
    assert c1.source_key != o1.source_key


def test_offset_tables_cut_from_the_quadrant_equal_love_values():
    """Windows of offsets of either sign, straddling zero or not, and a quadrant that must
    grow: the same values as Love's formula evaluated on the offsets."""
    from twoscale.analytic.halfspace import love_rectangle

    hs = HalfSpace(MAT)
    tables = BoundedCache(64e6)  # the quadrant kept between windows (and grown)
    h = 0.05
    rng = np.random.default_rng(3)
    for ox0, oy0, mx, my in [
        (-5, -7, 11, 15),
        (3, -20, 4, 9),
        (-30, 2, 8, 5),
        (0, 0, 1, 1),
        *[
            tuple(int(v) for v in rng.integers(-150, 150, 2)) + tuple(int(v) for v in rng.integers(1, 120, 2))
            for _ in range(20)
        ],
    ]:
        got = hs._window(h, ox0, oy0, mx, my, tables)
        ox, oy = (ox0 + np.arange(mx)) * h, (oy0 + np.arange(my)) * h
        want = love_rectangle(ox[None, :], oy[:, None], h / 2, h / 2, hs.E_star)
        assert got.shape == want.shape
        assert np.allclose(got, want, rtol=1e-9, atol=1e-12 * want.max())


def test_the_compliance_among_points_is_kept_and_cut_for_a_subset(monkeypatch):
    # the macro step's interaction among the tips, then the coarse space's among the tips
    # that have patches (a subset, in another order): the body makes it once, the same values
    hs = HalfSpace(MAT)
    tips = np.random.default_rng(4).random((200, 2)) * 10.0
    made = []
    body_compliance = HalfSpace.point_compliance

    def counted(self, targets, sources):
        made.append((len(targets), len(sources)))
        return body_compliance(self, targets, sources)

    monkeypatch.setattr(HalfSpace, "point_compliance", counted)
    cached = CachedBody(hs, OperatorCaches())
    first = cached.point_compliance(tips, tips)
    first[0, 1] = -1.0  # the caller's copy: changing it does not change what is kept
    again = cached.point_compliance(tips, tips.copy())
    some = np.array([150, 3, 77, 4, 199, 0] + list(range(20, 90)))
    cut = cached.point_compliance(tips[some], tips[some])
    assert made == [(200, 200)]
    np.testing.assert_array_equal(again, body_compliance(hs, tips, tips))
    np.testing.assert_array_equal(cut, body_compliance(hs, tips[some], tips[some]))
    # most points kept, two not (merged blocks' mean tips): their rows and columns by the body
    merged = np.vstack([tips[some], 0.5 * (tips[:2] + tips[2:4])])
    mixed = cached.point_compliance(merged, merged)
    np.testing.assert_array_equal(mixed, body_compliance(hs, merged, merged))
    assert made[1:] == [(2, len(merged)), (len(merged) - 2, 2)]
    # most points not kept, or targets other than the sources: the body's
    other = np.vstack([tips[:10], tips[:60] + 20.0])
    cached.point_compliance(other, other)
    cached.point_compliance(tips[:100], tips[100:])
    assert made[3:] == [(70, 70), (100, 100)]
