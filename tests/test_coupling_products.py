"""Cross-patch products of the micro step (twoscale.micro.blocks.Coupling): the fast routes
(near pairs summed in Fourier space on a common padded shape, separated pairs through
Chebyshev nodes) against the dense blocks of the provider (Love's closed form, exact)."""

import dataclasses

import numpy as np
import pytest

from twoscale.grid import Grid
from twoscale.indenters import Asperity
from twoscale.influence.halfspace import HalfSpace
from twoscale.material import Material
from twoscale.micro.blocks import Coupling, size_class
from twoscale.micro.patches import grow_patch, make_patch

HS = HalfSpace(Material(E=10.0, nu=0.3))
H = 0.1


def _scene():
    # three close spheres (patches touching, merged ownership), one a little apart, one far
    tips = [(0.0, 0.0), (2.1, 0.3), (1.0, 1.9), (5.0, -1.0), (14.0, 6.0)]
    asps = [Asperity(x=x, y=y, z=0.0, R=5.0) for x, y in tips]
    patches = []
    for k, (x, y) in enumerate(tips):
        w = 1.2 + 0.2 * k  # patches of different shapes
        patches.append(make_patch(k, Grid.covering(x - w, x + w, y - 1.1, y + 1.1, H), asps))
    return asps, patches


def _exact(patches, k, values, rhs):
    out = rhs.copy()
    for l, v in enumerate(values):
        if l != k:
            ik = np.flatnonzero(patches[k].owned.ravel())
            il = np.flatnonzero(patches[l].owned.ravel())
            out -= HS.grid_matrix(patches[k].grid, patches[l].grid)[np.ix_(ik, il)] @ v
    return out


def test_fast_routes_equal_the_dense_blocks():
    asps, patches = _scene()
    rng = np.random.default_rng(0)
    fast = Coupling(HS, patches, dense_max_entries=0)
    values = [rng.random(int(p.owned.sum())) for p in patches]
    for sweep in range(2):
        for k in range(len(patches)):
            b = rng.random(int(patches[k].owned.sum()))
            ref = _exact(patches, k, values, b)
            got = fast.rhs(k, values, b)
            np.testing.assert_allclose(got, ref, atol=1e-9 * np.abs(b - ref).max())
            values[k] = rng.random(len(values[k]))  # a Gauss-Seidel update: a new vector
    kinds = {route[0] for route in fast._routes.values()}
    assert kinds == {"spectral", "separated"}  # near pairs took one route, far pairs the other


def test_growth_into_another_size_class_rebuilds_the_spectral_pairs():
    asps, patches = _scene()
    rng = np.random.default_rng(1)
    fast = Coupling(HS, patches, dense_max_entries=0)
    values = [rng.random(int(p.owned.sum())) for p in patches]
    fast.rhs(0, values, np.zeros(len(values[0])))
    before = size_class(patches[1].grid.nx)
    for _ in range(3):  # into a larger size class
        patches[1] = grow_patch(patches[1], (True, True, True, True), asps)
    assert size_class(patches[1].grid.nx) > before
    fast.replace(1, patches[1])
    values[1] = rng.random(int(patches[1].owned.sum()))
    for k in (0, 1, 2):
        b = np.zeros(int(patches[k].owned.sum()))
        np.testing.assert_allclose(
            fast.rhs(k, values, b),
            _exact(patches, k, values, b),
            atol=1e-9 * np.abs(_exact(patches, k, values, b)).max(),
        )


def test_several_right_hand_sides_at_once():
    asps, patches = _scene()
    rng = np.random.default_rng(2)
    fast = Coupling(HS, patches, dense_max_entries=0)
    values = [rng.random((int(p.owned.sum()), 3)) for p in patches]
    b = np.zeros((int(patches[2].owned.sum()), 3))
    ref = np.column_stack([_exact(patches, 2, [v[:, j] for v in values], b[:, j]) for j in range(3)])
    np.testing.assert_allclose(fast.rhs(2, values, b), ref, atol=1e-9 * np.abs(ref).max())


@pytest.mark.parametrize("kwargs", [dict(), dict(separated_rtol=None)])
def test_a_changed_vector_in_place_of_the_old_one_is_seen(kwargs):
    # the caches are keyed by the vector object: a new object must never reuse old spectra
    asps, patches = _scene()
    fast = Coupling(HS, patches, dense_max_entries=0, **kwargs)
    values = [np.ones(int(p.owned.sum())) for p in patches]
    b = np.zeros(int(patches[0].owned.sum()))
    first = fast.rhs(0, values, b)
    values = [2.0 * v for v in values]
    np.testing.assert_allclose(fast.rhs(0, values, b), 2.0 * first, rtol=1e-12)


@pytest.fixture(scope="module")
def small_block():
    from fem_influence import BlockProvider

    return BlockProvider(
        material=Material(E=2.0, nu=0.5),
        use_cache=False,
        progress=False,
        size=(60.0, 60.0, 10.0),
        h_fine=5.0,
        h_coarse=10.0,
        fine_half_width=10.0,
    )


def _exact_with(provider, patches, k, values, rhs):
    out = rhs.copy()
    ik = np.flatnonzero(patches[k].owned.ravel())
    for l, v in enumerate(values):
        if l != k:
            il = np.flatnonzero(patches[l].owned.ravel())
            out -= provider.grid_matrix(patches[k].grid, patches[l].grid)[np.ix_(ik, il)] @ v
    return out


def test_block_provider_routes_add_its_correction(small_block):
    # the finite block splits into the half-space (fast routes) and its low-rank correction,
    # added per target from the sources' summed coefficients; against its dense blocks
    base, corr = small_block.split()
    assert isinstance(base, HalfSpace) and corr is not None
    asps, patches = _scene()
    rng = np.random.default_rng(3)
    fast = Coupling(small_block, patches, dense_max_entries=0)
    values = [rng.random(int(p.owned.sum())) for p in patches]
    for k in range(len(patches)):
        b = np.zeros(int(patches[k].owned.sum()))
        ref = _exact_with(small_block, patches, k, values, b)
        # the correction is a sizeable part of the interaction on a 10 mm block
        hs = _exact_with(base, patches, k, values, b)
        assert np.abs(ref - hs).max() > 0.05 * np.abs(ref).max()
        np.testing.assert_allclose(fast.rhs(k, values, b), ref, atol=1e-8 * np.abs(ref).max())
    assert {route[0] for route in fast._routes.values()} == {"spectral", "separated"}


def test_whole_patch_displacement_by_the_routes():
    asps, patches = _scene()
    rng = np.random.default_rng(4)
    fast = Coupling(HS, patches, dense_max_entries=0)
    values = [rng.random(int(p.owned.sum())) for p in patches]
    for k in (0, 4):
        ref = np.zeros(patches[k].grid.shape)
        for l, v in enumerate(values):
            if l != k:
                il = np.flatnonzero(patches[l].owned.ravel())
                ref += (HS.grid_matrix(patches[k].grid, patches[l].grid)[:, il] @ v).reshape(ref.shape)
        np.testing.assert_allclose(fast.patch_displacement(k, values), ref, atol=1e-9 * np.abs(ref).max())


def test_size_class_ladder():
    ladder = [size_class(n) for n in range(1, 200)]
    assert ladder[:8] == [8] * 8
    assert all(size_class(n) >= n for n in range(1, 500))
    assert all(size_class(n) <= max(8, 1.2 * n + 1) for n in range(1, 500))  # at most ~20 % padding
    assert len(set(ladder)) < 20


def test_without_memory_for_operators_every_pair_falls_back_to_plain_products():
    asps, patches = _scene()
    rng = np.random.default_rng(5)
    tight = Coupling(HS, patches, dense_max_entries=0, cache_bytes=1.0)
    values = [rng.random(int(p.owned.sum())) for p in patches]
    b = np.zeros(int(patches[0].owned.sum()))
    ref = _exact(patches, 0, values, b)
    np.testing.assert_allclose(tight.rhs(0, values, b), ref, atol=1e-9 * np.abs(ref).max())
    assert {route[0] for route in tight._routes.values()} == {"plain"}
    assert not tight._fft


def test_solver_answer_does_not_depend_on_the_routes():
    # a 3 x 3 grid of spheres 6 mm apart (separated pairs) and two close ones (spectral pairs)
    from twoscale.driver import solve_twoscale

    asps = [Asperity(x=6.0 * i, y=6.0 * j, z=0.0, R=5.0) for j in range(3) for i in range(3)]
    asps.append(Asperity(x=1.8, y=0.4, z=0.0, R=5.0))
    # the block iterations, whose cross-patch products take these routes (the policy may
    # take the union CG here: 0.12-0.14 s against 0.13 s, measured)
    kw = dict(h=0.05, penetration=0.08, iteration="block-gs")
    fast = solve_twoscale(HS, asps, **kw)
    plain = solve_twoscale(HS, asps, separated_rtol=None, **kw)
    assert fast.converged and plain.converged
    f1, f2 = fast.macro_forces, plain.macro_forces
    np.testing.assert_allclose(f1, f2, rtol=1e-12)
    # the routes change the cross products by <= 1e-8 of a pair's displacement; the final
    # forces move by far less than the 1e-6 sweep tolerance
    np.testing.assert_allclose(fast.asperities.forces, plain.asperities.forces, rtol=1e-6)
    assert fast.asperities.forces.min() > 0
    # the result says which routes ran (and result.json carries it)
    used, off = fast.details.micro.coupling, plain.details.micro.coupling
    assert used.separated > 0 and used.spectral > 0 and used.separated_rtol == 1e-8
    assert off.separated == 0 and off.separated_rtol is None
    from twoscale.io.result_json import result_to_dict
    from twoscale.scene import Scene

    scene = Scene(material=HS.material, asperities=asps, penetration=0.08, h=0.05)
    assert result_to_dict(fast, scene)["coupling"] == dataclasses.asdict(used)
    with pytest.raises(ValueError, match="separated_rtol"):
        solve_twoscale(HS, asps, separated_rtol=0.0, **kw)


@pytest.mark.parametrize("far", [False, True])
def test_transposed_operators_equal_the_reverse_pair(far):
    """``op.transposed()`` (the coupling takes (l, k) from (k, l) by reciprocity) equals the
    operator built for the reverse pair: the FFT operator (conjugate spectrum times a phase
    per axis) and the separated one (its node kernel transposed), on pairs of unequal grids."""
    base = Grid(0.0, 0.0, H, 400, 400)
    a = base.subgrid(10, 12, 13, 9)
    b = base.subgrid(200 if far else 18, 5, 7, 11)
    op = HS.separated_operator(a, b, rtol=1e-8) if far else HS.grid_operator(a, b)
    assert op is not None
    back = op.transposed()
    reverse = HS.grid_operator(b, a)
    p = np.random.default_rng(2).uniform(size=a.shape)
    want = reverse.apply(p)
    assert back.source == a and back.target == b
    assert np.allclose(back.apply(p), want, rtol=1e-7 if far else 1e-12, atol=0.0)
    assert np.allclose(back.finish(back.multiply(back.spectrum(p))), want, rtol=1e-7 if far else 1e-12)


def test_a_kept_pair_too_large_for_a_whole_patch_block_goes_by_its_route(monkeypatch):
    # patches 0-2 overlap (cells a neighbour owns): the whole patch's displacement from a
    # kept dense pair takes those cells from a block, or past the cap from the FFT route
    from twoscale.micro import farfield, localblock
    from twoscale.micro.farfield import FarFieldCoupling

    asps, patches = _scene()
    rng = np.random.default_rng(5)
    values = [rng.random(int(p.owned.sum())) for p in patches]
    calls = []
    monkeypatch.setattr(farfield, "whole_patch", lambda *a: calls.append(1) or localblock.whole_patch(*a))
    for cap, blocks in ((10**9, True), (0, False)):
        monkeypatch.setattr(localblock, "WHOLE_PATCH_MAX_ENTRIES", cap)
        near = FarFieldCoupling(HS, patches, far_tol=1e-6, dense_max_entries=10**6)
        for l in (1, 2):
            near.apply(0, l, values[l])  # makes and keeps the dense pair
        assert (0, 1) in near._ops and (0, 2) in near._ops
        calls.clear()
        ref = np.zeros(patches[0].grid.shape)
        for l, v in enumerate(values[1:], start=1):
            il = np.flatnonzero(patches[l].owned.ravel())
            ref += (HS.grid_matrix(patches[0].grid, patches[l].grid)[:, il] @ v).reshape(ref.shape)
        got = near.patch_displacement(0, values)
        np.testing.assert_allclose(got, ref, atol=1e-9 * np.abs(ref).max())
        assert bool(calls) is blocks
