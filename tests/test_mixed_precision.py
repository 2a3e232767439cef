"""Single-precision factors refined in double precision: the double-precision answer, or
None where single precision cannot give it."""

import numpy as np

from twoscale.mixed_precision import refined_solve


def _spd(n, cond, seed):
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return (Q * np.geomspace(1.0, 1.0 / cond, n)) @ Q.T


def test_refined_cholesky_gives_the_double_precision_solution_for_every_column():
    K = _spd(300, 1e4, 1)
    rhs = np.random.default_rng(2).normal(size=(300, 3)) * [1.0, 1e-30, 1e20]  # scales apart
    x = refined_solve(K, rhs, definite=True)
    exact = np.linalg.solve(K, rhs)
    assert x is not None
    err = np.max(np.abs(x - exact), axis=0) / np.max(np.abs(exact), axis=0)
    assert np.all(err <= 1e-11)
    plain = np.linalg.solve(K.astype(np.float32), rhs[:, 0].astype(np.float32))
    assert np.max(np.abs(plain - exact[:, 0])) > 1e-8 * np.max(np.abs(exact[:, 0]))  # refinement needed


def test_none_where_single_precision_cannot_serve():
    # not positive definite for Cholesky; too ill-conditioned for single precision to converge
    K = _spd(50, 10.0, 3)
    K[0, 0] = -1.0
    assert refined_solve(K, np.ones(50), definite=True) is None
    bad = _spd(200, 1e12, 4)
    assert refined_solve(bad, np.ones(200), definite=False) is None
    assert refined_solve(np.zeros((0, 0)), np.zeros(0)).shape == (0,)


def test_the_tolerance_norm_by_blocks_of_rows_is_numpys_whole_array_norm():
    # the largest row sum of |K| taken a few rows at a time: the same number as numpy's
    # sum over the whole |K| (each row summed alike), on shapes around the block's rows
    from twoscale.mixed_precision import NORM_BLOCK_ENTRIES, inf_norm

    rng = np.random.default_rng(5)
    for n in (1, 3, 255, 256, 257, 1000, NORM_BLOCK_ENTRIES + 1):
        rows = n if n <= 1000 else 3
        K = rng.normal(size=(rows, n)) * np.geomspace(1e-8, 1e8, n)
        assert inf_norm(K) == float(np.max(np.sum(np.abs(K), axis=1)))
    F = np.asfortranarray(rng.normal(size=(300, 300)))
    assert inf_norm(F) == float(np.max(np.sum(np.abs(F), axis=1)))
    assert inf_norm(F) == np.linalg.norm(F, np.inf)


def test_the_single_precision_factor_made_in_place_leaves_k_and_solves_as_before():
    # the factor works on a column-ordered single-precision copy: K is not changed, and the
    # answer is the double-precision solve's (LU and Cholesky)
    K = _spd(400, 1e3, 6)
    general = K + np.triu(np.random.default_rng(7).normal(size=(400, 400)) * 1e-3, 1)
    rhs = np.random.default_rng(8).normal(size=400)
    for M, definite in ((K, True), (general, False)):
        kept = M.copy()
        x = refined_solve(M, rhs, definite=definite)
        assert np.array_equal(M, kept)
        exact = np.linalg.solve(M, rhs)
        assert np.max(np.abs(x - exact)) <= 1e-11 * np.max(np.abs(exact))
