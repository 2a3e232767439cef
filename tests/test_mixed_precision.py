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
