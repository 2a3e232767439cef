"""The patches' set-up taken as arrays (thousands of tips): each helper against the one-grid,
one-tip route it replaces, to the bit."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from twoscale.grid import Grid, covering_grids, offsets_in
from twoscale.indenters import Asperity, Tilt
from twoscale.micro.patches import Patch, patch_radius
from twoscale.micro.sampling import box_of, patch_grids, shared_box
from twoscale.micro.workset import tip_approaches


def _tips(rng, n):
    shapes = rng.choice(["sphere", "paraboloid"], n)
    return [
        Asperity(float(x), float(y), float(z), float(R), str(s))
        for x, y, z, R, s in zip(
            rng.uniform(-3, 3, n), rng.uniform(-2, 4, n), rng.uniform(0, 0.05, n), rng.uniform(0.02, 2.0, n), shapes
        )
    ]


def test_covering_grids_are_grid_covering_of_each_box():
    rng = np.random.default_rng(3)
    xmin, ymin = rng.uniform(-5, 5, 500), rng.uniform(-5, 5, 500)
    xmax, ymax = xmin + rng.uniform(0, 2, 500), ymin + rng.uniform(0, 2, 500)
    xmax[:20] = xmin[:20]  # degenerate boxes: one cell
    for anchor, h in (((0.0, 0.0), 0.01), ((0.0031, -0.0017), 0.037)):
        many = covering_grids(xmin, xmax, ymin, ymax, h, anchor=anchor)
        one = [Grid.covering(*map(float, b), h, anchor=anchor) for b in zip(xmin, xmax, ymin, ymax)]
        assert many == one
        assert all(type(g.x0) is float and type(g.nx) is int for g in many)
    with pytest.raises(ValueError):
        covering_grids([math.nan], [1.0], [0.0], [1.0], 0.1)


def test_offsets_in_are_offset_in_of_each_grid():
    rng = np.random.default_rng(4)
    h, anchor = 0.013, (0.002, -0.004)
    parent = Grid.covering(-4, 4, -4, 4, h, anchor=anchor)
    lo = rng.uniform(-4, 3, (300, 2))
    grids = [Grid.covering(x, x + 0.5, y, y + 0.3, h, anchor=anchor) for x, y in lo]
    di, dj = offsets_in(grids, parent)
    assert list(zip(di.tolist(), dj.tolist())) == [g.offset_in(parent) for g in grids]
    shifted = grids[:5] + [dataclasses.replace(grids[5], x0=grids[5].x0 + 0.4 * h)]
    with pytest.raises(ValueError, match="aligned"):
        offsets_in(shifted, parent)
    with pytest.raises(ValueError, match="cell sizes"):
        offsets_in(grids[:3] + [dataclasses.replace(grids[3], h=1.01 * h)], parent)


def test_box_of_is_the_box_of_the_grids_bounds():
    rng = np.random.default_rng(5)
    h, anchor = 0.021, (0.001, 0.003)
    grids = [Grid.covering(x, x + w, y, y + w, h, anchor=anchor) for x, y, w in rng.uniform(0, 3, (400, 3))]
    b = np.array([g.bounds for g in grids])  # the bounds one grid at a time
    xmin, xmax, ymin, ymax = b[:, 0].min(), b[:, 1].max(), b[:, 2].min(), b[:, 3].max()
    cx, cy, rx, ry = (xmin + xmax) / 2, (ymin + ymax) / 2, (xmax - xmin) / 2, (ymax - ymin) / 2
    for grow in (1.0, 1.3):
        want = Grid.covering(cx - grow * rx, cx + grow * rx, cy - grow * ry, cy + grow * ry, h, anchor=anchor)
        assert box_of(grids, h, anchor, grow=grow) == want


def test_patch_grids_are_each_tips_radius_and_covering():
    rng = np.random.default_rng(6)
    tips = _tips(rng, 600)
    forces = rng.uniform(0, 3, 600)
    forces[::7], forces[1::11], forces[2::13] = 0.0, np.inf, np.nan
    approaches = rng.uniform(-0.01, 0.08, 600)
    approaches[::17] = 5.0  # deeper than a sphere's radius
    h, anchor, E = 0.011, (0.0004, 0.0007), 3.7
    got = patch_grids(tips, h=h, forces=forces, approaches=approaches, E_star=E, margin=1.3, anchor=anchor)
    want = []
    for k, a in enumerate(tips):
        if approaches[k] <= 0.0:
            continue
        r = patch_radius(a, force=float(forces[k]), approach=float(approaches[k]), E_star=E, h=h, margin=1.3)
        want.append((k, Grid.covering(a.x - r, a.x + r, a.y - r, a.y + r, h, anchor=anchor)))
    assert got == want and len(got) < 600


def test_tip_approaches_are_each_tips():
    rng = np.random.default_rng(7)
    tips = _tips(rng, 200)
    theta, pivot = (0.03, 1e-3, -2e-3), (0.4, -0.2)
    tilt = Tilt(theta[1], theta[2], pivot)
    want = [theta[0] - a.z - float(tilt.height(a.x, a.y)) for a in tips]
    assert tip_approaches(tips, theta, pivot).tolist() == want


def test_shared_box_refuses_a_window_of_the_box_at_another_place():
    # every patch a window of one array, but one of them a cell away from its grid's place
    h = 0.125  # a binary fraction: the box of the windows is the box itself, no rounding
    box = Grid.covering(0.0, 2.5, 0.0, 1.25, h)
    height, owner = np.zeros(box.shape), np.zeros(box.shape, dtype=np.int64)
    grids = [box.subgrid(0, 0, 6, 5), box.subgrid(10, 3, 11, 8), box.subgrid(4, 2, 5, 4)]

    def cut(g, shift=0):
        di, dj = g.offset_in(box)
        win = (slice(dj, dj + g.ny), slice(di + shift, di + shift + g.nx))
        return Patch(0, g, height[win], owner[win])

    assert shared_box([cut(g) for g in grids], 1, (0.0, 0.0)) is not None
    assert shared_box([cut(g) for g in grids[:2]] + [cut(grids[2], 1)], 1, (0.0, 0.0)) is None
    strided = Patch(0, grids[0], height[:10:2, :6], owner[:5, :6])
    assert shared_box([strided] + [cut(g) for g in grids[1:]], 1, (0.0, 0.0)) is None


def test_detached_patches_own_their_cells_and_let_the_sampled_box_go():
    import gc
    import weakref

    from twoscale.micro.sampling import detached, patches_cut_from_box

    h = 0.125
    tips = [Asperity(0.3, 0.3, 0.0, 1.0), Asperity(2.2, 1.0, 0.01, 1.5, shape="paraboloid")]
    box = Grid.covering(0.0, 2.5, 0.0, 1.25, h)
    grids = [box.subgrid(0, 0, 6, 5), box.subgrid(12, 3, 8, 6)]
    cut = patches_cut_from_box(list(zip([0, 1], grids)), box, tips)
    sampled = weakref.ref(cut[0].height.base)
    assert cut[1].height.base is sampled() and sampled().shape == box.shape  # windows of one box
    own = detached(cut)
    for a, b in zip(cut, own):
        assert (b.asperity, b.grid, b.members) == (a.asperity, a.grid, a.members)
        assert np.array_equal(b.height, a.height) and np.array_equal(b.owner, a.owner)
        assert np.array_equal(b.owned, a.owned)
        assert b.height.base is None and b.owner.base is None and not b.height.flags.writeable
    del cut, a  # the last window seen
    gc.collect()
    assert sampled() is None  # nothing of the detached patches holds the box
    assert detached(own)[0] is own[0]  # already their own: the same patches


def test_patches_reused_as_they_are_or_cut_down_else_built():
    # a patch of the same asperity and grid is taken as it is; one on a larger grid is cut
    # down to the wanted grid; the others are built: every one the patch made afresh
    from twoscale.micro.patches import make_patch
    from twoscale.micro.sampling import sampled_patches

    rng = np.random.default_rng(8)
    tips = [Asperity(float(x), float(y), 0.0, 1.0) for x, y in rng.uniform(-1.0, 1.0, (6, 2))]
    h = 0.02
    wanted = [(k, Grid.covering(a.x - 0.1, a.x + 0.1, a.y - 0.1, a.y + 0.1, h)) for k, a in enumerate(tips)]
    larger = make_patch(1, Grid.covering(tips[1].x - 0.2, tips[1].x + 0.2, tips[1].y - 0.2, tips[1].y + 0.2, h), tips)
    same = make_patch(0, wanted[0][1], tips)
    out = sampled_patches(tips, wanted, h=h, reuse=[same, larger], box_share=math.inf)
    assert out[0] is same and np.shares_memory(out[1].height, larger.height)
    for pt, (k, grid) in zip(out, wanted):
        fresh = make_patch(k, grid, tips)
        assert pt.asperity == k and pt.grid == grid
        assert np.array_equal(pt.owner, fresh.owner)
        # the cut patch's heights at the larger grid's cell centres (x0 + i h): rounding only
        assert np.allclose(pt.height, fresh.height, rtol=0.0, atol=1e-15 if k == 1 else 0.0)


def test_a_low_share_samples_the_box_once_only_where_it_has_few_cells_a_patch(monkeypatch):
    # patches on 9 % of their box: under the share, over the low share; their box is sampled
    # once (and they are its windows) where it has at most LOW_SHARE_CELLS_PER_PATCH cells a
    # patch, else they are built one by one; the same cells and owners either way
    import twoscale.micro.sampling as sampling
    from twoscale.micro.patches import make_patch

    h = 0.02
    tips = [Asperity(float(x), float(y), 0.0, 1.0) for x in np.arange(6) for y in np.arange(6)]
    wanted = [(k, Grid.covering(a.x - 0.1, a.x + 0.1, a.y - 0.1, a.y + 0.1, h)) for k, a in enumerate(tips)]
    box = sampling.box_of([g for _, g in wanted], h, (0.0, 0.0))
    share = sum(g.size for _, g in wanted) / box.size
    per_patch = box.size / len(wanted)
    assert 0.05 < share < 0.1 and sampling.BOX_CELLS_PER_PATCH < per_patch
    cuts = []
    cut = sampling.patches_cut_from_box
    monkeypatch.setattr(sampling, "patches_cut_from_box", lambda *a: cuts.append(a[1].size) or cut(*a))
    assert sampling.LOW_SHARE_CELLS_PER_PATCH < per_patch  # too many cells a patch: one by one
    apart = sampling.sampled_patches(tips, wanted, h=h, box_share=0.2, low_share=0.05)
    assert cuts == []
    monkeypatch.setattr(sampling, "LOW_SHARE_CELLS_PER_PATCH", 2.0 * per_patch)
    once = sampling.sampled_patches(tips, wanted, h=h, box_share=0.2, low_share=0.05)
    assert cuts == [box.size] and once[0].height.base is once[1].height.base
    sampling.sampled_patches(tips, wanted, h=h, box_share=0.2, low_share=0.1)  # over their share
    assert cuts == [box.size]
    for a, b, (k, grid) in zip(once, apart, wanted):
        fresh = make_patch(k, grid, tips)
        assert (
            a.grid == b.grid == grid and np.array_equal(a.owner, fresh.owner) and np.array_equal(b.owner, fresh.owner)
        )
        assert np.allclose(a.height, fresh.height, rtol=0.0, atol=1e-12) and np.array_equal(b.height, fresh.height)
