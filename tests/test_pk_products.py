"""The Polonsky-Keer kernel's cheaper products (twoscale.pk.products): the half-space
operator's columns against its FFT product, and a solve whose search directions take a
rough product (float32 FFTs, or a deliberately perturbed one) against the classical
double-precision CG: the same contact to the tolerance, since the residual the stopping
rule reads is always the exact product's."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.indenters import Surface
from twoscale.influence import HalfSpace
from twoscale.pk import Constraint, Products, Tolerance, pk_solve
from twoscale.reference import solve_cg

from helpers import crowded_surface

MAT = Material(E=6.0, nu=0.5)
HS = HalfSpace(MAT)


@pytest.mark.parametrize("shift", [(0, 0), (3, -2)])
def test_columns_are_the_product_of_a_pressure_on_a_few_cells(shift):
    """Each column a window of the offset table: the same displacement as the FFT product
    of the sparse pressure, on the square operator and on a pair of different grids."""
    source = Grid(0.0, 0.0, 0.1, 23, 17)
    target = Grid(shift[0] * 0.1, shift[1] * 0.1, 0.1, 19, 21) if shift != (0, 0) else source
    op = HS.grid_operator(target, source)
    rng = np.random.default_rng(2)
    cells = rng.choice(source.size, 7, replace=False)
    values = rng.random(7)
    p = np.zeros(source.size)
    p[cells] = values
    out = np.full(target.size, 0.5)  # the columns are added to what is there
    op.columns()(out, cells, values)
    expected = op.apply(p.reshape(source.shape)).ravel() + 0.5
    assert np.max(np.abs(out - expected)) <= 1e-13 * np.max(np.abs(expected))


@pytest.mark.parametrize("seed,load", [(4, {"penetration": 0.12}), (5, {"total_load": 30.0})])
def test_single_precision_directions_find_the_classical_contact(seed, load):
    surf = crowded_surface(MAT, seed, load)
    plain = solve_cg(HS, surf, tol=1e-9, **load)
    fast = solve_cg(HS, surf, tol=1e-9, precondition=True, precision="single-directions", keep_conjugacy=0.01, **load)
    assert plain.converged and fast.converged, (plain.message, fast.message)
    p, pp = fast.fields[0].pressure, plain.fields[0].pressure
    assert np.linalg.norm(p - pp) <= 1e-6 * np.linalg.norm(pp)
    assert fast.penetration == pytest.approx(plain.penetration, abs=1e-9)
    # warm-started from the answer moved by one cell: the few cells that change are
    # corrected by the kernel's columns, the answer the same
    start = np.roll(pp, 1, axis=1)
    warm = solve_cg(HS, surf, tol=1e-9, precondition=True, precision="single-directions", start=start, **load)
    assert warm.converged and np.linalg.norm(warm.fields[0].pressure - pp) <= 1e-6 * np.linalg.norm(pp)


def test_a_rough_direction_product_shapes_the_steps_only():
    """The search directions multiplied by an operator 1e-3 off (a smoothing of the
    kernel): the solve still stops at the exact problem's answer, because the
    displacement is refreshed and confirmed by the exact product before it stops."""
    g = Grid.covering(-1.0, 1.0, -1.0, 1.0, 0.05)
    op = HS.grid_operator(g)
    x, y = g.centres()
    z = (x**2 + y**2) / 4.0  # a sphere of radius 2 mm
    z1 = z.reshape(1, -1)
    basis = np.ones((g.size, 1))
    target = np.array([[3.0 / g.h**2]])

    def exact(v):
        return np.stack([op.apply(r) for r in v])

    def rough(v):
        return 1.001 * exact(v)

    start = np.maximum(0.05 - z1, 0.0)
    tol = Tolerance(residual=1e-10, max_iter=500)
    ref = pk_solve(
        exact, z1.reshape(1, *g.shape), start.reshape(1, *g.shape), None, tol, constraint=Constraint(basis, target)
    )
    approx = pk_solve(
        Products(exact, rough, op.columns()),
        z1.reshape(1, *g.shape),
        start.reshape(1, *g.shape),
        None,
        Tolerance(residual=1e-10, max_iter=500),
        constraint=Constraint(basis, target),
    )
    assert ref.converged[0] and approx.converged[0]
    assert np.max(np.abs(approx.pressure - ref.pressure)) <= 1e-7 * np.max(ref.pressure)
    # the same product everywhere would have solved a problem 0.1 % stiffer
    wrong = pk_solve(
        rough, z1.reshape(1, *g.shape), start.reshape(1, *g.shape), None, tol, constraint=Constraint(basis, target)
    )
    assert abs(wrong.multipliers[0, 0] - ref.multipliers[0, 0]) > 1e-4 * abs(ref.multipliers[0, 0])


def test_directions_kept_over_an_entry_do_not_stall_a_converged_start():
    """A sphere's contact solved on a grid that leaves out the contact's last column, then
    given the whole grid from that answer: the residual is the few cells outside that
    penetrate, the contact's own gap is ~0. The first step lets them in; keeping the
    conjugate directions over that entry (few cells) made Fletcher-Reeves' beta jump by
    ~1e12 and the steps vanish (the residual stayed at 7e-3 for every iteration to the cap);
    the directions are dropped when the gradient jumps, and it converges to the
    whole grid's answer."""
    g = Grid(-4.8, -4.8, 0.1, 96, 96)
    x, y = g.centres()
    z = (x**2 + y**2) / 20.0  # a sphere of radius 10 mm
    kw = dict(total_load=20.0, tol=1e-8, precision="single-directions", precondition=True, keep_conjugacy=0.05)
    whole = solve_cg(HS, Surface(g, z, np.zeros(g.shape, int), 1), **kw)
    cols = np.flatnonzero(whole.fields[0].pressure.any(axis=0))
    cut = g.subgrid(0, 0, int(cols[-1]), g.ny)  # the contact's last column left out
    part = solve_cg(HS, Surface(cut, z[:, : cut.nx], np.zeros(cut.shape, int), 1), **kw)
    assert part.converged and whole.converged
    start = cut.embed_in(part.fields[0].pressure, g)
    again = solve_cg(HS, Surface(g, z, np.zeros(g.shape, int), 1), start=start, max_iter=60, **kw)
    assert again.converged, again.message
    assert again.residuals["gap"][0] > 1e-3  # the start is off by the cells left out
    p, pw = again.fields[0].pressure, whole.fields[0].pressure
    assert np.abs(p - pw).max() <= 1e-6 * pw.max()


@pytest.mark.parametrize("seed,load", [(4, {"penetration": 0.12}), (5, {"total_load": 30.0})])
def test_single_precision_directions_take_one_double_product_and_the_classical_contact(seed, load, monkeypatch):
    """With float32 search directions the kernel asks for an exact product only once its
    residual is below ``FAST_RESIDUAL``: the first is taken in double precision and every
    later one (the confirmation at the tolerance) in float32 about it. One float64 product
    of the kernel's (besides the start's line search under penetration control, and the
    cropped grid's product back on the whole grid), and the classical double-precision
    CG's contact to 1e-7 of the largest force."""
    from twoscale.influence.convolution import ConvolutionOperator, _SingleConvolution

    surf = crowded_surface(MAT, seed, load)
    plain = solve_cg(HS, surf, tol=1e-9, **load)
    calls = []
    double, anchor = ConvolutionOperator.apply, _SingleConvolution.exact
    monkeypatch.setattr(ConvolutionOperator, "apply", lambda self, p: calls.append(1) or double(self, p))
    monkeypatch.setattr(_SingleConvolution, "exact", lambda self, p: calls.append(1) or anchor(self, p))
    fast = solve_cg(HS, surf, tol=1e-9, precondition=True, precision="single-directions", **load)
    assert plain.converged and fast.converged, (plain.message, fast.message)
    assert len(fast.residuals["gap"]) > 3  # not converged at the start
    assert len(calls) == 1 + 2 * ("penetration" in load)
    f, fp = fast.asperities.forces, plain.asperities.forces
    assert np.max(np.abs(f - fp)) <= 1e-7 * np.max(fp)
    # a rough start (CGSettings.rough_start) scales itself by the float32 product instead
    calls.clear()
    rough = solve_cg(HS, surf, tol=1e-9, precondition=True, precision="single-directions", rough_start=True, **load)
    assert rough.converged and len(calls) == 1 + ("penetration" in load)
    assert np.max(np.abs(rough.asperities.forces - fp)) <= 1e-7 * np.max(fp)


def test_a_direction_restarted_right_after_an_exact_product_takes_the_whole_product():
    """The halves (the step length by Parseval, the transforms back only if the step uses
    ``A t``) pay where the step likely refreshes the displacement: a direction restarted
    after a step whose displacement came from the fast product (cells entered, the
    contact settling). Right after an exact product (the anchor, a confirmation: ``stale``
    0) the residual is small and the step changes a few cells: ``A t`` is used, so the
    whole product is taken at once."""
    from twoscale.pk.products import halved

    begun = object()
    ops = Products(exact=lambda v: v, halves=lambda t: begun)
    t = np.array([[1.0, -1.0, 0.0]])  # (a restarted direction under load control sums to 0)
    restarted = np.zeros(1)
    assert halved(ops, t, 1, restarted, np.array([1])) is begun
    assert halved(ops, t, 1, restarted, np.array([0])) is None
    assert halved(ops, t, 1, np.ones(1), np.array([1])) is None  # (kept directions: whole)
