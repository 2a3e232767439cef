"""The cells the two-level rounds' stop tests read (:mod:`twoscale.micro.stop_cells`).

Checks: on patches of tips in a row (some contacts touching, some apart, one asperity
without a patch, a merged patch) and on random pressures, the kept cells answer what
:func:`~twoscale.micro.patches.edges_loaded` and :func:`~twoscale.micro.touching.touching_groups`
answer on the whole patches (which patches reach an edge; the same groups from the patches
the kept cells name); the kept cells follow a replaced patch.
"""

import numpy as np

from twoscale.grid import Grid
from twoscale.micro.blocks import scatter
from twoscale.micro.patches import edges_loaded, make_patch, merge_groups
from twoscale.micro.stop_cells import StopCells
from twoscale.micro.touching import touching_groups
from helpers import disc_on_patch, patches_on_x

H = 0.02


def _scene(tips):
    return patches_on_x(tips, H, 0.3, (-0.2, 0.25))


def test_the_kept_cells_answer_as_the_whole_patches():
    rng = np.random.default_rng(3)
    tips = [0.0, 0.05, 0.5, 1.4, 1.47, 2.6]
    asps, patches = _scene(tips)
    merged, _ = merge_groups(patches, asps, [[0], [1], [2], [3, 4], [5]])
    cases = [patches, patches[:5], merged]  # all apart or not; tip 5 without a patch; a merged pair
    seen = {"touch": set(), "edge": set()}
    for pts in cases:
        stop = StopCells(len(asps))
        for trial in range(40):
            radius = rng.uniform(0.005, 0.35)
            p = []
            for pt in pts:
                centre = asps[pt.members[0]].x + rng.uniform(-0.05, 0.05)
                v = disc_on_patch(pt, centre, radius) * rng.uniform(0.0, 2.0, int(pt.owned.sum()))
                v[rng.random(v.size) < 0.2] = 0.0
                p.append(v if trial % 5 else -v)  # all pressures below zero now and then
            touch = len(touching_groups(pts, p)) < len(pts)
            edge = any(any(edges_loaded(pt, scatter(pt, v))) for pt, v in zip(pts, p))
            assert stop.may_touch(pts, p) == touch
            assert stop.any_edge(pts, p) == edge
            # only the patches loaded near another's cells link: the same groups from them
            assert touching_groups(pts, p, only=stop.loaded_touch(pts, p)) == touching_groups(pts, p)
            loaded = [k for k, (pt, v) in enumerate(zip(pts, p)) if any(edges_loaded(pt, scatter(pt, v)))]
            assert stop.loaded_edges(pts, p) == loaded
            for pt, v in zip(pts, p):
                assert StopCells.sides(pt, v) == edges_loaded(pt, scatter(pt, v))
            seen["touch"].add(touch)
            seen["edge"].add(edge)
    assert seen == {"touch": {True, False}, "edge": {True, False}}  # both answers taken


def test_the_kept_cells_follow_a_replaced_patch():
    asps, patches = _scene([0.0, 1.0])
    stop = StopCells(len(asps))
    p = [disc_on_patch(pt, x, 0.1) for pt, x in zip(patches, [0.0, 1.0])]
    assert not stop.any_edge(patches, p)
    # the second patch cut to a grid whose right edge runs through its contact
    small = make_patch(1, Grid.covering(0.9, 1.0, -0.2, 0.25, H), asps)
    q = [p[0], disc_on_patch(small, 1.0, 0.1)]
    assert stop.any_edge([patches[0], small], q)
    assert stop.any_edge([patches[0], small], q) == any(edges_loaded(small, scatter(small, q[1])))
