"""Merging overlapping patches into one block (close and merged contacts).

Independent checks: the merge criterion (a merged grid has at most ``growth`` times the
cells of its members' grids) is recounted here from the grids; the merged solve is compared with the paper's one
block per asperity and with the reference solver on the same lattice.
"""

import math

import numpy as np
import pytest

from twoscale import Grid, Material
from twoscale.indenters import Asperity
from twoscale.influence import HalfSpace
from twoscale.micro.patches import make_patch, merge_overlapping
from twoscale.reference import solve_cg
from twoscale.paper import paper_case, reference_surface
from twoscale.driver import solve_twoscale

MAT = Material(10.0, 0.5)
HS = HalfSpace(MAT)
H = 0.25


def _ring(spacing, half, centre_half):
    """A centre tip and six on a hexagon of radius ``spacing`` (a vertex on top), square
    patches of half-width ``half`` (``centre_half`` for the centre, which its neighbours
    shield: the paper's seven spheres at d/2R = 0.3 give 3.0 and 3.75 mm at spacing 6 mm)."""
    tips = [(0.0, 0.0)] + [
        (spacing * math.cos(k * math.pi / 3 + math.pi / 2), spacing * math.sin(k * math.pi / 3 + math.pi / 2))
        for k in range(6)
    ]
    asps = [Asperity(x, y, 0.0, 10.0) for x, y in tips]
    halves = [centre_half] + [half] * 6
    patches = [
        make_patch(k, Grid.covering(x - r + 1e-9, x + r - 1e-9, y - r + 1e-9, y + r - 1e-9, H), asps)
        for k, ((x, y), r) in enumerate(zip(tips, halves))
    ]
    return asps, patches


def _union_cells(grids):
    big = Grid.covering(-50, 50, -50, 50, H)
    boxes = []
    for g in grids:
        di, dj = g.offset_in(big)
        boxes.append((di, di + g.nx, dj, dj + g.ny))
    b = np.array(boxes)
    return (b[:, 1].max() - b[:, 0].min()) * (b[:, 3].max() - b[:, 2].min())


def test_ring_merges_as_a_whole_though_the_centre_pairs_with_no_neighbour():
    asps, patches = _ring(6.0, 3.75, 3.0)
    # the centre and any one neighbour alone do not fit one grid of no more cells
    c = patches[0].grid
    for j in range(1, 7):
        assert _union_cells([c, patches[j].grid]) > c.size + patches[j].grid.size
    # all seven do
    assert _union_cells([pt.grid for pt in patches]) <= sum(pt.grid.size for pt in patches)
    merged, covers = merge_overlapping(patches, asps)
    assert len(merged) == 1 and merged[0].members == tuple(range(7)) and covers == [tuple(range(7))]


def test_far_patches_stay_one_per_asperity():
    asps, patches = _ring(10.0, 3.6, 3.6)
    merged, covers = merge_overlapping(patches, asps)
    assert [pt.members for pt in merged] == [(k,) for k in range(7)]
    assert all(m is p for m, p in zip(merged, patches))


@pytest.mark.parametrize("growth", [1.0, 1.5, 2.0, 3.0])
def test_growth_bounds_the_merged_grid(growth):
    asps, patches = _ring(10.0, 3.6, 3.6)
    total = _union_cells([pt.grid for pt in patches]) / sum(pt.grid.size for pt in patches)
    assert 1.5 < total < 2.0  # the ring of spacing 10 mm: all seven fit a grid 1.5-2x theirs
    merged, covers = merge_overlapping(patches, asps, growth=growth)
    for m, c in zip(merged, covers):
        assert m.grid.size <= growth * sum(patches[i].grid.size for i in c)
    assert (len(merged) == 1) == (growth >= total)
    with pytest.raises(ValueError, match="growth"):
        merge_overlapping(patches, asps, growth=0.5)


def test_merged_block_is_the_union_of_the_members_owned_cells():
    asps, patches = _ring(6.0, 3.75, 3.0)
    (m,), _ = merge_overlapping(patches, asps)
    assert m.grid.size <= sum(pt.grid.size for pt in patches)
    count = np.zeros(m.grid.shape, int)
    for pt in patches:
        di, dj = pt.grid.offset_in(m.grid)
        window = m.owned[dj : dj + pt.grid.ny, di : di + pt.grid.nx]
        # every cell a member owned on its own patch is in the merged block
        assert np.all(window[pt.owned])
        count[dj : dj + pt.grid.ny, di : di + pt.grid.nx] += pt.owned
    # and the block holds nothing else: cells nobody owned on a patch are owned by nobody
    # (no indenter reaches them) or lie outside every member patch
    assert np.all(m.owned[count > 0])
    assert np.all(m.owner[m.owned] >= 0)


def test_patch_members_must_start_with_its_asperity():
    asps, patches = _ring(6.0, 3.75, 3.0)
    pt = patches[0]
    with pytest.raises(ValueError, match="members"):
        make_patch(1, pt.grid, asps, (0, 1))


@pytest.mark.parametrize("layout,spacing", [("two", 0.1), ("seven", 0.3), ("seven", 0.5)])
def test_merged_solve_matches_one_block_per_asperity_and_the_reference(layout, spacing):
    case = paper_case(layout, spacing)
    kw = dict(h=case.h, penetration=case.penetration, tol=1e-8, iteration="block-gs")
    merged = solve_twoscale(HS, case.asperities, **kw)
    paper = solve_twoscale(HS, case.asperities, merge=False, **kw)
    assert merged.converged and paper.converged
    n = len(case.asperities)
    assert merged.details.micro.merged_patches == (tuple(range(n)),)
    assert paper.details.micro.merged_patches == ()
    # fewer sweeps: the strong interaction is inside the block
    assert merged.iterations["micro"] < paper.iterations["micro"]
    surf = reference_surface(case)
    ref = solve_cg(HS, surf, penetration=case.penetration)
    pr = ref.pressure_on(surf.grid)
    for res in (merged, paper):
        p = res.pressure_on(surf.grid)
        assert np.linalg.norm(p - pr) <= 1e-5 * np.linalg.norm(pr)
        np.testing.assert_allclose(res.asperities.forces, ref.asperities.forces, rtol=1e-5)
    # eq. 7 is per asperity either way: the same p0 distance (Fig. 6)
    assert merged.details.micro.p0_change_percent == pytest.approx(paper.details.micro.p0_change_percent, rel=1e-3)


def test_result_json_names_the_merged_asperities_from_one():
    from twoscale.io.result_json import result_to_dict
    from twoscale.scene import Scene

    # a merged pair (tips 0.6 mm apart, contact radius ~1 mm) and a far sphere
    # (mirror-symmetric about x = 0.05, between two cell columns, so ownership has no ties)
    asps = [Asperity(-0.25, 0.0, 0.0, 5.0), Asperity(0.35, 0.0, 0.0, 5.0), Asperity(0.05, 12.0, 0.0, 5.0)]
    res = solve_twoscale(HS, asps, h=0.1, penetration=0.2, iteration="block-gs")
    assert res.converged and res.details.micro.merged_patches == ((0, 1),)
    scene = Scene(material=MAT, asperities=asps, penetration=0.2, h=0.1)
    assert result_to_dict(res, scene)["merged_patches"] == [[1, 2]]
    # the merged block still reports one force per asperity, the pair's equal by symmetry
    f = res.asperities.forces
    assert f[0] == pytest.approx(f[1], rel=1e-6) and f[2] > f[0]


def test_patches_marked_as_carrying_nothing_stay_alone():
    asps, patches = _ring(6.0, 3.75, 3.0)
    carries = [True] * 7
    carries[3] = False
    merged, covers = merge_overlapping(patches, asps, growth=2.0, carries=carries)
    assert (3,) in covers and merged[covers.index((3,))] is patches[3]
    assert all(3 not in c for c in covers if len(c) > 1)
    assert sorted(i for c in covers for i in c) == list(range(7))


@pytest.mark.parametrize(
    "third",
    [
        Asperity(-0.25, 0.05, 0.1, 5.0),  # inside tip 0's patch, owning no cell
        Asperity(0.05, 1.5, 0.15, 5.0),  # beside the pair, shielded: no eq. 7 pressure
    ],
)
def test_a_tip_carrying_nothing_is_not_merged_and_the_answer_is_unchanged(third):
    # a merged pair and a third tip whose patch meets theirs but carries nothing
    asps = [Asperity(-0.25, 0.0, 0.0, 5.0), Asperity(0.35, 0.0, 0.0, 5.0), third]
    kw = dict(h=0.1, penetration=0.2, tol=1e-9, iteration="block-gs")
    merged = solve_twoscale(HS, asps, **kw)
    alone = solve_twoscale(HS, asps, merge=False, **kw)
    assert merged.converged and alone.converged
    assert merged.details.micro.merged_patches == ((0, 1),)
    f, g = merged.asperities.forces, alone.asperities.forces
    assert f[2] == 0.0 and g[2] == 0.0
    np.testing.assert_allclose(f, g, rtol=1e-7, atol=1e-7 * g.max())
