"""A dense pair block of few owned cells on large patch grids is computed on the owned cells
alone (not cut from the grids' whole block) and is the same block."""

import numpy as np

import twoscale.micro.blocks as blocks
from twoscale import Material
from twoscale.grid import Grid
from twoscale.indenters import Asperity
from twoscale.influence import HalfSpace
from twoscale.micro.patches import make_patch


def test_owned_cells_block_equals_the_grids_block_cut(monkeypatch):
    hs = HalfSpace(Material(E=10.0, nu=0.5))
    # two small spheres close together on wide patches: each owns a fifth of its grid
    asps = [Asperity(0.0, 0.0, 0.0, 0.2), Asperity(0.3, 0.05, 0.001, 0.25)]
    patches = [
        make_patch(k, Grid.covering(a.x - 0.4, a.x + 0.4, a.y - 0.4, a.y + 0.4, 0.02), asps) for k, a in enumerate(asps)
    ]
    nk, nl = (int(p.owned.sum()) for p in patches)
    assert patches[0].grid.size * patches[1].grid.size > 4 * nk * nl  # the owned cells are few
    monkeypatch.setattr(blocks, "GRID_BLOCK_MAX_ENTRIES", 0)  # the owned cells' block, computed

    def whole_block(*args):
        raise AssertionError("the grids' whole block was formed")

    with monkeypatch.context() as m:
        m.setattr(HalfSpace, "grid_matrix", whole_block)
        direct = blocks.Coupling(hs, patches, dense_max_entries=10**7)._dense(0, 1)
    monkeypatch.setattr(blocks, "GRID_BLOCK_MAX_ENTRIES", 10**12)  # force the cut of the grids' block
    cut = blocks.Coupling(hs, patches, dense_max_entries=10**7)._dense(0, 1)
    assert direct.shape == cut.shape == (nk, nl)
    np.testing.assert_allclose(direct, cut, rtol=1e-12, atol=0.0)
