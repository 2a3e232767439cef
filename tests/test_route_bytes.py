"""Near pairs' routes by their bytes when the preferred Chebyshev blocks overflow the budget.

Checks: the byte counts against the operators the half-space makes (the spectrum's exactly,
the Chebyshev kernel's as the plan gives it); and a coupling whose budget holds the pairs'
spectra but not their Chebyshev blocks keeps every pair's operator (no pair left to a
product made again at each use) with products equal to the dense blocks', while a coupling
within its budget keeps the Chebyshev blocks as before.
"""

import numpy as np
import pytest

from twoscale.grid import Grid
from twoscale.influence.halfspace import HalfSpace
from twoscale.material import Material
from twoscale.micro.blocks import Coupling, size_class
from twoscale.micro.patches import Patch
from twoscale.micro.route_bytes import chebyshev_bytes, preferred_bytes, spectrum_bytes, spectrum_is_smaller

HS = HalfSpace(Material(E=10.0, nu=0.3))
RTOL = 1e-8


def _big(g):
    return g.subgrid(0, 0, size_class(g.nx), size_class(g.ny))


@pytest.mark.parametrize("shapes", [((24, 20), (24, 20)), ((17, 30), (40, 12)), ((8, 8), (61, 45))])
def test_spectrum_bytes_are_the_operators(shapes):
    (nx1, ny1), (nx2, ny2) = shapes
    t, s = Grid(0.0, 0.0, 0.1, nx1, ny1), Grid(7.0, 3.0, 0.1, nx2, ny2)
    assert spectrum_bytes(t, s) == HS.grid_operator(t, s).nbytes


def test_chebyshev_bytes_are_the_node_kernels():
    t, s = Grid(0.0, 0.0, 0.1, 24, 20), Grid(8.0, 1.0, 0.1, 24, 20)
    op = HS.separated_operator(t, s, rtol=RTOL)
    assert chebyshev_bytes(t, s, RTOL) == op._K.nbytes <= op.nbytes
    # too close for a Chebyshev block: none counted
    near = Grid(2.5, 0.0, 0.1, 24, 20)
    assert HS.separated_operator(t, near, rtol=RTOL) is None and chebyshev_bytes(t, near, RTOL) == 0.0


def _patches():
    # four patches of 24 x 20 cells: three 8-10 mm apart (Chebyshev blocks of more bytes than
    # their spectra at 1e-8), the last close to the first (spectral either way)
    out = []
    for a, (x, y) in enumerate([(0.0, 0.0), (8.0, 1.0), (-3.0, 9.0), (2.6, 0.5)]):
        g = Grid.covering(x - 1.2, x + 1.2, y - 1.0, y + 1.0, 0.1)
        X, Y = g.centres()
        out.append(
            Patch(asperity=a, grid=g, height=np.zeros(g.shape), owner=np.where(np.hypot(X - x, Y - y) < 1.1, a, -1))
        )
    return out


def _exact(patches, k, values, rhs):
    out = rhs.copy()
    for l, v in enumerate(values):
        if l != k:
            ik, il = (np.flatnonzero(p.owned.ravel()) for p in (patches[k], patches[l]))
            out -= HS.grid_matrix(patches[k].grid, patches[l].grid)[np.ix_(ik, il)] @ v
    return out


def _coupling(patches, cache_bytes):
    c = Coupling(HS, patches, dense_max_entries=0, cache_bytes=cache_bytes)
    c.plan_routes([(k, l) for k in range(len(patches)) for l in range(k)])
    return c


def test_a_budget_short_of_the_chebyshev_blocks_keeps_every_pair_by_its_spectrum():
    patches = _patches()
    pairs = [(k, l) for k in range(4) for l in range(k)]
    preferred = preferred_bytes(patches, pairs, 0, RTOL, _big)
    lean = sum(spectrum_bytes(_big(patches[k].grid), _big(patches[l].grid)) for k, l in pairs)
    far = [
        (k, l)
        for k, l in pairs
        if spectrum_is_smaller(patches[k].grid, patches[l].grid, *map(_big, (patches[k].grid, patches[l].grid)), RTOL)
    ]
    assert (3, 0) not in far and {(1, 0), (2, 0), (2, 1)} <= set(far) and lean < preferred
    rng = np.random.default_rng(3)
    values = [rng.random(int(p.owned.sum())) for p in patches]
    tight = _coupling(patches, 0.5 * (lean + preferred) / 2.0)  # twice it: between the two
    roomy = _coupling(patches, 4e8)
    assert tight.lean_routes and not roomy.lean_routes
    for k in range(4):
        b = rng.random(int(patches[k].owned.sum()))
        ref = _exact(patches, k, values, b)
        for c in (tight, roomy):
            np.testing.assert_allclose(c.rhs(k, values, b), ref, atol=1e-9 * np.abs(b - ref).max())
    assert {route[0] for route in tight._routes.values()} == {"spectral"}  # none left to "plain"
    assert tight._route_bytes <= 2.0 * tight.cache_bytes
    assert {route[0] for route in roomy._routes.values()} == {"spectral", "separated"}
    # the preferred blocks in the tight budget: some pair is left without its operator
    preferring = Coupling(HS, patches, dense_max_entries=0, cache_bytes=tight.cache_bytes)
    for k in range(4):
        preferring.rhs(k, values, np.zeros(len(values[k])))
    assert "plain" in {route[0] for route in preferring._routes.values()}
