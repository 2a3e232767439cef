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
