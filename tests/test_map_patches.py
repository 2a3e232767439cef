"""A height map's patches cut from one sampled box, and the map's bookkeeping around the
solve (the basins' passes, their samples, the per-asperity sums), each against a direct
computation: the patches one by one, every pair of neighbouring samples, every label, every
owned cell."""

from __future__ import annotations

import numpy as np

from twoscale.grid import Grid
from twoscale.indenters import Asperity, surface_on
from twoscale.micro.patches import make_patch
from twoscale.micro.sampling import build_patches, one_map, shared_box
from twoscale.results import PressureField, summarise
from twoscale.surface import RawMap, SurfaceOptions, build_surface
from twoscale.surface.segmentation import _candidates, _passes, _watershed
from twoscale.surface.sphere_fit import basin_cells
from twoscale.surface.texture import road


def _road(size: float, seed: int, h: float = 0.1):
    return build_surface(RawMap(road(size, h, seed=seed), h, "mm", None, "road"), SurfaceOptions())


def test_a_maps_patches_are_windows_of_one_box_equal_to_the_patches_made_one_by_one():
    surface = _road(16.0, 3)
    asps = surface.asperities
    assert one_map(asps) and not one_map(asps + (Asperity(0.0, 0.0, 1.0, 5.0),))
    z = np.array([a.z for a in asps])
    approaches = 0.15 - z  # the stones within 0.15 mm of the highest one touch
    forces = np.where(approaches > 0, 2.0, 0.0)
    patches = build_patches(asps, h=0.1, forces=forces, approaches=approaches, E_star=13.3, anchor=(0.0, 0.0))
    assert 3 <= len(patches) < len(asps)
    for pt in patches:  # the route of any other scene: every patch sampled on its own
        own = make_patch(pt.asperity, pt.grid, asps)
        assert np.array_equal(pt.height, own.height) and np.array_equal(pt.owner, own.owner)
    # sampled once: the union CG takes the same box instead of sampling it again
    box = shared_box(patches, len(asps), (0.0, 0.0))
    assert box is not None
    again = surface_on(box.grid, asps)
    assert np.array_equal(box.height, again.height) and np.array_equal(box.owner, again.owner)


def test_passes_are_the_highest_of_every_pair_of_neighbouring_samples_across_two_basins():
    z = road(10.0, 0.2, seed=5, stone_radius=(1.5, 3.0))
    basins = _watershed(z, _candidates(z, 5.0))
    assert basins.max() >= 3
    direct: dict = {}
    ny, nx = z.shape
    for j in range(ny):
        for i in range(nx):
            for dj, di in ((0, 1), (1, 0), (1, 1), (1, -1)):
                jj, ii = j + dj, i + di
                if 0 <= jj < ny and 0 <= ii < nx and basins[j, i] != basins[jj, ii]:
                    a, b = sorted((int(basins[j, i]), int(basins[jj, ii])))
                    level = min(z[j, i], z[jj, ii])
                    direct[(a, b)] = max(direct.get((a, b), -np.inf), level)
    a, b, level = _passes(z, basins)
    assert sorted(direct) == list(zip(a.tolist(), b.tolist()))
    assert np.array_equal(level, np.array([direct[k] for k in sorted(direct)]))


def test_basin_cells_are_every_sample_of_each_label_in_raster_order():
    seg = _road(12.0, 4).segmentation
    cells = basin_cells(seg)
    flat = seg.labels.ravel()
    assert len(cells) == len(seg)
    for k, c in enumerate(cells):
        assert np.array_equal(c, np.flatnonzero(flat == k))


def test_asperity_sums_count_every_owned_cell_and_only_those():
    rng = np.random.default_rng(7)
    grid = Grid(0.0, 0.0, 0.1, 40, 30)
    owner = rng.integers(-1, 6, size=grid.shape)
    pressure = np.where(rng.random(grid.shape) < 0.3, rng.random(grid.shape), 0.0)
    pressure[owner == 4] = 0.0  # an asperity that carries nothing
    s = summarise((PressureField(grid, pressure, owner, np.zeros(grid.shape)),), 7)
    cell = grid.h**2
    for k in range(7):
        mine = pressure[owner == k]
        assert np.isclose(s.forces[k], cell * mine.sum(), rtol=1e-14, atol=0.0)
        assert s.contact_areas[k] == cell * np.count_nonzero(mine > 0)
        assert s.max_pressures[k] == (mine.max() if mine.size else 0.0)
    assert s.forces[4] == s.contact_areas[4] == s.max_pressures[4] == 0.0
