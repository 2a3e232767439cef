"""A free tilt about a pivot off the tips: refused where no tilt balances the moments, solved
on the full grid where the contact leaves the apexes' patches."""

from __future__ import annotations

import math

import numpy as np
import pytest

import twoscale
from twoscale import Asperity, Material
from twoscale.cli.main import main
from twoscale.pivot import hull_distance, pivot_route
from twoscale.scene import Scene, SceneError

# three paraboloids, a thin triangle: a pivot a little to the right of its long edge
TIPS = (
    Asperity(-1.509, -5.681, 0.0038, 9.2, "paraboloid"),
    Asperity(-3.89, -6.74, 0.0064, 8.27, "paraboloid"),
    Asperity(-0.58, -10.43, 0.0034, 8.19, "paraboloid"),
)
MATERIAL = Material(9.4, 0.5)
LOAD = 0.162
H = 0.04


def _off_edge(distance: float) -> tuple[float, float]:
    """The point ``distance`` mm outside the triangle's edge from tip 1 to tip 3, at its middle."""
    a, b = np.array([TIPS[0].x, TIPS[0].y]), np.array([TIPS[2].x, TIPS[2].y])
    t = (b - a) / np.linalg.norm(b - a)
    n = np.array([-t[1], t[0]])
    n = n if n[0] > 0 else -n  # away from tip 2
    p = 0.5 * (a + b) + distance * n
    return float(p[0]), float(p[1])


@pytest.mark.parametrize(
    ("points", "p", "expected"),
    [
        ([(0, 0), (1, 0), (1, 1), (0, 1)], (3.0, 0.5), 2.0),  # beside a side
        ([(0, 0), (1, 0), (1, 1), (0, 1)], (4.0, 5.0), 5.0),  # off a corner: 3-4-5
        ([(0, 0), (1, 0), (1, 1), (0, 1)], (0.3, 0.6), 0.0),  # inside
        ([(0, 0), (2, 2), (1, 1)], (2.0, 0.0), math.sqrt(2.0)),  # collinear: a segment
        ([(1, 1)], (4.0, 5.0), 5.0),  # one point
    ],
)
def test_hull_distance_against_plane_geometry(points, p, expected):
    assert hull_distance(np.array(points, dtype=float), p) == pytest.approx(expected, abs=1e-6)


def test_pivot_outside_all_material_is_refused_before_solving(tmp_path):
    with pytest.raises(SceneError, match=r"load\.pivot = \[.*outside every place the tips have material"):
        twoscale.solve(TIPS, total_load=LOAD, tilt=True, pivot=_off_edge(5.0), material=MATERIAL, h=H)


def test_a_pivot_inside_the_spheres_discs_but_beyond_the_loads_reach_is_refused_saying_so():
    # the spheres' material reaches y = -15 mm, so a pivot at y = -14.5 is among it; the
    # contacts this load can make end near y = -13: the refusal must say it is the reach,
    # not the material, that the pivot lies outside (it said "every place the tips have material")
    tips = twoscale.asperities([-10.0, 10.0, 0.0], [-10.0, -10.0, 10.0], 5.0)
    with pytest.raises(SceneError, match="outside every place the tips have material within the reach of the load"):
        twoscale.solve(tips, material=Material(6.0, 0.5), total_load=20.0, tilt=True, pivot=(0.0, -14.5))


def test_pivot_outside_is_exit_2_one_line_and_nothing_written(write_scene, tmp_path, capsys):
    px, py = _off_edge(5.0)
    tips = "".join(f"[[asperity]]\nx = {a.x}\ny = {a.y}\nz = {a.z}\nR = {a.R}\nshape = 'paraboloid'\n" for a in TIPS)
    text = f"[material]\nE = 9.4\nnu = 0.5\n[load]\ntotal = {LOAD}\ntilt = true\npivot = [{px}, {py}]\n{tips}"
    out = tmp_path / "out"
    assert main(["solve", str(write_scene(text)), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "load.pivot" in err
    assert not out.exists()


def test_pivot_inside_the_tips_keeps_the_two_scale_route():
    scene = Scene(material=MATERIAL, asperities=TIPS, total_load=LOAD, tilt=True, pivot=_off_edge(-0.3))
    assert pivot_route(scene) is None


@pytest.mark.parametrize(("distance", "route"), [(0.2, "two-scale"), (0.9, "full grid")])
def test_pivot_off_the_tips_balances_the_moments(distance, route):
    """Within a contact radius (~0.32 mm here) of the tips' hull the two-scale patches hold
    the contact; farther, the contact sits on the flanks and the default answers with the
    full grid, saying so. Either way the pressure's centre lies on the pivot."""
    pivot = _off_edge(distance)
    scene = Scene(material=MATERIAL, asperities=TIPS, total_load=LOAD, tilt=True, pivot=pivot)
    assert (pivot_route(scene) is not None) == (route == "full grid")
    res = twoscale.solve(TIPS, total_load=LOAD, tilt=True, pivot=pivot, material=MATERIAL, h=H)
    assert res.converged
    assert ("default route: the pivot lies" in res.message) == (route == "full grid")
    assert res.total_load == pytest.approx(LOAD, rel=1e-6)
    force = moment_x = moment_y = 0.0
    for field in res.fields:
        X, Y = field.grid.centres()
        w = field.pressure * field.grid.h**2
        force, moment_x, moment_y = force + w.sum(), moment_x + (w * X).sum(), moment_y + (w * Y).sum()
    # the moment arm left is below half a cell: the pressure's centre on the pivot
    assert math.dist((moment_x / force, moment_y / force), pivot) < 0.5 * H


def _square_slope(slope: float) -> tuple:
    """Four equal spheres on a 20 mm square whose heights rise by ``slope`` along x: the face
    balances them by turning ``beta = -slope`` (``delta_k = d - z_k - beta x_k - alpha y_k``
    with equal forces, by symmetry), ``alpha = 0``."""
    return tuple(Asperity(x, y, slope * x, 5.0) for x in (-10.0, 10.0) for y in (-10.0, 10.0))


@pytest.mark.parametrize("slope, warned", [(0.02, False), (0.2, True)])
def test_a_face_set_askew_tilts_level_and_large_tilts_are_warned(slope, warned):
    """From no tilt only the two low tips touch, on one side of the pivot: the macro step
    stalled and the solve was refused. The levelled start balances it; the forces are the
    full-grid reference's, and only the angle beyond small angles is warned about."""
    import warnings

    from twoscale.errors import TiltWarning

    tips, material = _square_slope(slope), Material(10.0, 0.5)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = twoscale.solve(tips, material=material, total_load=4.0, tilt=True, h=0.05)
    alpha, beta = res.tilt
    assert res.converged, res.message
    assert abs(beta + slope) < 0.05 * slope and abs(alpha) < 0.05 * slope
    tilt_warnings = [w for w in caught if issubclass(w.category, TiltWarning)]
    assert len(tilt_warnings) == int(warned)
    if warned:
        assert f"beta {beta:.3g}" in str(tilt_warnings[0].message) and "load.pivot" in str(tilt_warnings[0].message)
    else:
        ref = twoscale.solve(tips, material=material, total_load=4.0, tilt=True, h=0.05, method="reference")
        assert np.allclose(res.forces, ref.forces, rtol=0.005, atol=0)
        assert abs(res.tilt[1] - ref.tilt[1]) < 0.005 * slope


@pytest.mark.parametrize("slope, warned", [(0.02, False), (0.2, True)])
def test_a_load_history_warns_of_a_large_tilt_as_one_load_does(slope, warned):
    """A load history's tilt was never checked against the small angles. Elastic here (a
    sequence of elastic solves): by symmetry the face turns by beta = -slope at every load.
    The full-grid reference: the two-scale steps of the 0.2 slope end in NaN (not solved here)."""
    import warnings

    from twoscale.errors import TiltWarning

    steps = twoscale.TimeSteps(count=2)
    history = twoscale.LoadHistory("total", ((0.0, 0.0), (1.0, 4.0)), output=(0.5, 1.0), steps=steps)
    scene = Scene(material=Material(10.0, 0.5), asperities=_square_slope(slope), tilt=True, h=0.1, history=history)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = twoscale.solve(scene, method="reference")
    assert res.converged, res.message
    assert np.all(np.abs(res.tilt[:, 1] + slope) < 0.05 * slope)
    assert sum(issubclass(w.category, TiltWarning) for w in caught) == int(warned)
