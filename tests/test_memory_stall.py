"""What the memory estimate counts beyond the route it expects (twoscale.memory_stall,
twoscale.memory_parts): the level of the neighbours' mean push under load control against
its closed form on two tips; on clustered spheres under load, the patches a stalled macro
step leaves (sized by the micro step's own rule from the macro step's answer) against what
the estimate counts; the union CG's coarse correction's near pairs against its count."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from twoscale import Material
from twoscale.analytic import hertz
from twoscale.control import Loading
from twoscale.indenters import Asperity
from twoscale.influence.precorrected import Precorrected
from twoscale.laws import law_for
from twoscale.macro import solve_macro
from twoscale.mean_field import mean_field
from twoscale.memory_costs import BASE_BYTES, COARSE_BYTES_PER_LOADED_CELL_AND_FILL, PATCH_BYTES_PER_CELL
from twoscale.memory_costs import REACH_PATCH_HELD
from twoscale.memory_stall import SIZING_SHARE
from twoscale.micro.sampling import patch_grids
from twoscale.pk.coarse import MAX_FILL, PRODUCT_COARSE, PRODUCT_RADIUS, SIDE
from twoscale.resources import estimate_memory
from twoscale.scene import Scene, default_h
from twoscale.scenespace import build, sweep
from twoscale.api import solve

MATERIAL = Material(E=10.0, nu=0.5)


def test_the_level_under_load_lifts_each_tip_by_the_others_mean_force():
    # two paraboloids L apart under W: each carries W / 2 at its approach P_H^-1(W / 2); the
    # rigid level is that plus the other's Boussinesq lift (W / 2) / (pi E* L)
    R, W, L = 5.0, 2.0, 8.0
    scene = Scene(material=MATERIAL, total_load=W, asperities=[Asperity(0.0, 0.0, 0.0, R), Asperity(L, 0.0, 0.0, R)])
    E_star = MATERIAL.E_star
    delta = float(hertz.penetration(R, W / 2.0, E_star))
    level = delta + (W / 2.0) / (math.pi * E_star * L)
    field = mean_field(scene)
    assert field.level == pytest.approx(level, rel=1e-9)
    assert field.local == pytest.approx([delta, delta], rel=1e-9)
    assert field.geometric == pytest.approx([level, level], rel=1e-9)


def test_the_patches_a_stalled_macro_step_leaves_on_clustered_tips_under_load_are_counted():
    # seed 8's #112 (1,916 clustered spheres under load) with 1,200 tips: more than the macro
    # step's safe path takes, so a stall hands its iterate on and the tips' reach sizes the
    # patches; the macro step's own answer stands for that iterate (#112 stalled at 1.5e-2)
    scene = build(dataclasses.replace(sweep(200, 8)[112], n=1200))
    h = default_h(scene)
    asp = scene.asperities
    tips = np.array([[a.x, a.y] for a in asp])
    z = np.array([a.z for a in asp])
    macro = solve_macro(
        scene.provider(), tips, z, [law_for(a, scene.material) for a in asp], Loading(total_load=scene.total_load)
    )
    geometric = macro.penetration - z
    local = np.asarray(macro.local_penetrations, dtype=float)
    sizing = np.minimum(geometric, local + SIZING_SHARE * max(float(local.max()), 0.0))

    def cells(approaches) -> float:  # the micro step's patches without forces to size them
        grids = patch_grids(
            asp, h=h, forces=np.full(len(asp), np.inf), approaches=approaches, E_star=scene.material.E_star
        )
        return float(sum(g.size for _, g in grids))

    carried, policy = cells(sizing), cells(geometric)
    est = estimate_memory(scene, h)
    assert est.bytes >= BASE_BYTES + PATCH_BYTES_PER_CELL * carried + REACH_PATCH_HELD * policy
    assert 0.8 * carried <= est.cells <= 1.25 * carried


def test_the_coarse_corrections_product_holds_what_is_counted_for_its_fill():
    # contacts of 6 cells' radius every 24 cells: about one a square, as full as the
    # correction is built at (fill = sum n_i^2 / (side^2 sum n_i) <= MAX_FILL); the arrays
    # its precorrected product keeps (the near pairs' values and structure, the
    # interpolation's) against the count a loaded cell and unit of fill; they do not depend
    # on the kernel's values
    import scipy.sparse

    n = 600
    yy, xx = np.mgrid[0:n, 0:n]
    loaded = (yy % 24 - 12) ** 2 + (xx % 24 - 12) ** 2 <= 36
    per_square = np.bincount(((yy // SIDE) * (-(-n // SIDE)) + xx // SIDE)[loaded]).astype(float)
    fill = float(per_square @ per_square) / (SIDE**2 * loaded.sum())
    assert 0.15 <= fill <= MAX_FILL
    product = Precorrected(
        np.ones((2 * n - 1, 2 * n - 1)), (n, n), np.flatnonzero(loaded), PRODUCT_COARSE, PRODUCT_RADIUS
    )
    held = 0
    for value in vars(product).values():
        if scipy.sparse.issparse(value):
            held += value.data.nbytes + value.indices.nbytes + value.indptr.nbytes
        for a in value if isinstance(value, tuple) else (value,):
            held += a.nbytes if isinstance(a, np.ndarray) else 0
    counted = COARSE_BYTES_PER_LOADED_CELL_AND_FILL * fill * loaded.sum()
    assert 0.6 * counted <= held <= counted


@pytest.mark.slow
def test_under_load_a_union_cg_on_patches_the_level_raises_is_counted():
    # seed 7's #156 (839 spheres under load): the macro step's level lifts tips out of contact,
    # whose patches reach as far as they can touch, and the policy takes the union CG on their
    # box, which the contacts alone did not crowd (0.12 of it at the default h); a block
    # iteration may run too, so the box is what the estimate says the union CG would need,
    # checked when the policy takes it (test_memory_at_choice)
    import re

    scene = build(sweep(200, 7)[156])
    h = 0.1
    result = solve(scene, h=h)
    assert result.details.micro.choice.iteration == "union-cg"
    est = estimate_memory(scene, h)
    key = next(k for k, _ in est.union_parts if k.startswith("the union box ("))
    ny, nx = map(int, re.findall(r"\d+", key)[:2])
    assert ny * nx >= 0.9 * result.n_cells and est.union_bytes > est.bytes
