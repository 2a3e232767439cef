"""The reference solver's grid is sampled by the union box's sampler (tiles, windows or
every cell, whichever is cheaper), with the heights and owners of every indenter
evaluated on every cell, bit for bit, so its answers are those of the plain sampling."""

from __future__ import annotations

import numpy as np
from helpers import every_tip_on_every_cell
import pytest

from twoscale import Material, Scene
from twoscale.grid import Grid
from twoscale.indenters import Asperity
from twoscale.influence import HalfSpace
from twoscale.micro import sampling
from twoscale.reference import solve_reference
from twoscale.reference.on_scene import reference_grid, solve_reference_scene


def _crowd(n, seed=2):
    """``n`` spheres and paraboloids packed about 0.3 mm apart on a square."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    xy = 0.3 * np.stack(np.divmod(np.arange(n), side), axis=1) + rng.uniform(-0.05, 0.05, (n, 2))
    shapes = np.where(rng.random(n) < 0.7, "sphere", "paraboloid")
    return [
        Asperity(float(x), float(y), float(z), float(R), str(s))
        for (x, y), z, R, s in zip(xy, rng.uniform(0, 0.01, n), rng.uniform(0.5, 2.0, n), shapes)
    ]


def test_a_small_grid_crowded_with_tips_is_sampled_by_tiles_asevery_tip_on_every_cell(monkeypatch):
    asps = _crowd(400)
    grid = Grid.covering(-0.2, 6.2, -0.2, 6.2, 0.02)  # 102,400 cells
    monkeypatch.setattr(sampling, "SAMPLE_WHOLE_CELLS", 200_000)
    assert grid.size <= sampling.SAMPLE_WHOLE_CELLS
    assert grid.size * len(asps) > sampling.SAMPLE_WHOLE_ENTRIES  # not sampled whole
    calls = []
    monkeypatch.setattr(sampling, "surface_on", lambda *a, **k: calls.append(1))
    s = sampling.box_surface(grid, asps, whole_cells=sampling.SAMPLE_WHOLE_CELLS)
    assert not calls
    height, owner = every_tip_on_every_cell(grid, asps)
    assert np.array_equal(s.owner, owner)
    assert np.array_equal(s.height, height)


@pytest.mark.parametrize("control", ["penetration", "load"])
def test_the_reference_on_a_crowded_scene_equals_its_solve_on_every_tip_sampled_on_every_cell(control):
    asps = _crowd(120, seed=5)
    material = Material(E=10.0, nu=0.5)
    load = {"penetration": 0.004} if control == "penetration" else {"total_load": 0.5}
    scene = Scene(asperities=tuple(asps), material=material, **load)
    provider = HalfSpace(material)
    h = 0.02
    got = solve_reference_scene(scene, provider, h)
    grid = reference_grid(scene, h)
    height, owner = every_tip_on_every_cell(grid, asps)
    from twoscale.indenters import Surface

    want = solve_reference(provider, Surface(grid, height, owner, len(asps)), **load)
    assert got.converged and want.converged
    np.testing.assert_array_equal(got.forces, want.forces)
