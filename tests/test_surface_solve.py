"""Measured surfaces in the solvers.

* the tabulated law of a paraboloid basin against Hertz (closed form);
* a height map sampled from known spheres gives back their summits, and the same forces
  as the sphere scene on the same lattice (the rigid surfaces are the same samples);
* on a seeded random road texture, the two-scale solve against the full-grid reference
  on the same map and grid: total load and contact area within 0.5 %, per-asperity forces
  within 1 %, pressure field within 2 % (L2), under load and penetration control.
"""

import numpy as np
import pytest

from twoscale import Material
from twoscale.analytic import hertz
from twoscale.indenters import Asperity, surface_on
from twoscale.influence import HalfSpace
from twoscale.reference import solve_reference
from twoscale.surface import RawMap, SurfaceOptions, build_surface
from twoscale.surface.texture import road
from twoscale.driver import solve_twoscale

MAT = Material(10.0, 0.5)
HS = HalfSpace(MAT)


def _lattice(n, h):
    x = (np.arange(n) - n // 2) * h
    return np.meshgrid(x, x)


def _surface(z, h, **options):
    return build_surface(RawMap(z, h, "mm", None, "test map"), SurfaceOptions(**options))


@pytest.mark.parametrize("R", [5.0, 10.0])
def test_paraboloid_basin_law_matches_hertz(R):
    h = 0.05
    X, Y = _lattice(121, h)
    s = _surface(-(X**2 + Y**2) / (2 * R), h, prominence=0.01, law_depth=0.1)
    assert len(s.asperities) == 1
    assert s.asperities[0].R == pytest.approx(R, rel=1e-6)  # the cap fit of an exact paraboloid
    table = s.book.table(MAT)
    d, P = table.delta[0, 1:], table.P[0, 1:]
    # 2a/h from 4 to 36 cells across: 3 % at the smallest, 0.5 % at the largest
    assert np.allclose(P, hertz.load(R, d, MAT.E_star), rtol=0.03)
    assert P[-1] == pytest.approx(float(hertz.load(R, d[-1], MAT.E_star)), rel=0.005)
    assert table.exponents()[0] == pytest.approx(1.5, abs=0.01)
    assert s.sphere_error(MAT).largest < 0.03


SPHERES = [
    Asperity(-3.0, -2.0, 0.0, 4.0),
    Asperity(2.5, 1.5, 0.05, 3.0),
    Asperity(-1.0, 3.5, 0.1, 5.0),
    Asperity(3.0, -4.0, 0.02, 2.5),
]


def _spheres_map(h=0.1, n=151):
    X, Y = _lattice(n, h)
    z = np.full(X.shape, -1.0)  # a floor below every cap, never reached
    for a in SPHERES:
        z = np.maximum(z, -a.height(X, Y))
    return z


@pytest.mark.parametrize("load", [{"penetration": 0.2}, {"total_load": 20.0}])
def test_map_of_spheres_gives_back_the_sphere_scene(load):
    h = 0.1
    s = _surface(_spheres_map(h), h, min_distance=1.0, prominence=0.1)
    assert len(s.asperities) == len(SPHERES)
    got = {(round(a.x, 6), round(a.y, 6)): a for a in s.asperities}
    for sp in SPHERES:  # every summit found on its sample, with its recess and radius
        a = got[(sp.x, sp.y)]
        assert a.z == pytest.approx(sp.z, abs=1e-12)
        assert a.R == pytest.approx(sp.R, rel=0.02)  # the exact sphere's cap is not a paraboloid
    on_map = solve_twoscale(HS, s.asperities, h=h, **load)
    spheres = solve_twoscale(HS, SPHERES, h=h, **load)
    assert on_map.converged and spheres.converged, (on_map.message, spheres.message)
    order = [s.asperities.index(got[(sp.x, sp.y)]) for sp in SPHERES]
    # the same samples, the same discrete problem: equal to the solvers' tolerance
    assert np.allclose(on_map.asperities.forces[order], spheres.asperities.forces, rtol=1e-4)
    assert on_map.penetration == pytest.approx(spheres.penetration, rel=1e-6)


def _compare(result, reference, grid):
    assert result.converged, result.message
    assert reference.converged, reference.message
    assert result.total_load == pytest.approx(reference.total_load, rel=0.005)
    f, g = result.asperities.forces, reference.asperities.forces
    big = g > 0.01 * g.max()
    assert np.all(np.abs(f - g)[big] <= 0.01 * g[big])
    assert np.all(f[~big] <= 0.02 * g.max())
    p, q = result.pressure_on(grid), reference.pressure_on(grid)
    assert np.count_nonzero(p) == pytest.approx(np.count_nonzero(q), rel=0.005)
    assert np.linalg.norm(p - q) <= 0.02 * np.linalg.norm(q)


@pytest.mark.parametrize("seed", [1, 2])
def test_road_texture_twoscale_agrees_with_the_reference(seed):
    h = 0.1
    s = _surface(road(16.0, h, seed=seed), h)
    assert len(s.asperities) >= 5
    W = 0.2 * 16.0 * 16.0  # 0.2 MPa nominal
    two = solve_twoscale(HS, s.asperities, h=h, total_load=W)
    ref = solve_reference(HS, surface_on(s.hmap.grid, s.asperities), total_load=W)
    _compare(two, ref, s.hmap.grid)
    d = two.penetration  # and under penetration control at that approach
    _compare(
        solve_twoscale(HS, s.asperities, h=h, penetration=d),
        solve_reference(HS, surface_on(s.hmap.grid, s.asperities), penetration=d),
        s.hmap.grid,
    )


def test_tilt_on_a_map():
    h = 0.1
    s = _surface(road(16.0, h, seed=3), h)
    two = solve_twoscale(HS, s.asperities, h=h, total_load=40.0, tilt=True, pivot=(1.0, -0.5))
    ref = solve_reference(HS, surface_on(s.hmap.grid, s.asperities), total_load=40.0, tilt=True, pivot=(1.0, -0.5))
    _compare(two, ref, s.hmap.grid)
    assert np.allclose(two.tilt, ref.tilt, rtol=0.01, atol=1e-6)


def test_laws_are_tabulated_only_where_pressed_and_cached(tmp_path):
    from twoscale.surface import LawCache

    h = 0.1
    z = road(16.0, h, seed=2)
    tab = SurfaceOptions(law="tabulated")
    s = build_surface(RawMap(z, h, "mm", None, "road"), tab, cache=LawCache(tmp_path))
    res = solve_twoscale(HS, s.asperities, h=h, total_load=5.0)  # a light load: the top stones only
    touched = int(np.count_nonzero(res.details.macro.local_penetrations > 0))
    assert res.converged and 0 < s.book.tabulated < len(s.asperities)
    assert s.book.tabulated >= touched
    again = build_surface(RawMap(z, h, "mm", None, "road"), tab, cache=LawCache(tmp_path))
    res2 = solve_twoscale(HS, again.asperities, h=h, total_load=5.0)
    assert again.book.tabulated == 0 and again.book.cache.hits == s.book.tabulated
    assert np.array_equal(res2.asperities.forces, res.asperities.forces)


def test_auto_law_tabulates_nothing_and_takes_the_cached_tables(tmp_path):
    # "auto" (the default): the equivalent sphere where no table is known, so a cold solve
    # tabulates nothing, and the answer is the micro step's on the true heights either way
    from twoscale.surface import LawCache

    h = 0.1
    z = road(16.0, h, seed=2)
    cold = build_surface(RawMap(z, h, "mm", None, "road"), SurfaceOptions(), cache=LawCache(tmp_path))
    res = solve_twoscale(HS, cold.asperities, h=h, total_load=5.0)
    assert res.converged and cold.book.tabulated == 0
    tab = build_surface(RawMap(z, h, "mm", None, "road"), SurfaceOptions(law="tabulated"), cache=LawCache(tmp_path))
    ref = solve_twoscale(HS, tab.asperities, h=h, total_load=5.0)
    assert tab.book.tabulated > 0
    np.testing.assert_allclose(res.asperities.forces, ref.asperities.forces, atol=2e-3 * ref.asperities.forces.max())
    # now cached: "auto" takes the tables (same macro forces as the tabulated run), computes none
    warm = build_surface(RawMap(z, h, "mm", None, "road"), SurfaceOptions(), cache=LawCache(tmp_path))
    res2 = solve_twoscale(HS, warm.asperities, h=h, total_load=5.0)
    assert warm.book.tabulated == 0 and warm.book.cache.hits > 0
    np.testing.assert_allclose(res2.details.macro.forces, ref.details.macro.forces, rtol=1e-9, atol=1e-12)


def test_far_field_on_a_road_keeps_every_stone_within_one_percent():
    """The policy's far-field coupling on map basins (the loads sit off the summits):
    forced here on a road small enough for the default run (the policy itself takes the
    far field from FAR_FIELD_MIN_PATCHES patches, as on benchmarks/surfaces.py's road)."""
    from twoscale.micro.policy import AUTO_FAR_TOL

    h = 0.1
    s = _surface(road(36.0, h, seed=1), h)  # the old resultant at each summit: 4.5 % on one stone
    W = 0.2 * 36.0 * 36.0
    two = solve_twoscale(HS, s.asperities, h=h, total_load=W, iteration="two-level", far_tol=AUTO_FAR_TOL)
    assert two.details.micro.attempts[-1].far_tol == AUTO_FAR_TOL
    ref = solve_reference(HS, surface_on(s.hmap.grid, s.asperities), total_load=W)
    _compare(two, ref, s.hmap.grid)
