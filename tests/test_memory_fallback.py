"""The union CG a far-field attempt falls back to, checked against the memory available when
it is about to start (twoscale.memory_now) instead of being counted before the solve: where
its box does not fit, block Gauss-Seidel with the same far field runs instead; its bytes a
cell against the arrays a union CG solve allocates (tracemalloc)."""

import tracemalloc
import warnings

import pytest

from twoscale import Asperity, Material, Scene
from twoscale.api import solve_scene
from twoscale.driver import solve_twoscale
from twoscale.errors import MemoryWarning
from twoscale.influence import HalfSpace
from twoscale.memory_now import UNION_BOX_SPREAD, union_box_bytes, union_box_fits
from twoscale.micro import driver, twolevel
from twoscale.micro.policy import Choice

from helpers import random_scene

MAT = Material(10.0, 0.5)
MERGED = dict(h=0.15, total_load=108.0, tol=1e-8)


def _failing_far_field_attempt(monkeypatch):
    # a far-field two-level attempt on patches said to cover half their box, held to a rate
    # it cannot show: it ends at its trial of 2 sweeps and the fallback decides
    monkeypatch.setattr(twolevel, "SLOW_RATE", 1e-6)
    monkeypatch.setattr(driver, "TWO_LEVEL_SWEEPS", 2)
    monkeypatch.setattr(driver, "choose", lambda *a, **k: Choice("two-level", 0.05, "test", {"coverage": 0.5}))


def test_the_union_cg_follows_a_failed_far_field_attempt_where_its_box_fits(monkeypatch):
    _failing_far_field_attempt(monkeypatch)
    with warnings.catch_warnings():
        warnings.simplefilter("error", MemoryWarning)
        res = solve_twoscale(HalfSpace(MAT), random_scene(2, 18), max_sweeps=100, **MERGED)
    first, second = res.details.micro.attempts
    assert first.iteration == "two-level" and not first.converged
    assert second.iteration == "union-cg" and res.converged


def test_block_gauss_seidel_replaces_the_union_cg_that_does_not_fit(monkeypatch):
    from twoscale import memory_now

    _failing_far_field_attempt(monkeypatch)
    boxes = []
    fits = memory_now.union_box_fits
    monkeypatch.setattr(driver, "union_box_fits", lambda cells: boxes.append(cells) or fits(cells, available=1e6))
    with pytest.warns(MemoryWarning, match="block Gauss-Seidel with the same far field"):
        res = solve_twoscale(HalfSpace(MAT), random_scene(2, 18), max_sweeps=100, **MERGED)
    first, second = res.details.micro.attempts
    assert first.iteration == "two-level" and not first.converged
    assert (second.iteration, second.far_tol) == ("block-gs", 0.05) and res.converged
    # the box asked about is the patches' (the 18 tips' at h 0.15 mm: tens of thousands of
    # cells, 300 bytes each over 0.8 MB)
    assert len(boxes) == 1 and union_box_bytes(boxes[0]) > 0.8e6


def test_union_box_fits_compares_its_bytes_with_80_percent_of_the_memory_given():
    cells = 1_000_000
    need = UNION_BOX_SPREAD * union_box_bytes(cells)
    assert union_box_fits(cells, available=need / 0.8 * 1.001)
    assert not union_box_fits(cells, available=need / 0.8 * 0.999)


def test_the_union_cg_allocates_within_the_spread_the_check_allows(monkeypatch):
    # 400 spheres on a lattice, solved by the union CG: what its run allocates beyond what
    # was live at its start (tracemalloc), against the box's bytes the check counts; at most
    # UNION_BOX_SPREAD of them, or a fallback let through could exceed the memory it checked
    from twoscale.micro import strategies

    tips = [Asperity(0.6 * i, 0.6 * j, 0.0, 2.0) for i in range(20) for j in range(20)]
    scene = Scene(material=MAT, penetration=0.1, asperities=tips)
    solve_scene(scene, h=0.05, iteration="union-cg")  # imports and caches first
    grown = []
    run = strategies.UnionCG.run

    def traced(self, *args, **kwargs):
        start, _ = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        out = run(self, *args, **kwargs)
        grown.append(tracemalloc.get_traced_memory()[1] - start)
        return out

    monkeypatch.setattr(strategies.UnionCG, "run", traced)
    tracemalloc.start()
    try:
        res = solve_scene(scene, h=0.02, iteration="union-cg")
    finally:
        tracemalloc.stop()
    ratio = grown[0] / union_box_bytes(res.n_cells)
    assert 0.67 <= ratio <= UNION_BOX_SPREAD, (ratio, res.n_cells)
