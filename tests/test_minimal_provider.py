"""The provider contract is complete: a body that implements only the abstract
methods (point and cell compliance, a grid operator with only ``apply``) runs the two-scale
solver, through the defaults of :mod:`twoscale.influence.base`, and gives the half-space's
answer. Its operators wrap the half-space's dense blocks, so the answers differ only by the
solver tolerance and the half-space's separated route (1e-8 of a pair's displacement).
"""

import numpy as np
import pytest

from twoscale import Grid, Material
from twoscale.indenters import Asperity
from twoscale.influence import GridOperator, HalfSpace, InfluenceProvider
from twoscale.micro.blocks import Coupling
from twoscale.micro.patches import make_patch
from twoscale.driver import solve_twoscale

MAT = Material(E=10.0, nu=0.5)
HS = HalfSpace(MAT)


class DenseOperator(GridOperator):
    """Only ``apply``: the half-space's dense block times the pressure."""

    def __init__(self, target: Grid, source: Grid):
        self.target, self.source = target, source
        self._A = HS.grid_matrix(target, source)

    def apply(self, p):
        return (self._A @ np.asarray(p, dtype=float).ravel()).reshape(self.target.shape)


class MinimalProvider(InfluenceProvider):
    """Only the abstract methods of the contract."""

    kind = "minimal"

    def __init__(self, material: Material):
        self.material = material

    def point_compliance(self, targets, sources):
        return HS.point_compliance(targets, sources)

    def cell_block(self, targets, sources, h):
        return HS.cell_block(targets, sources, h)

    def grid_operator(self, target, source=None):
        return DenseOperator(target, target if source is None else source)


# three spheres far enough apart that their patches stay separate blocks
SPHERES = [Asperity(0.0, 0.0, 0.0, 5.0), Asperity(6.0, 0.5, 0.02, 4.0), Asperity(2.5, 6.0, 0.01, 6.0)]


def test_default_stages_compose_to_apply():
    t, s = Grid(0.0, 0.0, 0.1, 7, 5), Grid(1.0, 0.3, 0.1, 4, 6)
    op = DenseOperator(t, s)
    p = np.random.default_rng(0).uniform(size=s.shape)
    assert np.array_equal(op.finish(op.multiply(op.spectrum(p))), op.apply(p))
    assert op.source_key == DenseOperator(Grid(5.0, 5.0, 0.1, 7, 5), s).source_key
    assert op.target_key != DenseOperator(t, Grid(1.0, 0.3, 0.1, 4, 7)).source_key
    assert op.nbytes > 0 and op.flops_estimate == t.size * s.size


def test_coupling_routes_with_a_minimal_provider_equal_the_dense_blocks():
    patches = [
        make_patch(k, Grid.covering(a.x - 1.0, a.x + 1.2, a.y - 0.9, a.y + 1.0, 0.1), SPHERES)
        for k, a in enumerate(SPHERES)
    ]
    rng = np.random.default_rng(2)
    values = [rng.uniform(size=int(pt.owned.sum())) for pt in patches]
    fast = Coupling(MinimalProvider(MAT), patches, dense_max_entries=0)
    dense = Coupling(HS, patches, dense_max_entries=10**9)
    for k in range(3):
        rhs = np.zeros(len(values[k]))
        assert np.allclose(fast.rhs(k, values, rhs), dense.rhs(k, values, rhs), rtol=1e-12, atol=1e-15)
    assert fast.route_counts()["spectral"] == 6


@pytest.mark.parametrize("load", [{"penetration": 0.12}, {"total_load": 3.0}])
def test_minimal_provider_solves_like_the_half_space(load):
    # the block iterations, whose cross products go through the provider (the policy may
    # take the union CG for these three close spheres)
    kw = dict(h=0.1, tol=1e-10, iteration="block-gs" if "penetration" in load else "two-level", **load)
    ref = solve_twoscale(HS, SPHERES, **kw)
    # dense_max_cells=50: the local solves use the operator (CG), not only the dense block
    got = solve_twoscale(MinimalProvider(MAT), SPHERES, dense_max_cells=50, **kw)
    assert ref.converged and got.converged, got.message
    F, F_ref = got.asperities.forces, ref.asperities.forces
    assert np.all(F_ref > 0)
    assert np.allclose(F, F_ref, rtol=1e-6, atol=0.0)
    assert got.penetration == pytest.approx(ref.penetration, rel=1e-6)
    assert got.details.micro.coupling.spectral > 0  # the cross products went through the defaults
