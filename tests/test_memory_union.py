"""What the union CG holds beside its box, against what the memory estimate counts for it:
its patches as windows of the box it samples once, and its coarse correction exactly where
the correction is built (:func:`twoscale.memory_parts.coarse_parts`)."""

import tracemalloc

import pytest

import twoscale
from twoscale import Asperity, Material, Scene
from twoscale.memory_costs import PATCH_WINDOW_BYTES_EACH
from twoscale.micro import strategies
from twoscale.pk import coarse
from twoscale.resources import estimate_memory

H = 0.02


def _lattice(side: int, spacing: float, penetration: float) -> Scene:
    tips = [Asperity(spacing * i, spacing * j, 0.0, 2.0) for i in range(side) for j in range(side)]
    return Scene(material=Material(E=10.0, nu=0.5), penetration=penetration, asperities=tips)


@pytest.mark.parametrize(
    "side, spacing, penetration, built",
    [
        (24, 0.5, 0.005, True),  # contacts of ~80 cells, one a square of 625: fill ~0.13
        (20, 0.6, 0.1, False),  # contacts of ~1,500 cells crowding their squares: fill ~0.6
    ],
)
def test_the_union_cgs_coarse_correction_and_patches_are_counted_as_held(
    monkeypatch, side, spacing, penetration, built
):
    scene = _lattice(side, spacing, penetration)
    spaces, live = [], []
    build = coarse.CoarseSpace.build.__func__
    monkeypatch.setattr(
        coarse.CoarseSpace, "build", classmethod(lambda cls, *a: spaces.append(build(cls, *a)) or spaces[-1])
    )
    run = strategies.UnionCG.run

    def start(self, context, *args, **kwargs):
        live.append((tracemalloc.get_traced_memory()[0], len(context.patches), context.patches))
        return run(self, context, *args, **kwargs)

    monkeypatch.setattr(strategies.UnionCG, "run", start)
    tracemalloc.start()
    try:
        res = twoscale.solve(scene, h=H, iteration="union-cg")
    finally:
        tracemalloc.stop()
    assert res.converged and res.n_cells >= coarse.MIN_CELLS and spaces
    parts = dict(estimate_memory(scene, H, iteration="union-cg").parts)
    assert any(s is not None for s in spaces) == built
    assert ("the union CG's coarse correction" in parts) == built
    # the patches: windows of the one box sampled (their heights share one base), and all
    # that was live when the union CG started, but for that sample, within the bytes
    # counted a patch
    held, count, patches = live[0]
    assert all(pt.height.base is not None for pt in patches)
    assert len({id(pt.height.base) for pt in patches}) == 1
    name = next(k for k in parts if k.endswith("patches, windows of the union box"))
    counted = int(name.split()[0])  # the patches that can touch, by the estimate
    assert parts[name] == PATCH_WINDOW_BYTES_EACH * counted
    box = patches[0].height.base.nbytes + patches[0].owner.base.nbytes  # counted with the box
    assert held - box <= PATCH_WINDOW_BYTES_EACH * count
