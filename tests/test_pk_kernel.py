"""The Polonsky-Keer kernel (twoscale.pk) on its own: against Hertz, stacked against row by
row, and its stop reasons.

Hertz: R = 10 mm, E = 10 MPa, nu = 0.5, penetration d = 0.1 mm (a = 1 mm), the tip at the
corner of four cells. The pressure sampled at the cell centres has a first-order L2 error
(the square-root edge, see test_reference_hertz.py: 0.45 % at 2a/h = 64), so the bound is
written as a multiple of h/a; the load's error is of higher order (about 1.5), and the
rigid approach found under load control is within a small multiple of h/a of Hertz's.
"""

import math

import numpy as np
import pytest

from twoscale import Grid, Material
from twoscale.analytic import hertz
from twoscale.influence import HalfSpace
from twoscale.pk import Constraint, StopReason, Tolerance, pk_solve
from twoscale.pk.kernel import Start

MAT = Material(10.0, 0.5)
HS = HalfSpace(MAT)
R, D = 10.0, 0.1
A = math.sqrt(R * D)


def _hertz_problem(n: int):
    """Grid with ``n`` cells across the contact diameter covering 1.2 a, the paraboloid's
    heights on it, and its FFT operator."""
    h = 2 * A / n
    grid = Grid.covering(-1.2 * A, 1.2 * A, -1.2 * A, 1.2 * A, h, anchor=(0.5 * h, 0.5 * h))
    X, Y = grid.centres()
    r = np.hypot(X, Y)
    return grid, r, (X**2 + Y**2) / (2 * R), HS.grid_operator(grid)


@pytest.mark.parametrize("n", [32, 64])
def test_penetration_control_matches_hertz_to_first_order_in_h(n):
    grid, r, z, op = _hertz_problem(n)
    out = pk_solve(
        op.apply_stack,
        (z - D)[None],
        np.maximum(D - z, 0.0)[None],
        np.ones((1, *z.shape), bool),
        Tolerance(residual=1e-10, max_iter=500),
    )
    assert out.reasons == (StopReason.CONVERGED,) and out.converged.all()
    pe = hertz.pressure(r, R, D, MAT.E_star)
    p = out.pressure[0]
    h_over_a = grid.h / A
    assert np.linalg.norm(p - pe) / np.linalg.norm(pe) <= 0.25 * h_over_a  # measured 0.14 h/a
    load = grid.h**2 * p.sum()
    assert abs(load / hertz.load(R, D, MAT.E_star) - 1) <= 0.1 * h_over_a**1.5  # measured 0.01-0.02
    # the displacement returned is A p
    assert np.allclose(out.displacement[0], op.apply(p), rtol=0, atol=1e-12 * D)


def test_load_control_finds_hertz_approach_as_its_multiplier():
    grid, r, z, op = _hertz_problem(48)
    W = float(hertz.load(R, D, MAT.E_star))
    out = pk_solve(
        op.apply_stack,
        z[None],
        np.ones((1, *z.shape)),
        np.ones((1, *z.shape), bool),
        Tolerance(residual=1e-10, max_iter=500),
        constraint=Constraint(np.ones((z.size, 1)), np.array([[W / grid.h**2]])),
    )
    assert out.converged.all()
    p = out.pressure[0]
    assert abs(grid.h**2 * p.sum() / W - 1) <= 1e-12  # the constraint is held exactly
    # g = A p + z - m vanishes on the contact: m is the rigid approach, Hertz's d to O(h/a)
    assert abs(out.multipliers[0, 0] / D - 1) <= 0.01 * grid.h / A  # measured 0.002 h/a
    pe = hertz.pressure(r, R, D, MAT.E_star)
    assert np.linalg.norm(p - pe) / np.linalg.norm(pe) <= 0.25 * grid.h / A


def test_stack_equals_rows_one_by_one():
    """Rows of a stack are independent: four penetrations (one without contact) solved at
    once give each row's own solve (same iterations and reason, pressure to rounding)."""
    grid, _, z, op = _hertz_problem(24)
    depths = np.array([0.1, 0.04, -0.01, 0.07])
    zs = np.stack([z - d for d in depths])
    starts = np.stack([np.maximum(-zz, 0.0) * (i % 2) for i, zz in enumerate(zs)])
    mask = np.ones(zs.shape, bool)
    tol = Tolerance(change=1e-9, max_iter=400)
    stacked = pk_solve(op.apply_stack, zs, starts, mask, tol)
    for i in range(len(depths)):
        alone = pk_solve(op.apply_stack, zs[i : i + 1], starts[i : i + 1], mask[i : i + 1], tol)
        assert stacked.reasons[i] is alone.reasons[0] is StopReason.CONVERGED
        assert stacked.iterations[i] == alone.iterations[0]
        scale = max(float(np.abs(alone.pressure).max()), 1e-300)
        assert np.allclose(stacked.pressure[i], alone.pressure[0], rtol=0.0, atol=1e-12 * scale)
    assert not stacked.pressure[2].any() and stacked.iterations[2] == 0


def test_iteration_cap_is_a_stop_reason_with_the_users_message():
    grid, _, z, op = _hertz_problem(32)
    out = pk_solve(
        op.apply_stack,
        (z - D)[None],
        np.maximum(D - z, 0.0)[None],
        np.ones((1, *z.shape), bool),
        Tolerance(residual=1e-12, max_iter=3),
    )
    assert out.reasons == (StopReason.MAX_ITER,) and not out.converged.any()
    assert out.iterations[0] == 3
    assert out.message(0).startswith("KKT residual ") and out.message(0).endswith("after max_iter=3")


def test_rows_of_one_stack_stop_for_their_own_reasons():
    grid, _, z, op = _hertz_problem(24)
    zs = np.stack([z + 0.01, z - D])  # no contact at all / a contact needing many steps
    out = pk_solve(op.apply_stack, zs, np.zeros(zs.shape), np.ones(zs.shape, bool), Tolerance(change=1e-12, max_iter=4))
    assert out.reasons == (StopReason.CONVERGED, StopReason.MAX_ITER)
    assert not out.pressure[0].any() and out.pressure[1].max() > 0


def test_residual_that_stops_halving_is_stagnation():
    grid, _, z, op = _hertz_problem(24)
    out = pk_solve(
        op.apply_stack,
        (z - D)[None],
        np.maximum(D - z, 0.0)[None],
        np.ones((1, *z.shape), bool),
        Tolerance(residual=1e-30, max_iter=1000, stall=1),
    )
    assert out.reasons == (StopReason.STAGNATED,) and out.iterations[0] < 1000
    assert out.message(0).startswith("no progress: KKT residual")


def test_operator_that_is_not_positive_is_a_breakdown():
    grid, _, z, op = _hertz_problem(16)
    out = pk_solve(
        lambda v: -op.apply_stack(v),
        (z - D)[None],
        np.maximum(D - z, 0.0)[None],
        np.ones((1, *z.shape), bool),
        Tolerance(residual=1e-8),
    )
    assert out.reasons == (StopReason.BREAKDOWN,)
    assert out.denominator[0] <= 0 and out.message(0).startswith("CG breakdown (t.A t = ")


def test_a_stopping_rule_is_required():
    with pytest.raises(ValueError, match="residual or change"):
        Tolerance()
    with pytest.raises(ValueError, match="max_iter"):
        Tolerance(residual=1e-8, max_iter=-1)


def test_block_gauss_seidel_says_why_it_stopped():
    """The sweeps' result carries a StopReason: the caller's stop test, the sweep cap, or
    convergence (what the micro step branches on, not the message)."""
    from twoscale.indenters import Asperity
    from twoscale.micro.blocks import Coupling
    from twoscale.micro.gauss_seidel import gauss_seidel
    from twoscale.micro.localblock import LocalBlock
    from twoscale.micro.sampling import build_patches

    d, h = 0.08, 0.07
    tips = [Asperity(0.0, 0.0, 0.0, 2.0, "paraboloid"), Asperity(0.9, 0.0, 0.002, 2.0, "paraboloid")]
    patches = build_patches(tips, h=h, forces=np.ones(2), approaches=np.full(2, d), E_star=MAT.E_star)
    blocks = [LocalBlock(HS, pt) for pt in patches]
    b = [np.full(blk.n, 0.01) for blk in blocks]  # a flat punch 10 um deep on each block
    start = [np.zeros(blk.n) for blk in blocks]
    coupling = Coupling(HS, patches)
    stopped = gauss_seidel(blocks, coupling, b, start, tol=1e-10, max_sweeps=50, stop=lambda p: True)
    assert stopped.reason is StopReason.STOPPED and not stopped.converged and stopped.sweeps == 1
    capped = gauss_seidel(blocks, coupling, b, start, tol=1e-14, max_sweeps=2)
    assert capped.reason is StopReason.MAX_ITER and "2 sweeps" in capped.message
    done = gauss_seidel(blocks, coupling, b, start, tol=1e-8, max_sweeps=200)
    assert done.reason is StopReason.CONVERGED and done.converged and done.message == ""


def test_a_start_product_given_replaces_the_first_product_and_changes_nothing_else():
    grid, r, z, op = _hertz_problem(32)
    start = 0.5 * np.maximum(D - z, 0.0)[None]
    calls = []

    def apply(v):
        calls.append(len(v))
        return op.apply_stack(v)

    args = ((z - D)[None], start, np.ones((1, *z.shape), bool), Tolerance(residual=1e-10, max_iter=500))
    plain = pk_solve(apply, *args)
    n_plain = len(calls)
    calls.clear()
    given = pk_solve(apply, args[0], Start(start, op.apply_stack(start)), *args[2:])
    assert len(calls) == n_plain - 1  # the kernel's first product not made
    assert np.array_equal(given.pressure, plain.pressure)  # the same product: the same iterates
    assert given.converged.all()
