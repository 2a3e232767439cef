"""Eq. 8's first active-set pass on many dense blocks at once
(:func:`twoscale.micro.local_batch.final_first_passes`).

Cross-check with the one-block loop (:func:`twoscale.micro.local.contact_solve`, gaps by
the gathered active columns): from each block's own solution the stacked pass (gaps by one
FFT product a size class) is final and gives the same pressure and contact; from a start
whose contact misses penetrating cells, or holds cells that pull, it is not final and the
block is left to the loop.
"""

import numpy as np

from helpers import paraboloid_patch_problems
from twoscale import Material
from twoscale.influence import HalfSpace
from twoscale.influence.cached import CachedBody, OperatorCaches
from twoscale.micro.local import contact_solve
from twoscale.micro.local_batch import batchable, final_first_passes
from twoscale.micro.localblock import LocalBlock
from twoscale.micro.pk_stack import BlockStacks

MAT = Material(10.0, 0.5)
H = 0.02


def test_stacked_first_passes_are_the_one_block_solutions_where_final():
    rng = np.random.default_rng(3)
    patches, z, _, approaches = paraboloid_patch_problems(rng, 30, (6, 18), 1.0, H, MAT.E_star)
    body = CachedBody(HalfSpace(MAT), OperatorCaches())
    blocks = [LocalBlock(body, pt) for pt in patches]
    assert all(batchable(b) for b in blocks)
    rhs = {k: a - zk for k, (a, zk) in enumerate(zip(approaches, z))}  # d - z, no neighbours
    solved = [contact_solve(blk, rhs[k], np.zeros(blk.n)) for k, blk in enumerate(blocks)]
    assert all(s.converged and s.active.any() for s in solved)
    previous = [s.pressure for s in solved]
    wrong = {}
    for k in range(0, 30, 3):  # a contact missing its outer cells: they penetrate
        s = solved[k].active.copy()
        edge = np.flatnonzero(s)[[0, -1]]
        s[edge] = False
        previous[k] = np.where(s, solved[k].pressure, 0.0)
        wrong[k] = True
    for k in range(1, 30, 6):  # a contact with the highest cells in it: they pull
        p = solved[k].pressure.copy()
        p[np.argsort(rhs[k])[:3]] = 1e-3
        previous[k] = p
        wrong[k] = True
    stacks = BlockStacks(body)
    got = final_first_passes(blocks, list(range(30)), rhs, previous, stacks)
    for k, s in enumerate(solved):
        if k in wrong:
            continue
        assert k in got
        pressure, active = got[k]
        assert np.array_equal(active, s.active)
        assert np.allclose(pressure, s.pressure, rtol=1e-12, atol=1e-12 * s.pressure.max())
    assert not set(wrong) & set(got)
    # again on the same blocks (a sweep's level every sweep): the same answer
    again = final_first_passes(blocks, list(range(30)), rhs, previous, stacks)
    assert again.keys() == got.keys()
    assert all(np.array_equal(again[k][0], got[k][0]) for k in got)
