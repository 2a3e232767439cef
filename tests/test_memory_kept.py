"""What the far field holds for its weights, against what the memory estimate counts for it
(:func:`twoscale.memory_parts.far_weight_bytes`): per owned cell on patches under
``SEPARABLE_CELLS`` owned cells, the tensor-product form's rows and columns on the larger.

The held bytes are the ``nbytes`` of the arrays the far field keeps after a refresh and a
sweep's levels (and after a whole solve), not a copy of the count."""

import numpy as np

from helpers import lattice_patches

from twoscale import Material
from twoscale.influence import HalfSpace
from twoscale.memory_parts import far_weight_bytes
from twoscale.micro.farfield import LaggedFarField
from twoscale.micro.level_far import axis_weights
from twoscale.micro.sources import KEPT_BYTES_PER_OWNED_CELL, SEPARABLE_BYTES_PER_ROW_OR_COLUMN, SEPARABLE_CELLS
from twoscale.micro.twolevel import sweep_levels

HS = HalfSpace(Material(10.0, 0.5))
H = 0.02


def _held(far: LaggedFarField) -> tuple[int, set]:
    """Bytes of the weights ``far`` keeps (the source weights by patch, the levels' stacked
    interpolation rows and their block indices, the per-patch interpolation rows) and the
    patches they are kept for."""
    arrays = list(far._sources.values())
    kept_for = set(far._sources)
    for W, rows, _starts, _level, small in far._levels._kept.values():
        arrays += [W, rows]
        kept_for |= set(small)
    arrays += [w for key, w in far._weights.items() if key[0] != "shape"]
    return sum(a.nbytes for a in arrays), kept_for


def _counted(patches) -> tuple[float, float]:
    """The estimate's count on these patches, and its rows and columns part alone."""
    owned = np.array([pt.owned.sum() for pt in patches], dtype=float)
    sides = np.array([pt.grid.nx + pt.grid.ny for pt in patches], dtype=float)
    large = owned >= SEPARABLE_CELLS
    return far_weight_bytes(owned, sides), SEPARABLE_BYTES_PER_ROW_OR_COLUMN * float(sides[large].sum())


def test_a_far_field_holds_per_cell_weights_only_for_its_small_patches():
    rng = np.random.default_rng(4)
    patches = lattice_patches(rng, 30, 6.0, H, largest=60)
    owned = np.array([pt.owned.sum() for pt in patches])
    assert (owned >= SEPARABLE_CELLS).any() and (owned < SEPARABLE_CELLS).any()
    far = LaggedFarField(HS, patches, far_tol=0.3)
    values = [rng.random(int(n)) for n in owned]
    far.refresh(values)
    for level in sweep_levels(far):  # a sweep's far field, level by level
        far.rhs_level(level, values, [np.zeros(len(v)) for v in values])
    held, kept_for = _held(far)
    small = {k for k, n in enumerate(owned) if n < SEPARABLE_CELLS}
    assert kept_for == small  # nothing per cell for a large patch
    assert held == KEPT_BYTES_PER_OWNED_CELL * int(owned[sorted(small)].sum())
    counted, rows_and_columns = _counted(patches)
    assert counted == held + rows_and_columns
    # the rows and columns: the tensor-product form's weights of a large patch's grid
    for k in set(range(len(patches))) - small:
        g = patches[k].grid
        made = axis_weights(g.ny).nbytes + axis_weights(g.nx).nbytes
        assert made == SEPARABLE_BYTES_PER_ROW_OR_COLUMN * (g.nx + g.ny)


def test_the_far_fields_weights_after_a_two_level_solve_are_those_counted(monkeypatch):
    # 40 spheres on a sparse lattice, two radii (patches of ~400 and ~5,000
    # cells): the far field of the two-level iteration at its last sweep
    import twoscale
    from twoscale import Asperity, Scene
    from twoscale.micro import farfield

    made = []
    init = farfield.LaggedFarField.__init__

    def keep(self, *args, **kwargs):
        init(self, *args, **kwargs)
        made.append(self)

    monkeypatch.setattr(farfield.LaggedFarField, "__init__", keep)
    rng = np.random.default_rng(2)
    tips = [
        Asperity(6.0 * i + rng.uniform(-1, 1), 6.0 * j + rng.uniform(-1, 1), 0.0, 0.5 if (i + j) % 2 else 8.0)
        for i in range(8)
        for j in range(5)
    ]
    scene = Scene(material=Material(E=10.0, nu=0.5), penetration=0.05, asperities=tips)
    res = twoscale.solve(scene, h=0.02, iteration="two-level", far_tol=0.3)
    assert res.converged and made
    far = made[-1]
    owned = np.array([pt.owned.sum() for pt in far.patches])
    assert (owned >= SEPARABLE_CELLS).any() and (owned < SEPARABLE_CELLS).any()
    held, kept_for = _held(far)
    assert held > 0 and all(owned[k] < SEPARABLE_CELLS for k in kept_for)
    counted, rows_and_columns = _counted(far.patches)
    # what is counted, and where a block's right-hand side was asked alone (the rounds'
    # gaps) its interpolation rows once more (9 float64 an owned cell, not counted)
    small = owned < SEPARABLE_CELLS
    assert counted - rows_and_columns <= held <= counted - rows_and_columns + 72 * int(owned[small].sum())
