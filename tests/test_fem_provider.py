"""BlockProvider on a small block: contract consistency, reciprocity, interpolation, cache.

A 60 x 60 x 10 mm block meshed at 5-10 mm keeps these tests to seconds; the
validation against docs/method.md section 6 on the 140 x 140 x 20 mm block is in
test_fem_block_validation.py (slow).
"""

import numpy as np
import pytest

from fem_influence import BlockProvider
from fem_influence.correction import CorrectionSolver
from twoscale.grid import Grid
from twoscale.influence.halfspace import HalfSpace
from twoscale.material import Material

MAT = Material(E=2.0, nu=0.5)
SMALL = dict(size=(60.0, 60.0, 10.0), h_fine=5.0, h_coarse=10.0, fine_half_width=10.0)


@pytest.fixture(scope="module")
def block():
    return BlockProvider(material=MAT, use_cache=False, progress=False, **SMALL)


def test_kind_and_contract(block):
    assert block.kind == "block"
    t = np.array([[3.0, 1.0], [-2.0, 4.0]])
    s = np.array([[0.0, 0.0], [1.0, -1.0], [2.5, 2.5]])
    K = block.point_compliance(t, s)
    assert K.shape == (2, 3)
    np.testing.assert_allclose(K - HalfSpace(MAT).point_compliance(t, s), block.correction(t, s), rtol=1e-12)
    assert np.isinf(block.point_compliance(s[:1], s[:1])[0, 0])


def test_bonded_block_is_stiffer(block):
    # a bonded incompressible block removes compliance: C < 0, fading with distance
    r = np.array([[2.0, 0.0], [5.0, 0.0], [10.0, 0.0]])
    C = block.correction(r, np.zeros((1, 2)))[:, 0]
    assert np.all(C < 0) and np.all(np.diff(C) > 0)


def test_small_block_against_layer_theory(block):
    # sides 3 thicknesses away: the centre of a 60 x 60 x 10 block is close to an
    # infinite 10 mm layer (independent Hankel-transform solution) for r <= t
    from fem_influence.layer import point_ratio

    r = np.array([1.0, 2.5, 5.0, 10.0])
    C = block.correction(np.column_stack([r, 0 * r]), np.zeros((1, 2)))[:, 0]
    C_layer = (point_ratio(r, 10.0, 0.5) - 1.0) / (np.pi * MAT.E_star * r)
    np.testing.assert_allclose(C, C_layer, atol=0.03 * np.abs(C_layer).max())


def test_reciprocity(block):
    # Betti: C(x, x') = C(x', x); the two sides come from different solves and interpolations,
    # so they agree only to the discretisation error (a few % of |C| at 5 mm elements)
    pts = np.array([[0.0, 0.0], [7.0, 3.0], [-4.0, 6.0], [12.0, -9.0]])
    C = block.correction(pts, pts)
    np.testing.assert_allclose(C, C.T, atol=0.03 * np.abs(C).max())


def test_source_interpolation_error(block):
    # off-lattice sources: lattice (cubic) interpolation vs a direct solve at the exact
    # source; halving the spacing must cut the error by ~2^4, and at spacing/thickness
    # = 0.25 (the default 5 mm on 20 mm) it must be below 0.2 % of |C|
    from scipy.interpolate import CloughTocher2DInterpolator

    solver = CorrectionSolver.build(block.mesh, MAT.nu, "bonded")
    srcs = np.array([[2.3, -1.7], [1.25, 1.25], [6.2, 3.9]])
    tgt = np.array([[0.0, 0.0], [5.0, 5.0], [-8.0, 2.0], [2.3, -1.7]])
    direct = solver.top_displacement(srcs) / MAT.E
    errs = []
    for d in (5.0, 2.5):
        prov = BlockProvider(material=MAT, mesh=block.mesh, source_spacing=d, use_cache=False, progress=False)
        e = 0.0
        for k, s in enumerate(srcs):
            ref = CloughTocher2DInterpolator(solver.top_xy, direct[k])(tgt)
            e = max(e, np.abs(prov.correction(tgt, s[None])[:, 0] - ref).max() / np.abs(ref).max())
        errs.append(e)
    assert errs[1] < 2e-3
    assert np.log2(errs[0] / errs[1]) > 3.0


def test_cell_block_grid_matrix_operator_agree(block):
    g = Grid(-3.0, -2.0, 0.5, 9, 7)
    sub = g.subgrid(2, 1, 4, 3)
    dense = block.grid_matrix(g)
    np.testing.assert_allclose(dense, block.cell_block(g.points(), g.points(), g.h), rtol=1e-12)
    p = np.random.default_rng(1).random(g.shape)
    np.testing.assert_allclose(block.grid_operator(g).apply(p).ravel(), dense @ p.ravel(), rtol=1e-10)
    ps = p[1:4, 2:6]
    np.testing.assert_allclose(
        block.grid_operator(g, sub).apply(ps).ravel(), block.grid_matrix(g, sub) @ ps.ravel(), rtol=1e-10
    )


def test_self_compliance_is_diagonal(block):
    pts = np.array([[0.0, 0.0], [4.0, -3.0], [1.0, 1.0], [-6.0, 2.0], [3.0, 8.0]])
    np.testing.assert_allclose(block.smooth_self_compliance(pts), np.diag(block.correction(pts, pts)), rtol=1e-12)
    assert np.all(block.smooth_self_compliance(pts) < 0)


def test_origin_shifts_the_scene(block):
    shifted = BlockProvider(material=MAT, origin=(4.0, -2.0), mesh=block.mesh, use_cache=False, progress=False)
    t, s = np.array([[1.0, 2.0], [-3.0, 0.5]]), np.array([[0.0, 0.0], [2.0, 1.0]])
    np.testing.assert_allclose(shifted.correction(t, s), block.correction(t + [4.0, -2.0], s + [4.0, -2.0]), rtol=1e-12)


def test_modulus_scaling(block):
    soft = BlockProvider(material=Material(E=1.0, nu=0.5), mesh=block.mesh, use_cache=False, progress=False)
    t, s = np.array([[5.0, 0.0]]), np.array([[0.0, 0.0]])
    np.testing.assert_allclose(soft.correction(t, s), 2.0 * block.correction(t, s), rtol=1e-12)


def test_disk_cache_roundtrip(tmp_path, monkeypatch):
    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path))
    t, s = np.array([[5.0, 0.0], [0.0, 9.0]]), np.array([[0.0, 0.0], [1.0, 2.0]])
    cold = BlockProvider(material=MAT, progress=False, **SMALL)
    C1 = cold.correction(t, s)
    assert cold._state.solver is not None
    files = list(tmp_path.glob("block-*.npz"))
    assert len(files) == 1
    warm = BlockProvider(material=MAT, progress=False, **SMALL)
    C2 = warm.correction(t, s)
    assert warm._state.solver is None  # nothing solved, nothing factorised
    np.testing.assert_array_equal(C1, C2)
    other = BlockProvider(material=Material(2.0, 0.45), progress=False, **SMALL)
    assert other._state.fields.key != warm._state.fields.key
    sliding = BlockProvider(material=MAT, base="sliding", progress=False, **SMALL)
    assert sliding._state.fields.key != warm._state.fields.key


def test_invalid_inputs():
    with pytest.raises(ValueError, match="base"):
        BlockProvider(material=MAT, base="glued", use_cache=False, **SMALL)
    with pytest.raises(ValueError, match="origin"):
        BlockProvider(material=MAT, origin=(40.0, 0.0), use_cache=False, **SMALL)
    with pytest.raises(ValueError, match="size"):
        BlockProvider(material=MAT, size=(60.0, 0.0, 10.0), use_cache=False)
    with pytest.raises(ValueError, match="nu"):
        BlockProvider(material=Material(1.0, 0.0), use_cache=False, **SMALL)


def test_nu_half_against_nearly_half(block):
    # the mixed form is continuous in 1/lambda: nu = 0.4999 must agree with 0.5 within 0.5 %
    # (layer theory puts the true difference near 0.02 % here)
    near = BlockProvider(material=Material(E=2.0, nu=0.4999), mesh=block.mesh, use_cache=False, progress=False)
    t = np.array([[2.5, 0.0], [5.0, 0.0], [10.0, 0.0], [7.0, 7.0]])
    s = np.zeros((1, 2))
    np.testing.assert_allclose(near.point_compliance(t, s), block.point_compliance(t, s), rtol=5e-3)
    np.testing.assert_allclose(near.correction(t, s), block.correction(t, s), rtol=5e-3)


def test_user_mesh_file(block, tmp_path):
    from meshes import write_block_mesh

    path = tmp_path / "user.vtu"
    write_block_mesh(block.mesh, path)
    user = BlockProvider(material=MAT, mesh=str(path), use_cache=False, progress=False)
    assert user.size == pytest.approx((60.0, 60.0, 10.0))
    t, s = np.array([[5.0, 0.0], [0.0, -7.0]]), np.array([[0.0, 0.0], [2.0, 1.0]])
    # same block and nodes, but renumbered: the Delaunay triangulation of the top-face
    # nodes (a rectilinear grid, so co-circular quadruples) may pick other diagonals,
    # which moves the Clough-Tocher target interpolation by ~1e-4 relative
    np.testing.assert_allclose(user.correction(t, s), block.correction(t, s), rtol=1e-3)


def test_mirror_symmetry_matches_direct_solves(block):
    # the default mesh is mirror-symmetric: fields of sources with negative lattice
    # indices are read at mirrored nodes instead of solved; compare with solving them
    plain = BlockProvider(material=MAT, mesh=block.mesh, use_symmetry=False, use_cache=False, progress=False)
    sym = BlockProvider(material=MAT, mesh=block.mesh, use_cache=False, progress=False)
    t = np.array([[3.0, -4.0], [-6.0, 2.0], [0.5, 0.5]])
    s = np.array([[-7.0, -3.0], [4.0, -8.0], [-1.0, 6.0]])
    np.testing.assert_allclose(sym.correction(t, s), plain.correction(t, s), rtol=1e-6, atol=1e-9)
    n_solved = sum(1 for i, j in sym._state.fields.fields if i >= 0 and j >= 0)
    assert n_solved < len(sym._state.fields.fields)


def test_sources_near_the_sides_are_refused(block):
    # the lattice stops one spacing (5 mm) inside the 30 mm half-width: a source at
    # x = 27 would be extrapolated (measured error ~20 % of |C|), so it is refused
    assert np.isfinite(block.correction(np.zeros((1, 2)), np.array([[25.0, -25.0]]))).all()
    with pytest.raises(ValueError, match="outside the block.s answered region"):
        block.correction(np.zeros((1, 2)), np.array([[27.0, 0.0]]))


def test_solver_residuals_are_small(block):
    solver = CorrectionSolver.build(block.mesh, MAT.nu, "sliding")
    solver.top_displacement(np.array([[0.0, 0.0], [5.0, -5.0]]))
    assert len(solver.residuals) == 2 and max(solver.residuals) < 1e-8


def test_tilt_on_the_block_matches_the_reference(block):
    # Pivot on tip 0 of a bonded 10 mm block: the macro step puts the whole load on tip 0
    # (point forces balance any tilt that lifts the others); the two-scale answer must
    # still be the full-grid reference's, which solves its own tilt (before the micro step
    # covered asperities the macro step left out, it returned [W, 0, 0] as converged).
    from twoscale.indenters import Asperity, surface_on
    from twoscale.reference import solve_cg
    from twoscale.driver import solve_twoscale

    asp = [Asperity(0.0, 0.0, 0.0, 5.0), Asperity(8.0, 0.0, 0.0, 5.0), Asperity(0.0, 8.0, 0.0, 4.0)]
    h, W = 0.1, 4.0
    res = solve_twoscale(block, asp, h=h, total_load=W, tilt=True, tol=1e-9)
    assert res.converged, res.message
    ref = solve_cg(block, surface_on(Grid.covering(-6.0, 14.0, -6.0, 14.0, h), asp), total_load=W, tilt=True, tol=1e-10)
    assert ref.converged
    Fr = np.asarray(ref.asperities.forces)
    assert Fr[1] > 0.01 * W and Fr[2] > 0.01 * W
    assert np.max(np.abs(np.asarray(res.asperities.forces) - Fr)) <= 1e-5 * W
    assert np.allclose(res.tilt, ref.tilt, rtol=1e-4)


def test_point_operator_is_the_dense_sum_with_exclusions_and_coincident_points(block):
    # above the dense operator's size the block's point sums are the half-space's Ewald
    # operator plus the low-rank correction less the pairs left out; the default operator
    # (every pair's compliance, exact) is the independent answer
    import scipy.sparse as sp

    from fem_influence.operators import BlockPointOperator
    from twoscale.influence.points import KEEP_ENTRIES, DensePointOperator

    rng = np.random.default_rng(4)
    s = rng.uniform(-22.0, 22.0, (2000, 2))
    t = np.concatenate([rng.uniform(-22.0, 22.0, (1800, 2)), s[:300]])  # 300 targets on sources
    assert len(t) * len(s) > KEEP_ENTRIES
    exclude = sp.random(len(t), len(s), density=0.003, random_state=5, format="csr")
    F = rng.uniform(0.1, 1.0, (len(s), 2))
    fast = block.point_operator(t, s, exclude=exclude, rtol=1e-10)
    assert isinstance(fast, BlockPointOperator)
    exact = DensePointOperator(block.point_compliance, t, s, exclude).apply(F)
    assert np.max(np.abs(fast.apply(F) - exact)) <= 1e-8 * np.max(np.abs(exact))
    # (the correction of the pairs left out, were it kept, moves the sum by 1.4 % of its largest)


def test_correction_factors_are_not_kept_dense_per_grid(block):
    # the correction on a grid from all lattice nodes stays factored (sparse interpolation
    # times the shared table), and gives the dense evaluation
    from twoscale.influence.base import LowRankCorrection

    g = Grid(-3.0, -2.0, 0.25, 40, 36)
    _, corr = block.split()
    assert isinstance(corr, LowRankCorrection)
    p = np.random.default_rng(2).random(g.shape)
    c = corr.coefficients(g, p)
    u = corr.evaluate(g, c)
    np.testing.assert_allclose(u.ravel(), g.h**2 * block.correction(g.points(), g.points()) @ p.ravel(), rtol=1e-10)
    factor = block._target_factor(g)  # 9 interpolation weights a cell, the table's rows of the nodes used
    table = block._state.table
    assert factor.M.nnz <= 9 * g.size and factor.M.shape == (g.size, factor.T.shape[0])
    assert factor.T.shape[1] == table.shape[1] and factor.T.shape[0] < table.shape[0] < g.size


def test_the_last_sources_weights_are_kept_and_answer_as_made_afresh(block):
    # the correction from the same sources asked for again (their weights kept on the
    # provider), and from other sources of the same count, against a provider that makes
    # every weight afresh (a kept set taken for another of its size would be 1e-3 off)
    from fem_influence.operators import point_weights

    rng = np.random.default_rng(3)
    s = rng.uniform(-15.0, 15.0, (40, 2))
    moved = s + 1.5
    t = rng.uniform(-15.0, 15.0, (7, 2))
    fresh = BlockProvider(material=MAT, mesh=block.mesh, use_cache=False, progress=False)
    expected = fresh.correction(t, s)
    block.correction(t, s)
    assert point_weights(block, s) is point_weights(block, s.copy())
    # (to rounding: the module's block has solved other lattice nodes, in another order)
    close = dict(rtol=1e-12, atol=1e-14 * np.abs(expected).max())
    rows = np.vstack([block.correction(t[a : a + 3], s) for a in range(0, len(t), 3)])
    np.testing.assert_allclose(rows, expected, **close)
    other = fresh.correction(t, moved)
    np.testing.assert_allclose(block.correction(t, moved), other, **close)
    assert np.abs(other - expected).max() > 1e-3 * np.abs(expected).max()
