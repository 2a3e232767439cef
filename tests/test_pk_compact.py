"""The constrained CG on a part of the grid (``solve_cg(reach=...)``, :mod:`twoscale.pk.compact`):
the same contact as on the whole grid, whether the part holds the contact or misses some of
it (then the whole grid is solved from the part's answer)."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.pk.compact import Part
from twoscale.reference import solve_cg

from helpers import crowded_surface

MAT = Material(E=6.0, nu=0.5)
HS = HalfSpace(MAT)
SETTINGS = {"tol": 1e-9, "precondition": True, "precision": "single-directions", "keep_conjugacy": 0.005}


def _same(a, b):
    assert a.converged and b.converged, (a.message, b.message)
    p, q = a.fields[0].pressure, b.fields[0].pressure
    assert np.linalg.norm(p - q) <= 1e-6 * np.linalg.norm(q)
    assert a.penetration == pytest.approx(b.penetration, abs=1e-9)
    g, h = a.fields[0].gap, b.fields[0].gap
    finite = np.isfinite(h)
    assert np.max(np.abs(g[finite] - h[finite])) <= 1e-6 * np.abs(h[finite]).max()


@pytest.mark.parametrize("load", [{"total_load": 30.0}, {"penetration": 0.12}])
def test_a_part_holding_the_contact_gives_the_whole_grids_answer(load):
    surf = crowded_surface(MAT, 5, load)
    whole = solve_cg(HS, surf, **load, **SETTINGS)
    near = (whole.fields[0].pressure > 0) | (whole.fields[0].gap < 0.02)
    assert near.mean() < 0.5  # a part, not the grid
    part = solve_cg(HS, surf, reach=near, **load, **SETTINGS)
    _same(part, whole)


def test_a_rough_start_scaled_on_the_part_gives_the_whole_grids_answer(monkeypatch):
    """Penetration control, a rough start and a part: the start's line search by the part's
    float32 product, which is then the kernel's first (one product fewer than a line search
    on the whole grid followed by the kernel's own)."""
    from twoscale.influence.convolution import ConvolutionOperator, _SingleConvolution
    from twoscale.influence.on_cells import CellProduct

    load = {"penetration": 0.12}
    surf = crowded_surface(MAT, 5, load)
    whole = solve_cg(HS, surf, **load, **SETTINGS)
    near = (whole.fields[0].pressure > 0) | (whole.fields[0].gap < 0.02)
    guess = np.where(near & np.isfinite(surf.height), np.maximum(0.12 - surf.height, 0.0), 0.0)
    calls = []
    for kind, name in ((CellProduct, "__call__"), (ConvolutionOperator, "apply"), (_SingleConvolution, "apply")):
        made = getattr(kind, name)
        monkeypatch.setattr(kind, name, lambda self, v, made=made, kind=kind: calls.append(kind) or made(self, v))
    rough = solve_cg(HS, surf, reach=near, start=guess, rough_start=True, **load, **SETTINGS)
    made_rough = list(calls)
    calls.clear()
    scaled = solve_cg(HS, surf, reach=near, start=guess, **load, **SETTINGS)  # exact line search, whole grid
    _same(rough, whole)
    _same(scaled, whole)
    # the exact line search is a whole-grid float64 product; the rough one is on the part
    # (no whole-grid product of either precision more than the other solve's)
    assert made_rough.count(ConvolutionOperator) == calls.count(ConvolutionOperator) - 1
    assert made_rough.count(_SingleConvolution) == calls.count(_SingleConvolution)
    if rough.iterations["cg"] == scaled.iterations["cg"]:  # (19 and 19)
        assert len(made_rough) == len(calls) - 1  # the line search's product is the kernel's first


def test_a_part_missing_contact_is_solved_on_the_whole_grid_from_its_answer():
    load = {"total_load": 30.0}
    surf = crowded_surface(MAT, 5, load)
    whole = solve_cg(HS, surf, **load, **SETTINGS)
    X, _ = surf.grid.centres()
    on = whole.fields[0].pressure > 0
    half = X < np.median(X[on])  # half the contact left out
    part = solve_cg(HS, surf, reach=half, **load, **SETTINGS)
    _same(part, whole)
    wrong = solve_cg(HS, surf, reach=np.zeros_like(half), **load, **SETTINGS)  # no cell: the whole grid
    _same(wrong, whole)
    with pytest.raises(ValueError, match="reach"):
        solve_cg(HS, surf, reach=half[1:], **load, **SETTINGS)


def test_the_parts_products_are_the_grids_on_its_cells():
    g = Grid.covering(-2.0, 2.0, -1.5, 1.5, 0.1)
    op = HS.grid_operator(g)
    rng = np.random.default_rng(3)
    cells = np.flatnonzero(rng.random(g.size) < 0.3)
    part = Part(cells, g.shape)
    v = rng.random((1, cells.size))
    field = np.zeros(g.size)
    field[cells] = v[0]
    exact = part.product(lambda w: op.apply(w[0])[None], exact=True)
    np.testing.assert_allclose(exact(v)[0], op.apply(field.reshape(g.shape)).ravel()[cells], rtol=1e-14)
    # the last exact product is the grid's displacement of that pressure
    np.testing.assert_array_equal(part.displacement(v, None)[0], op.apply(field.reshape(g.shape)).ravel())
    # a kernel column added on the part is the grid's column on its cells
    out = np.zeros((1, cells.size))
    part.columns(op.columns())(out[0], np.array([4]), np.array([2.0]))
    unit = np.zeros(g.size)
    unit[cells[4]] = 2.0
    np.testing.assert_allclose(out[0], op.apply(unit.reshape(g.shape)).ravel()[cells], rtol=1e-9, atol=1e-15)
    # and so are the operator's columns on the part's cells as targets, a gather each
    on_part = np.zeros(cells.size)
    op.columns(cells)(on_part, cells[[4, 17]], np.array([2.0, -1.0]))
    unit[cells[17]] = -1.0
    np.testing.assert_allclose(on_part, op.apply(unit.reshape(g.shape)).ravel()[cells], rtol=1e-9, atol=1e-15)
    # a candidate off the part below the tolerance is touching; one above it is not
    gap = np.ones((1, g.size))
    off = np.setdiff1d(np.arange(g.size), cells)[0]
    gap[0, off] = -1e-3
    cand = np.ones((1, g.size), bool)
    assert part.touching(gap, cand, np.array([1e-4]))[0]
    assert not part.touching(gap, cand, np.array([1e-2]))[0]
    cand[0, off] = False
    assert not part.touching(gap, cand, np.array([1e-4]))[0]


@pytest.mark.parametrize("on_part", [True, False])
@pytest.mark.parametrize("load", [{"total_load": 30.0}, {"penetration": 0.12}])
def test_search_directions_in_halves_give_the_whole_products_answer(load, on_part, monkeypatch):
    """``half_products``: where a direction restarted, its product (on a part, or on every
    cell) is begun only (the step length by Parseval) and finished where the step uses
    ``A t``; the contact is the one of whole products, and some products never ran their
    transforms back."""
    from twoscale.influence.on_cells import CellProduct

    surf = crowded_surface(MAT, 5, load)
    whole = solve_cg(HS, surf, **load, **SETTINGS)
    near = (whole.fields[0].pressure > 0) | (whole.fields[0].gap < 0.02) if on_part else None
    counts = {"forward": 0, "finish": 0}
    forward, finish = CellProduct.forward, CellProduct.finish

    def counted(name, method):
        def run(self, *args):
            counts[name] += 1
            return method(self, *args)

        return run

    monkeypatch.setattr(CellProduct, "forward", counted("forward", forward))
    monkeypatch.setattr(CellProduct, "finish", counted("finish", finish))
    plain = solve_cg(HS, surf, reach=near, **load, **SETTINGS)
    assert counts["forward"] == counts["finish"]
    assert (counts["finish"] > 0) == on_part  # (on every cell the whole products are the grid's)
    counts.update(forward=0, finish=0)
    halves = solve_cg(HS, surf, reach=near, half_products=True, **load, **SETTINGS)
    assert counts["forward"] > counts["finish"]
    _same(halves, whole)
    _same(halves, plain)
    assert halves.iterations["cg"] <= plain.iterations["cg"] + 1


@pytest.mark.parametrize("load", [{"total_load": 30.0}, {"penetration": 0.12}])
def test_restarted_directions_stepped_by_the_preconditioners_model_give_the_same_answer(load, monkeypatch):
    """``step_model``: a restarted direction's step length from the preconditioner's torus
    (no transform of the padded grid unless the step then uses ``A t``): under load control
    the contact of the whole products, with fewer padded forward transforms than Parseval's
    halves take; under penetration control (directions that do not sum to 0) the halves'
    own run."""
    from twoscale.influence.on_cells import CellProduct

    surf = crowded_surface(MAT, 5, load)
    whole = solve_cg(HS, surf, **load, **SETTINGS)
    near = (whole.fields[0].pressure > 0) | (whole.fields[0].gap < 0.02)
    counts = {"forward": 0}
    forward = CellProduct.forward

    def counted(self, *args):
        counts["forward"] += 1
        return forward(self, *args)

    monkeypatch.setattr(CellProduct, "forward", counted)
    halves = solve_cg(HS, surf, reach=near, half_products=True, **load, **SETTINGS)
    begun, counts["forward"] = counts["forward"], 0
    modelled = solve_cg(HS, surf, reach=near, half_products=True, step_model=True, **load, **SETTINGS)
    _same(modelled, whole)
    _same(modelled, halves)
    assert modelled.iterations["cg"] <= halves.iterations["cg"] + 1
    if "total_load" in load:
        assert counts["forward"] < begun
    else:
        assert counts["forward"] == begun
        assert np.array_equal(modelled.fields[0].pressure, halves.fields[0].pressure)
