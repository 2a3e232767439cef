"""Tips above the approach that a bonded block's rising surface touches (twoscale.bulge,
twoscale.bulge_rounds).

A sphere pressed 0.5 mm into a bonded, incompressible 5 mm layer raises the surface about
20 um some 6 mm away. A second sphere there, its apex 10 um above the approach, is outside
every tip's reach. Both solvers take it in and agree with the constrained CG on a grid
that covers both tips (the whole problem at once, nothing left out): the reference grows
its grid by the rise; the two-scale solve gives it a patch, from the macro step's local
approach (its point compliance is negative where the surface rises) or, where that misses
it, from the answer's check and a second micro step. The apex's gap is
checked independently: the solved pressure spread on a grid that covers both tips, its
displacement by the body's grid operator (FFT and correction, not the cell blocks the
check uses). With the apex 40 um above, or on the half-space (whose surface only sinks),
the gap stays open, nothing is said, and the solve is the one made without the check."""

from __future__ import annotations

import copy
import warnings
from unittest import mock

import numpy as np
import pytest

import twoscale
import twoscale.bulge_rounds as rounds
import twoscale.driver as driver
from twoscale import Material
from twoscale.details import BulgeDetails
from twoscale.errors import BulgeWarning
from twoscale.grid import Grid
from twoscale.indenters import Asperity, surface_on
from twoscale.reference import solve_reference
from twoscale.scene import Scene

MAT = Material(E=10.0, nu=0.5)
BLOCK = {"kind": "block", "size": (40.0, 40.0, 5.0), "base": "bonded", "source_spacing": 2.0}
D = 0.5


def _scene(rise: float, influence=None) -> Scene:
    tips = (Asperity(x=0.0, y=0.0, z=0.0, R=10.0), Asperity(x=6.0, y=0.0, z=D + rise, R=10.0))
    return Scene(material=MAT, asperities=tips, penetration=D, influence=influence or BLOCK, h=0.1)


def _pressure_on(grid: Grid, result) -> np.ndarray:
    """The result's pressure fields placed on ``grid`` (same cell size; cells outside it dropped)."""
    X, Y = grid.centres()
    p = np.zeros(grid.shape)
    for f in result.fields:
        fx, fy = f.grid.centres()
        cols = np.rint((fx[0] - X[0, 0]) / grid.h).astype(int)
        rows = np.rint((fy[:, 0] - Y[0, 0]) / grid.h).astype(int)
        keep_r, keep_c = (rows >= 0) & (rows < grid.ny), (cols >= 0) & (cols < grid.nx)
        p[np.ix_(rows[keep_r], cols[keep_c])] += f.pressure[np.ix_(keep_r, keep_c)]
    return p


def _apex_gap(scene: Scene, result) -> float:
    """``z + u - d`` at the second tip's apex, ``u`` by the body's grid operator from the
    result's pressure placed on a grid covering both tips."""
    grid = Grid.covering(-3.0, 8.0, -3.0, 3.0, result.fields[0].grid.h)
    X, Y = grid.centres()
    p = _pressure_on(grid, result)
    provider = scene.provider(progress=False) if scene.influence["kind"] == "block" else scene.provider()
    u = provider.grid_operator(grid).apply(p)
    i, j = int(np.argmin(np.abs(Y[:, 0]))), int(np.argmin(np.abs(X[0] - 6.0)))
    return float(scene.asperities[1].z + u[i, j] - result.penetration)


def _warned(scene: Scene, method: str, provider=None, **options):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        opts = {"progress": False} if scene.influence["kind"] == "block" and provider is None else None
        result = twoscale.solve(scene, method=method, provider=provider, provider_options=opts, **options)
    return result, [w for w in caught if issubclass(w.category, BulgeWarning)]


def _covering(scene: Scene):
    """The constrained CG on a grid covering both tips (the whole problem at once)."""
    return solve_reference(
        scene.provider(progress=False),
        surface_on(Grid.covering(-3.0, 8.0, -3.0, 3.0, 0.1), scene.asperities),
        penetration=D,
        method="cg",
        tol=1e-10,
    )


def _blind(provider):
    """``provider`` whose point compliance (the macro step's; the check takes the loaded
    cells near an apex cell by cell) is never negative: a macro step blind to the rise,
    which leaves the lifted tip out."""
    base = type(provider)

    class Blind(base):
        def point_compliance(self, targets, sources):
            return np.maximum(base.point_compliance(self, targets, sources), 0.0)

    blind = copy.copy(provider)
    object.__setattr__(blind, "__class__", Blind)
    return blind


@pytest.fixture(autouse=True)
def _cache(tmp_path, monkeypatch):
    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path))


@pytest.mark.parametrize("iteration", ["auto", "block-gs", "two-level"])
def test_the_two_scale_solve_takes_the_lifted_tip_in(iteration):
    """The macro step's local approach lifts the second tip into contact (its point
    compliance is negative 6 mm away): it gets a patch, and every micro iteration gives
    both tips the covering grid's forces, with no second micro step and no warning. The
    same lattice: only the iterations' tolerances part them."""
    scene = _scene(0.010)
    result, found = _warned(scene, "twoscale", iteration=iteration)
    covering = _covering(scene)
    assert covering.forces[1] > 1e-3 * covering.forces[0]  # it touches
    assert result.forces[1] == pytest.approx(covering.forces[1], rel=1e-4)
    assert result.forces[0] == pytest.approx(covering.forces[0], rel=1e-6)
    assert result.details.bulge == BulgeDetails(rounds=0, taken=(1,))
    assert found == [] and abs(_apex_gap(scene, result)) < 1e-6


@pytest.mark.parametrize("iteration", ["auto", "block-gs", "two-level"])
def test_a_tip_the_macro_step_misses_is_taken_in_by_a_second_micro_step(iteration):
    """With a macro step blind to the rise the first micro step leaves the second tip out;
    the answer's check finds its apex in the solved surface, and the micro step solved again
    with its patch gives the covering grid's forces."""
    scene = _scene(0.010)
    result, found = _warned(scene, "twoscale", provider=_blind(scene.provider(progress=False)), iteration=iteration)
    assert result.details.macro.forces[1] == 0.0  # the macro step left it out
    covering = _covering(scene)
    assert result.forces[1] == pytest.approx(covering.forces[1], rel=1e-4)
    assert result.forces[0] == pytest.approx(covering.forces[0], rel=1e-6)
    assert result.details.bulge == BulgeDetails(rounds=1, taken=(1,))
    assert found == [] and abs(_apex_gap(scene, result)) < 1e-6


def test_a_tip_still_lifted_after_the_rounds_is_named():
    """No round allowed: the blind macro step's answer lacks the second tip's contact, and
    the warning names it from the solve's own check."""
    scene = _scene(0.010)
    with mock.patch.object(rounds, "SETTLE_ROUNDS", 0):
        result, found = _warned(scene, "twoscale", provider=_blind(scene.provider(progress=False)))
    assert result.forces[1] == 0.0 and _apex_gap(scene, result) < -0.005  # left out, yet 5+ um in
    assert result.details.bulge.left == (1,) and result.details.bulge.rounds == 0
    assert len(found) == 1 and "tip 2 at (6, 0) mm" in str(found[0].message)


def test_the_reference_takes_the_lifted_tip_in():
    """The reference grows its grid by the rise and holds the second tip's contact: its
    force is that of the CG on a hand-built grid covering both tips (the whole problem at
    once), and its apex's gap is closed."""
    scene = _scene(0.010)
    result, found = _warned(scene, "reference")
    covering = _covering(scene)
    assert covering.forces[1] > 1e-3 * covering.forces[0]  # it touches
    assert result.forces[1] == pytest.approx(covering.forces[1], rel=1e-5)
    assert result.forces[0] == pytest.approx(covering.forces[0], rel=1e-8)
    assert found == [] and abs(_apex_gap(scene, result)) < 1e-6


def test_a_tip_beyond_the_bulge_or_on_the_half_space_is_not():
    high = _scene(0.040)
    result, found = _warned(high, "twoscale")
    assert _apex_gap(high, result) > 0.005 and found == []
    flat = _scene(0.010, influence={"kind": "halfspace"})
    result, found = _warned(flat, "twoscale")
    assert _apex_gap(flat, result) > 0.005 and found == []


def test_the_dense_reference_on_a_block_solves_the_blocks_own_matrix():
    """A block's cell matrix is reciprocal only to ~1e-3 (sources on the mesh, receivers
    interpolated). Johnson's dense iteration on the grid covering both tips must solve that
    matrix (not the symmetric one its upper triangle spells) and settle: its forces are the
    CG's on the same grid, whose products are the body's operator, and its active set
    settles in a few passes although the bulge adds hundreds of cells at once."""
    scene = _scene(0.010)
    provider = scene.provider(progress=False)
    surface = surface_on(Grid.covering(-3.0, 8.0, -3.0, 3.0, 0.25), scene.asperities)
    cg = solve_reference(provider, surface, penetration=D, method="cg", tol=1e-10)
    dense = solve_reference(provider, surface, penetration=D, method="dense", tol=1e-10)
    assert dense.converged and dense.iterations["outer"] <= 20
    assert dense.forces[1] > 1e-3 * dense.forces[0]
    np.testing.assert_allclose(dense.forces, cg.forces, rtol=1e-6)


def test_an_unsymmetric_matrix_is_solved_as_it_is():
    """Cholesky reads one triangle: on a matrix whose upper triangle is that of a positive
    definite one but whose lower is not, only LU gives ``A x = b``."""
    from twoscale.reference.dense import _factor_solve, is_symmetric

    rng = np.random.default_rng(3)
    M = rng.standard_normal((40, 40))
    A = M @ M.T + 40 * np.eye(40)
    A[np.tril_indices(40, -1)] *= 1.01
    b = rng.standard_normal(40)
    assert not is_symmetric(A) and is_symmetric(M @ M.T)
    x = _factor_solve(A, b, is_symmetric(A))
    np.testing.assert_allclose(A @ x, b, atol=1e-10)


def test_least_index_moves_reach_the_complementary_solution():
    """Murty's rule (the dense iteration's guard against a repeated set on a matrix that is
    not symmetric) ends on the one active set whose pressures and gaps satisfy the
    conditions, found here by trying all 2^8 sets."""
    from itertools import product

    from twoscale.reference.dense import _least_index_move

    rng = np.random.default_rng(7)
    n, d = 8, 1.0
    M = rng.standard_normal((n, n))
    A = M @ M.T / n + np.eye(n) + 0.2 * rng.standard_normal((n, n))  # positive definite symmetric part
    z = rng.uniform(0.0, 2.0, n)
    B = np.zeros((n, 0))

    def solve(S):
        q = np.zeros(n)
        q[S] = np.linalg.solve(A[np.ix_(S, S)], d - z[S]) if S.size else []
        return q

    exact = []
    for bits in product([False, True], repeat=n):
        S = np.flatnonzero(bits)
        q = solve(S)
        gap = z + A @ q - d
        if np.all(q >= -1e-12) and np.all(gap[~np.array(bits)] >= -1e-12):
            exact.append(q)
    assert len(exact) == 1
    active = np.zeros(n, dtype=bool)
    for _ in range(2**n):
        S = np.flatnonzero(active)
        if not _least_index_move(A, z, B, d, S, solve(S)[S], np.zeros(0), active, 1e-12):
            break
    np.testing.assert_allclose(solve(np.flatnonzero(active)), exact[0], atol=1e-12)


def test_a_block_scene_where_nothing_is_lifted_is_solved_as_without_the_check():
    """The apex 40 um above: the macro step lifts no tip and the check finds none, so the
    micro step runs once and the answer is, bit for bit, the solve made without either."""
    scene = _scene(0.040)
    provider = scene.provider(progress=False)
    with mock.patch.object(driver, "run_micro", wraps=driver.run_micro) as micro:
        result, found = _warned(scene, "twoscale", provider=provider)
    assert micro.call_count == 1 and found == []
    assert result.details.bulge == BulgeDetails()
    with mock.patch.object(driver, "rises", return_value=False):
        plain = twoscale.solve(scene, provider=provider)
    assert plain.details.bulge is None
    assert np.array_equal(result.forces, plain.forces) and result.penetration == plain.penetration
    for f, g in zip(result.fields, plain.fields, strict=True):
        assert f.grid == g.grid and np.array_equal(f.pressure, g.pressure)


def test_the_half_space_never_runs_the_check():
    scene = _scene(0.010, influence={"kind": "halfspace"})
    with (
        mock.patch.object(rounds, "lifted_among", side_effect=AssertionError("checked")),
        mock.patch.object(driver, "run_micro", wraps=driver.run_micro) as micro,
    ):
        result = twoscale.solve(scene, iteration="auto")  # an option: the two-scale solver itself
    assert micro.call_count == 1 and result.details.bulge is None and result.forces[1] == 0.0


def test_result_json_names_the_tips_the_bulge_lifted():
    # a tip 1 um above the approach, 12 mm from a deep contact on a bonded 10 mm block: only
    # the rising surface can load it; result.json must say so, numbered from 1
    from helpers import small_block

    from twoscale.io.result_json import result_to_dict

    d = 0.8
    scene = Scene(
        material=MAT, asperities=(Asperity(0.0, 0.0, 0.0, 10.0), Asperity(12.0, 0.0, d + 0.001, 10.0)), penetration=d
    )
    res = twoscale.solve(scene, provider=small_block(MAT), h=0.1)
    lifted = [k + 1 for k, a in enumerate(scene.asperities) if a.z > d and res.asperities.forces[k] > 0]
    record = result_to_dict(res, scene)["bulge"]
    assert lifted == [2] and record["taken"] == lifted and record["left"] == []
    on_half_space = twoscale.solve(scene, h=0.1)
    assert "bulge" not in result_to_dict(on_half_space, scene)


def test_the_reference_names_a_tip_still_lifted_after_its_rounds(monkeypatch):
    """Without a round to grow its grid, the reference's scene solve leaves the lifted tip out
    and says so itself, once (the one-shot solve does not check its answer again)."""
    import twoscale.bulge as bulge

    monkeypatch.setattr(bulge, "SETTLE_ROUNDS", 0)
    result, found = _warned(_scene(0.010), "reference")
    assert result.forces[1] == 0.0
    assert len(found) == 1 and "tip 2 at (6, 0) mm" in str(found[0].message)


@pytest.mark.parametrize("route", ["split", "whole"])
def test_the_apex_displacement_is_the_body_grid_operators(route, monkeypatch):
    """The check's displacement at points the solved pressure does not load, against the
    body's grid operator on a grid covering both tips (FFT and the correction's grid
    factors). ``split``: the half-space's cell blocks near the points in one call, the
    block's smooth part from every loaded cell at once; ``whole``: the provider's own cell
    blocks point by point (a body without a low-rank part). Every point lies within the
    check's reach of the loaded tip, so no resultant stands in for its cells: the same
    sums, to rounding."""
    import twoscale.bulge as bulge

    scene = _scene(0.040)
    provider = scene.provider(progress=False)
    result = twoscale.solve(scene, provider=provider)
    grid = Grid.covering(-4.0, 8.0, -4.0, 4.0, result.fields[0].grid.h)
    X, Y = grid.centres()
    p = _pressure_on(grid, result)
    u = provider.grid_operator(grid).apply(p)
    picks = [(i, j) for i in (3, 40, 77) for j in (5, 70, 100) if p[i, j] == 0.0]
    apexes = np.array([[X[i, j], Y[i, j]] for i, j in picks])
    if route == "whole":
        monkeypatch.setattr(type(provider), "split", lambda self: (self, None))
    got = bulge._apex_displacement(provider, result, apexes)
    want = np.array([u[i, j] for i, j in picks])
    assert len(picks) >= 6 and np.max(np.abs(want)) > 1e-3
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.max(np.abs(u)))
