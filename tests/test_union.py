"""The union iteration (one constrained CG over the patches' box) against the full-grid
reference on seeded random scenes: penetration control, load control, load with tilt;
and the mixed-precision CG against the double-precision one."""

from __future__ import annotations


import numpy as np
import pytest

from helpers import crowded
from twoscale import Material
from twoscale.indenters import surface_on
from twoscale.influence import HalfSpace
from twoscale.reference import solve_cg
from twoscale.reference.on_scene import reference_grid
from twoscale.api import solve_scene
from twoscale.scene import Scene
from twoscale.driver import solve_twoscale

MAT = Material(E=6.0, nu=0.5)
HS = HalfSpace(MAT)


@pytest.mark.parametrize(
    "seed,load", [(0, {"penetration": 0.15}), (1, {"total_load": 24.0}), (2, {"total_load": 24.0, "tilt": True})]
)
def test_union_cg_matches_the_reference(seed, load):
    asps = crowded(seed, 12)
    h = 0.1
    res = solve_twoscale(HS, asps, h=h, iteration="union-cg", tol=1e-8, **load)
    assert res.converged, res.message
    scene = Scene(material=MAT, asperities=asps, h=h, **load)
    ref = solve_scene(scene, method="reference", tol=1e-10)
    assert ref.converged
    F, Fr = res.asperities.forces, ref.asperities.forces
    assert np.max(np.abs(F - Fr)) <= 1e-6 * Fr.max()
    assert res.total_load == pytest.approx(ref.total_load, rel=1e-8)
    assert res.penetration == pytest.approx(ref.penetration, abs=1e-8)
    if load.get("tilt"):
        assert np.allclose(res.tilt, ref.tilt, atol=1e-8)
    grid = reference_grid(scene, h)
    p, pr = res.pressure_on(grid), ref.pressure_on(grid)
    assert np.linalg.norm(p - pr) <= 1e-5 * np.linalg.norm(pr)


def test_mixed_precision_meets_the_same_tolerance_in_fewer_double_iterations():
    asps = crowded(3, 10)
    grid = reference_grid(Scene(material=MAT, asperities=asps, h=0.08, total_load=20.0), 0.08)
    surf = surface_on(grid, asps)
    double = solve_cg(HS, surf, total_load=20.0, tol=1e-9)
    mixed = solve_cg(HS, surf, total_load=20.0, tol=1e-9, precision="mixed")
    assert double.converged and mixed.converged
    single = mixed.details.single_precision_iterations
    assert single > 0
    # the double-precision stage starts from the single one's answer: fewer double iterations
    assert mixed.iterations["cg"] - single < double.iterations["cg"]
    p, pd = mixed.pressure_on(grid), double.pressure_on(grid)
    assert np.linalg.norm(p - pd) <= 1e-6 * np.linalg.norm(pd)
    with pytest.raises(ValueError, match="precision"):
        solve_cg(HS, surf, total_load=20.0, precision="half")


def test_single_precision_operator_agrees_with_the_double_one():
    from twoscale.grid import Grid

    g = Grid.covering(-3.0, 3.0, -2.0, 2.0, 0.1)
    op = HS.grid_operator(g)
    p = np.random.default_rng(0).uniform(0.0, 1.0, g.shape)
    u, u32 = op.apply(p), op.single_precision().apply(p)
    assert u32.dtype == np.float64
    assert np.max(np.abs(u32 - u)) <= 1e-6 * np.max(np.abs(u))
    assert np.max(np.abs(u32 - u)) > 0  # it is really another computation


def test_block_gauss_seidel_merges_close_patches_under_load_control():
    # load control with merged contacts through the paper's iteration: close patches are
    # one block, and the answer is the reference's
    asps = crowded(4, 10)
    res = solve_twoscale(HS, asps, h=0.1, total_load=20.0, iteration="block-gs", tol=1e-8)
    assert res.converged, res.message
    assert any(len(m) > 1 for m in res.details.micro.merged_patches)
    scene = Scene(material=MAT, asperities=asps, h=0.1, total_load=20.0)
    ref = solve_scene(scene, method="reference", tol=1e-10)
    F, Fr = res.asperities.forces, ref.asperities.forces
    assert np.max(np.abs(F - Fr)) <= 1e-5 * Fr.max()
    assert res.penetration == pytest.approx(ref.penetration, abs=1e-7)


def test_the_union_cg_takes_single_precision_directions():
    # one stage with float32 search directions (no restart at 1e-6)
    from twoscale.micro.union import MIXED_MIN_CELLS, union_precision

    assert union_precision("auto", MIXED_MIN_CELLS) == "single-directions"
    assert union_precision("auto", MIXED_MIN_CELLS - 1) == "double"
    assert union_precision("mixed", 10 * MIXED_MIN_CELLS) == "mixed"
    # on a box above the threshold the answer is the full grid's (double precision)
    asps = crowded(4, 16)
    h = 0.05
    for load in ({"penetration": 0.15}, {"total_load": 30.0}, {"total_load": 30.0, "tilt": True}):
        res = solve_twoscale(HS, asps, h=h, iteration="union-cg", tol=1e-8, **load)
        assert res.converged, res.message
        ref = solve_scene(Scene(material=MAT, asperities=asps, h=h, **load), method="reference", tol=1e-10)
        F, Fr = res.asperities.forces, ref.asperities.forces
        assert np.max(np.abs(F - Fr)) <= 1e-6 * Fr.max()
        if load.get("tilt"):
            assert np.allclose(res.tilt, ref.tilt, atol=1e-8)


def test_single_precision_directions_converge_with_the_tilt():
    # with the tilt's moments restored every step the displacement is refreshed from
    # scratch; it was refreshed in float32 even below the fast products' residual, and the
    # CG never reached 1e-8 (4 tilted spheres: 1,019 iterations against 54 in two stages)
    grid = reference_grid(Scene(material=MAT, asperities=crowded(5, 12), h=0.08, total_load=20.0, tilt=True), 0.08)
    surf = surface_on(grid, crowded(5, 12))
    kw = dict(total_load=20.0, tilt=True, tol=1e-8, max_iter=400, precondition=True)
    mixed = solve_cg(HS, surf, precision="mixed", **kw)
    one = solve_cg(HS, surf, precision="single-directions", **kw)
    assert mixed.converged and one.converged, one.message
    assert one.iterations["cg"] <= mixed.iterations["cg"] + 10
    p, pm = one.pressure_on(grid), mixed.pressure_on(grid)
    assert np.linalg.norm(p - pm) <= 1e-6 * np.linalg.norm(pm)


def test_union_box_grows_only_on_the_sides_the_pressure_reaches():
    # seven tilted spheres passed one side of their box by 4 cells: grown about its centre
    # the box had 2.25x the cells; grown on that side alone, 1.25x
    from twoscale.grid import Grid
    from twoscale.micro.union import grown_box

    box = Grid(1.0, -2.0, 0.5, 40, 20)
    p = np.zeros(box.shape)
    p[5:9, -1] = 1.0  # the right edge only
    right = grown_box(box, p)
    assert (right.ny, right.nx) == (20, 50) and (right.x0, right.y0) == (box.x0, box.y0)
    assert box.window_in(right) == (slice(0, 20), slice(0, 40))
    p[0, 3] = p[-1, 3] = p[7, 0] = 1.0  # every side
    every = grown_box(box, p)
    assert (every.ny, every.nx) == (30, 60) and every.x0 == box.x0 - 10 * 0.5 and every.y0 == box.y0 - 5 * 0.5
    assert box.offset_in(every) == (10, 5)


def test_under_a_free_tilt_the_union_box_is_wide_enough_at_once():
    # the sweep's seven tilted spheres under load: the macro tilt (0.146 against 0.089) and
    # forces (0.035 against 0.055 N) sized two patches short, and the box grew once (40 CG
    # iterations on two boxes); the first box now covers patches of the tilt's margin
    from twoscale.grid import Grid
    from twoscale.micro.patches import patch_radius
    from twoscale.micro.sampling import box_of
    from twoscale.micro.union import TILT_MARGIN
    from twoscale.micro.workset import tip_approaches
    from twoscale.scenespace import build, sweep

    (spec,) = [s for s in sweep(200, 0) if s.index == 132]
    scene = build(spec)
    result = solve_scene(scene)
    micro, macro, field = result.details.micro, result.details.macro, result.fields[0]
    assert micro.strategy == "union-cg" and micro.growths == 0 and result.converged
    # the box of the patches the micro step's margin gives (written out from the macro step)
    # does not hold the contact, and the box of the tilt's margin is the field's
    h, anchor = field.grid.h, (0.0, 0.0)  # the default lattice
    theta = (macro.penetration, *macro.tilt)
    approach = tip_approaches(scene.asperities, theta, scene.pivot)
    E_star = scene.material.E_star

    def box(margin):
        grids = []
        for k, a in enumerate(scene.asperities):
            if approach[k] > 0:
                r = patch_radius(a, force=macro.forces[k], approach=approach[k], E_star=E_star, h=h, margin=margin)
                grids.append(Grid.covering(a.x - r, a.x + r, a.y - r, a.y + r, h, anchor=anchor))
        return box_of(grids, h, anchor)

    narrow, wide = box(1.3), box(TILT_MARGIN)
    inside = np.zeros(field.grid.shape, dtype=bool)
    di, dj = narrow.offset_in(field.grid)
    inside[max(dj, 0) : dj + narrow.ny, max(di, 0) : di + narrow.nx] = True
    assert np.any(field.pressure[~inside] > 0)
    assert field.grid.shape == wide.shape and wide.offset_in(field.grid) == (0, 0)


@pytest.mark.parametrize("n", [20, 150])
def test_a_widened_box_keeps_the_cells_it_had_and_samples_the_rest(n):
    # the union box widened under a free tilt, or grown, samples only the strips around the
    # box it had (among more than TREE_MIN asperities tile by tile)
    from twoscale.grid import Grid
    from twoscale.indenters import Asperity, Surface
    from twoscale.micro.union import widened_surface

    rng = np.random.default_rng(n)
    shapes = ["sphere", "paraboloid"]
    asps = [
        Asperity(x, y, z, R, shape=shapes[k % 2])
        for k, (x, y, z, R) in enumerate(
            zip(rng.uniform(-2, 2, n), rng.uniform(-2, 2, n), rng.uniform(0, 0.05, n), rng.uniform(0.5, 2.0, n))
        )
    ]
    box = Grid.covering(-2.0, 2.0, -1.5, 2.5, 0.02)
    inner = box.subgrid(7, 11, box.nx - 20, box.ny - 15)
    whole = surface_on(box, asps)
    part = surface_on(inner, asps)
    marked = Surface(inner, part.height + 1.0, part.owner, n)  # kept cells are not sampled again
    out = widened_surface(marked, box, asps)
    rows, cols = inner.window_in(box)
    keep = np.zeros(box.shape, dtype=bool)
    keep[rows, cols] = True
    assert out.grid == box and np.array_equal(out.height[keep], marked.height.ravel())
    assert np.array_equal(out.owner[~keep], whole.owner[~keep])
    finite = np.isfinite(whole.height) & ~keep
    assert np.array_equal(np.isfinite(out.height) & ~keep, finite)
    assert np.allclose(out.height[finite], whole.height[finite], rtol=0, atol=1e-12)
    assert widened_surface(whole, box, asps) is whole


def test_the_reach_holds_the_cells_below_the_highest_macro_level():
    from twoscale.grid import Grid
    from twoscale.indenters import Asperity, Surface
    from twoscale.micro.union import REACH_MARGIN, contact_reach

    g = Grid(0.0, 0.0, 0.1, 10, 10)
    height = np.tile(np.linspace(0.0, 0.9, 10), (10, 1))  # 0.0 ... 0.9 along x
    height[0, 0] = np.inf  # no material
    owner = np.zeros((10, 10), int)
    tips = [Asperity(0.0, 0.0, 0.0, 5.0), Asperity(0.5, 0.5, 0.2, 5.0)]
    surf = Surface(g, height, owner, 2)
    reach = contact_reach(surf, tips, np.array([0.1, 0.15]))  # highest level 0.35
    level = 0.35 + REACH_MARGIN * 0.35
    assert np.array_equal(reach, np.isfinite(height) & (height < level))
    assert reach.sum() == 4 * 10 - 1
    assert contact_reach(surf, tips, np.array([0.1, 0.5])) is None  # 0.77 mm: most of the box


@pytest.mark.parametrize("margin", [0.1, -0.9])
def test_the_union_cg_on_its_reach_gives_the_whole_box_answer(margin, monkeypatch):
    # -0.9: a part that misses contact cells, so the answer is solved on the whole box from it
    import twoscale.micro.union as union
    from twoscale.pk import compact

    asps = crowded(4, 12)
    kw = dict(h=0.1, iteration="union-cg", tol=1e-8, total_load=24.0)
    whole = solve_twoscale(HS, asps, **kw)
    monkeypatch.setattr(union, "REACH_MAX_FRACTION", 1.0)
    monkeypatch.setattr(union, "REACH_MARGIN", margin)
    touched = []
    answer = compact.Part.answer

    def recorded(self, *args):
        out = answer(self, *args)
        touched.append(out[2])
        return out

    monkeypatch.setattr(compact.Part, "answer", recorded)
    part = solve_twoscale(HS, asps, **kw)
    assert whole.converged and part.converged
    assert touched == [margin < 0]
    F, Fw = part.asperities.forces, whole.asperities.forces
    assert np.max(np.abs(F - Fw)) <= 1e-7 * Fw.max()
