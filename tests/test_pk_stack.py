"""Stacked local solves (the Polonsky-Keer kernel on a stack of blocks) against the
one-block solves they batch.

Each block of a stack is an independent contact problem; the stacked iteration must give,
block by block, what :func:`pk_fixed_approach` / :func:`pk_fixed_force` give on that
block alone with the block's own FFT operator (same iteration counts, pressures to
rounding), whatever the block's size within the canvas, its mask, or whether it touches.
The sweep by levels must give what the plain order gives.
"""

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.micro.pk import fixed_approach, fixed_force, pk_fixed_approach, pk_fixed_force

HS = HalfSpace(Material(10.0, 0.5))
H = 0.04
CANVAS = (21, 21)


def _blocks(seed: int, count: int = 6):
    """Random blocks on the canvas: (mask, z) per block, spheres of R 2-6 mm with a notch
    cut out of some masks (cells a neighbour owns)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        ny, nx = rng.integers(12, CANVAS[0] + 1, 2)
        X, Y = np.meshgrid(np.arange(nx) * H, np.arange(ny) * H)
        mask = np.ones((ny, nx), bool)
        if i % 2:
            mask[:3, :4] = False
        R = rng.uniform(2.0, 6.0)
        z = ((X - X.mean() - 0.05) ** 2 + (Y - Y.mean()) ** 2) / (2.0 * R)
        out.append((mask, z))
    return out


def _own_matvec(mask):
    op = HS.grid_operator(Grid(0.0, 0.0, H, mask.shape[1], mask.shape[0]))

    def matvec(v):
        a = np.zeros(mask.shape)
        a[mask] = v
        return op.apply(a)[mask]

    return matvec


def _canvas(blocks, values):
    mask = np.zeros((len(blocks), *CANVAS), bool)
    out = np.zeros(mask.shape)
    for i, ((m, _), v) in enumerate(zip(blocks, values)):
        mask[i, : m.shape[0], : m.shape[1]] = m
        out[i][mask[i]] = v
    return mask, out


@pytest.mark.parametrize("seed", [0, 1])
def test_stacked_fixed_approach_matches_one_block_solves(seed):
    blocks = _blocks(seed)
    rng = np.random.default_rng(seed + 10)
    b, starts = [], []
    for i, (m, z) in enumerate(blocks):
        d = -0.01 if i == 2 else rng.uniform(0.002, 0.01)  # block 2 does not touch
        b.append(d - z[m])
        starts.append(np.maximum(b[-1], 0.0) * 50.0 if i % 3 else np.zeros(int(m.sum())))
    mask, B = _canvas(blocks, b)
    _, P0 = _canvas(blocks, starts)
    p, ok, it = fixed_approach(HS.grid_operator(Grid(0.0, 0.0, H, *CANVAS[::-1])).apply_stack, B, P0, mask, rtol=1e-9)
    for i, (m, _) in enumerate(blocks):
        ref, ref_ok, ref_it = pk_fixed_approach(_own_matvec(m), b[i], starts[i], rtol=1e-9)
        assert ok[i] == ref_ok and it[i] == ref_it
        assert np.allclose(p[i][mask[i]], ref, rtol=0.0, atol=1e-12 * max(np.abs(ref).max(), 1e-300))
    assert not np.any(p[2])


def test_stacked_fixed_force_matches_one_block_solves():
    blocks = _blocks(3)
    forces = np.linspace(0.01, 0.05, len(blocks))
    starts = [np.sqrt(np.maximum(0.002 - (z[m] - z[m].min()), 0.0)) + (z[m] == z[m].min()) for m, z in blocks]
    mask, Z = _canvas(blocks, [z[m] for m, z in blocks])
    _, P0 = _canvas(blocks, starts)
    op = HS.grid_operator(Grid(0.0, 0.0, H, *CANVAS[::-1]))
    p, s, ok, it = fixed_force(op.apply_stack, Z, forces / H**2, P0, mask, rtol=1e-9)
    for i, (m, z) in enumerate(blocks):
        ref, ref_s, ref_ok, ref_it = pk_fixed_force(_own_matvec(m), z[m], forces[i], H, starts[i], rtol=1e-9)
        assert ok[i] == ref_ok and it[i] == ref_it
        assert np.allclose(p[i][mask[i]], ref, rtol=0.0, atol=1e-12 * ref.max())
        assert abs(s[i] - ref_s) <= 1e-12 * abs(ref_s)
        assert abs(H**2 * p[i].sum() - forces[i]) <= 1e-12 * forces[i]


#: 40 spheres at a small dense limit, so that most blocks are FFT blocks solved in stacks.
STACKED = dict(h=0.05, total_load=2.0, tol=1e-8, max_sweeps=200, far_tol=0.05, coarse=True, dense_max_cells=60)


def _stacked_and_plain(provider, asp, monkeypatch):
    """Forces of the two-level solve by levels and stacks, and of the same solve in the
    plain sweep order with one solve per block (no stacks)."""
    from twoscale.micro import pk_stack, twolevel
    from twoscale.driver import solve_twoscale

    stacked = solve_twoscale(provider, asp, **STACKED)
    monkeypatch.setattr(twolevel, "sweep_levels", lambda coupling: None)
    monkeypatch.setattr(pk_stack.BlockStacks, "usable", staticmethod(lambda provider: False))
    plain = solve_twoscale(provider, asp, **STACKED)
    assert stacked.converged and plain.converged
    fs, fp = np.asarray(stacked.asperities.forces), np.asarray(plain.asperities.forces)
    assert np.mean(fp > 0) >= 0.3
    return fs, fp


def test_two_level_by_levels_and_stacks_matches_the_plain_order(monkeypatch):
    from helpers import spaced_spheres

    fs, fp = _stacked_and_plain(HS, spaced_spheres(40, 4, 20.0), monkeypatch)
    assert np.max(np.abs(fs - fp)) <= 1e-9 * fp.max()


def test_two_level_stacks_on_the_block_lag_only_its_self_correction(monkeypatch):
    # on the finite block the stacked local solves take the half-space part on a shared
    # canvas and each block's correction of itself at its previous pressure: the same
    # fixed point as one solve per block with the block's own operator
    pytest.importorskip("fem_influence")
    from helpers import small_block, spaced_spheres
    from twoscale.indenters import Asperity
    from twoscale.micro import pk_stack
    from twoscale.driver import solve_twoscale

    block = small_block(Material(10.0, 0.5))
    asp = [Asperity(a.x - 10.0, a.y - 10.0, a.z, a.R) for a in spaced_spheres(40, 4, 20.0)]
    assert pk_stack.BlockStacks.usable(block)
    fs, fp = _stacked_and_plain(block, asp, monkeypatch)
    assert np.max(np.abs(fs - fp)) <= 1e-6 * fp.max()
    half = solve_twoscale(HS, asp, **STACKED)  # the correction matters here: far more than that
    assert np.max(np.abs(np.asarray(half.asperities.forces) - fp)) > 1e-2 * fp.max()


def _sphere_blocks(radii, n: int):
    """One-asperity FFT blocks of ``n`` x ``n`` cells (every cell owned), a sphere of each
    radius with its tip off the cells' centres; their heights as block vectors."""
    from twoscale.micro.localblock import LocalBlock
    from twoscale.micro.patches import Patch

    blocks, z = [], []
    for k, R in enumerate(radii):
        g = Grid(20.0 * k, 0.0, H, n, n)
        X, Y = g.centres()
        height = ((X - 20.0 * k - 0.5 * n * H - 0.013) ** 2 + (Y - 0.5 * n * H + 0.007) ** 2) / (2.0 * R)
        blk = LocalBlock(HS, Patch(k, g, height, np.full(g.shape, k)))
        assert not blk.dense
        blocks.append(blk)
        z.append(height[blk.canvas_mask(g.shape)])
    return blocks, z


def _counting(monkeypatch, name):
    """Wrap ``pk_stack``'s ``name`` (fixed_force or fixed_approach) to record the rows'
    iteration counts."""
    from twoscale.micro import pk_stack

    seen: list = []
    inner = getattr(pk_stack, name)

    def wrapped(*args, **kwargs):
        out = inner(*args, **kwargs)
        seen.extend(out[-1].tolist())
        return out

    monkeypatch.setattr(pk_stack, name, wrapped)
    return seen


def test_stacked_eq7_on_large_blocks_is_the_plain_iteration_in_fewer_steps(monkeypatch):
    # the stacks precondition by the canvas's circulant inverse and take float32 search
    # directions: the same solution as one plain float64 Polonsky-Keer solve per block
    # (contacts of 25-45 cells across: the plain iteration takes 28-38 steps to 1e-8, these 10)
    from twoscale.analytic import hertz
    from twoscale.micro.local import pk_start
    from twoscale.micro.pk_stack import BlockStacks

    radii, forces = [8.0, 5.0, 12.0], [0.6, 0.4, 0.9]
    blocks, z = _sphere_blocks(radii, 48)
    approaches = hertz.penetration(np.array(radii), np.array(forces), HS.material.E_star)
    starts = {k: pk_start(z[k], float(approaches[k])) for k in range(3)}
    seen = _counting(monkeypatch, "fixed_force")
    out = BlockStacks(HS).initial(blocks, [0, 1, 2], z, forces, starts, H, rtol=1e-8)
    for k, blk in enumerate(blocks):
        ref, _, ok, plain = pk_fixed_force(blk.matvec, z[k], forces[k], H, starts[k], rtol=1e-8)
        assert ok and plain >= 25
        assert np.max(np.abs(out[k] - ref)) <= 1e-6 * ref.max()
        assert abs(H**2 * out[k].sum() - forces[k]) <= 1e-12 * forces[k]
        assert seen[k] <= plain / 2


def test_stacked_local_solves_on_large_blocks_are_the_plain_iteration_in_fewer_steps(monkeypatch):
    from twoscale.micro.pk_stack import BlockStacks

    blocks, z = _sphere_blocks([8.0, 5.0, 12.0], 48)
    rhs = {k: d - z[k] for k, d in enumerate([0.012, 0.02, 0.008])}
    previous = [np.zeros(blk.n) for blk in blocks]
    seen = _counting(monkeypatch, "fixed_approach")
    out = BlockStacks(HS).solve(blocks, [0, 1, 2], rhs, previous, 1e-9)
    for k, blk in enumerate(blocks):
        ref, ok, plain = pk_fixed_approach(blk.matvec, rhs[k], previous[k], rtol=1e-9)
        assert ok and out[k][1] and plain >= 35
        assert np.max(np.abs(out[k][0] - ref)) <= 1e-6 * ref.max()
        assert seen[k] <= plain / 2


def test_stack_products_in_float32_and_the_circulant_inverse_on_a_stack():
    # the stacked forms against the one-row forms they batch: the float32 product within
    # its rounding of the float64 one, the circulant inverse to rounding (a grid below and
    # one above the side from which the torus is longer than the grid)
    rng = np.random.default_rng(5)
    for n in (30, 140):
        op = HS.grid_operator(Grid(0.0, 0.0, H, n, n - 3))
        P = rng.uniform(0.0, 1.0, (3, n - 3, n))
        exact = np.stack([op.apply(p) for p in P])
        single = op.single_precision().apply_stack(P)
        assert single.dtype == np.float64 and np.max(np.abs(single - exact)) <= 1e-6 * np.abs(exact).max()
        inverse = op.preconditioner()
        rows = np.stack([inverse.apply(u) for u in exact])
        assert np.allclose(inverse.apply_stack(exact), rows, rtol=0.0, atol=1e-12 * np.abs(rows).max())
