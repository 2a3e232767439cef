"""Fixed costs of the default solve on the sweep's smallest scenes (one or two tips, where
the full-grid reference takes 10-30 ms): counted in law evaluations and products, not
timed."""

import numpy as np
import pytest

from twoscale.laws import HertzLaw, LawStack, SphereLaw
from twoscale.macro.start import independent_approach


class _Counting(LawStack):
    calls = 0

    def force(self, delta):
        type(self).calls += 1
        return super().force(delta)


@pytest.mark.parametrize("law, z", [(SphereLaw(20.0, 20.0), [0.0]), (HertzLaw(3.0, 5.0), [0.0, 0.01, 0.3])])
def test_the_load_control_start_carries_the_load_in_few_law_evaluations(law, z):
    # the cold start of the macro step under load control: the approach at which the tips,
    # alone, carry W; bisection to the last bit asked the laws 66 times (40 % of a
    # one-sphere solve's CPU time)
    z = np.array(z)
    stack = _Counting([law] * len(z))
    _Counting.calls = 0
    W = 0.0019
    d = independent_approach(z, stack, W)
    carried = float(np.sum(LawStack([law] * len(z)).force(d - z)))
    assert carried == pytest.approx(W, rel=1e-12)
    assert _Counting.calls <= 35


def test_the_smallest_scenes_take_their_full_grid_and_say_so():
    # 12 merged spheres under penetration control on a full grid of 2,491 cells: the macro
    # step's safe path alone (0.11 s of CPU) cost three times the whole full-grid CG
    import twoscale
    from twoscale.micro.full_grid_rule import FULL_GRID_MAX_CELLS
    from twoscale.reference.on_scene import reference_grid
    from twoscale.scene import default_h
    from twoscale.scenespace import build, draw

    scene = build(draw(152, 0))
    h = default_h(scene) if scene.h is None else scene.h
    assert reference_grid(scene, h).size <= FULL_GRID_MAX_CELLS
    res = twoscale.solve(scene)
    ref = twoscale.solve(scene, method="reference")
    assert res.method == "reference" and res.converged
    assert res.message.startswith("default route: the full grid has 2,491 cells")
    # the reference's grid and tolerance, its CG preconditioned: the same discrete answer
    # to the tolerance's ~2e-7, in fewer iterations
    assert "preconditioned CG" in res.message
    f, f_ref = res.asperities.forces, ref.asperities.forces
    assert np.max(np.abs(f - f_ref)) <= 1e-6 * np.max(f_ref)
    assert res.iterations["cg"] < ref.iterations["cg"]
    # the memory estimate follows the route: the reference grid's (a default solve made
    # the patches' surface for it before, ~1 ms of a 20 ms solve)
    from twoscale.resources import estimate_memory

    est = estimate_memory(scene, h, "twoscale")
    assert est.cells == reference_grid(scene, h).size
    assert est.bytes == estimate_memory(scene, h, "reference").bytes
    assert estimate_memory(scene, h, "twoscale", iteration="block-gs").cells != est.cells
    # any option asks for the two-scale solver itself
    res = twoscale.solve(scene, tol=1e-6)
    assert res.method == "twoscale" and res.details.micro.attempts[-1].converged
    f, r = np.asarray(res.asperities.forces), np.asarray(ref.asperities.forces)
    assert np.max(np.abs(f - r)) <= 1e-3 * np.max(r)


def test_a_larger_full_grid_keeps_the_two_scale_route():
    # two spheres 1.5 contact diameters apart on a full grid of 8,736 cells: the two-scale
    # solve ran at 0.9x the full grid's
    import twoscale
    from twoscale.scenespace import build, draw

    res = twoscale.solve(build(draw(199, 0)))
    assert res.method == "twoscale" and res.converged


@pytest.mark.parametrize("split", [0, None, 10**12])
@pytest.mark.parametrize("shape", ["paraboloid", "sphere"])
def test_a_large_union_box_is_sampled_tile_by_tile_to_the_same_surface(shape, split, monkeypatch):
    # 843 paraboloids sampled on every cell of their union box took about 45 s of CPU
    # before the CG's first iteration; a tile only needs the tips that can own a cell of it
    from twoscale.grid import Grid
    from twoscale.indenters import Asperity, surface_on
    from twoscale.micro.patches import TipTable
    from twoscale.micro.sampling import SAMPLE_WHOLE_CELLS, box_surface

    rng = np.random.default_rng(3)
    tips = [
        Asperity(float(x), float(y), float(z), float(r), shape)
        for x, y, z, r in zip(
            rng.uniform(-6, 6, 80), rng.uniform(-6, 6, 80), rng.uniform(0, 0.05, 80), rng.uniform(0.5, 3.0, 80)
        )
    ]
    grid = Grid.covering(-6.5, 6.5, -6.2, 6.2, 0.04)
    assert grid.size > SAMPLE_WHOLE_CELLS
    if split is not None:  # tiles split down to the smallest (0), or never
        monkeypatch.setattr("twoscale.micro.sampling.SAMPLE_SPLIT_ENTRIES", split)
    tiled, whole = box_surface(grid, TipTable.of(tips)), surface_on(grid, tips)
    assert np.array_equal(tiled.owner, whole.owner)
    # the tiles' cell centres are x0 + i0 h + i h, the box's x0 + (i0 + i) h: rounding only
    assert np.array_equal(np.isinf(tiled.height), np.isinf(whole.height))
    finite = np.isfinite(whole.height)
    assert np.allclose(tiled.height[finite], whole.height[finite], rtol=0.0, atol=1e-12)


def test_a_box_of_dense_paraboloids_is_sampled_in_small_tiles_to_the_same_surface(monkeypatch):
    # a lattice of paraboloids 0.4 mm apart: a large tile's height bound (from the tips
    # nearest its centre) lets in hundreds of tips; small tiles, all evaluated at once, let
    # in few, and the surface is still the union of every tip on every cell
    from twoscale.grid import Grid
    from twoscale.indenters import Asperity, surface_on
    from twoscale.micro import envelope, sampling
    from twoscale.micro.patches import TipTable

    rng = np.random.default_rng(5)
    xs = np.arange(-4.0, 4.0, 0.4)
    tips = [
        Asperity(float(x), float(y), float(rng.uniform(0, 0.01)), float(rng.uniform(0.4, 1.0)), "paraboloid")
        for x in xs
        for y in xs
    ]
    grid = Grid.covering(-4.0, 4.0, -4.0, 4.0, 0.03)
    assert grid.size > sampling.SAMPLE_WHOLE_CELLS
    calls = []
    monkeypatch.setattr(sampling, "envelope_on", lambda g, t: calls.append(g) or envelope.envelope_on(g, t))
    tiled, whole = sampling.box_surface(grid, TipTable.of(tips)), surface_on(grid, tips)
    assert calls == [grid]
    assert np.array_equal(tiled.owner, whole.owner)
    # the box's own cell centres and the same arithmetic: the same heights to the bit
    assert np.array_equal(tiled.height, whole.height)
