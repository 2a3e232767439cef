"""Point operators (sums of point-force displacements): the exact chunked default against
a direct double loop, the half-space Ewald operator against the default, validation."""

import math

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.spatial import cKDTree

from twoscale import Material
from twoscale.influence.halfspace import HalfSpace
from twoscale.influence.halfspace_points import EwaldParameters, EwaldPointOperator
from twoscale.influence.points import DensePointOperator

MAT = Material(10.0, 0.3)
HS = HalfSpace(MAT)


def clustered(n, rng, size=300.0, clusters=15):
    """``n`` points (mm) in clusters of widths 0.5-20 mm over a ``size`` square."""
    centres = rng.uniform(0.0, size, (clusters, 2))
    widths = rng.uniform(0.5, 20.0, clusters)
    k = rng.integers(0, clusters, n)
    return centres[k] + rng.normal(size=(n, 2)) * widths[k, None]


def make_scene():
    """3000 sources (a few doubled), 5000 targets of which 1000 sit on sources, and an
    exclude pattern mixing random far pairs with each target's 4 nearest sources."""
    rng = np.random.default_rng(7)
    s = clustered(3000, rng)
    s[-20:] = s[:20]  # coincident sources
    t = np.concatenate([clustered(4000, rng), s[rng.choice(3000, 1000, replace=False)]])
    _, nearest = cKDTree(s).query(t, k=4)
    rows = np.repeat(np.arange(len(t)), 4)
    near = sp.csr_matrix((np.ones(rows.size), (rows, nearest.ravel())), shape=(len(t), len(s)))
    far = sp.random(len(t), len(s), density=0.002, random_state=3, format="csr")
    exclude = (near + far).tocsr()
    F = rng.uniform(0.1, 1.0, (len(s), 3))  # forces of one sign
    u = DensePointOperator(HS.point_compliance, t, s, exclude).apply(F)
    return t, s, exclude, F, u


@pytest.fixture(scope="module")
def scene():
    return make_scene()


def rel_error(u, ref):
    return float(np.max(np.abs(u - ref)) / np.max(np.abs(ref)))


def test_dense_matches_double_loop():
    t = np.array([[0.0, 0.0], [1.0, 0.5], [3.0, -2.0], [0.2, 0.1]])
    s = np.array([[0.0, 0.0], [2.0, 1.0], [-1.0, 4.0]])
    exclude = sp.coo_matrix(([5.0, -1.0], ([1, 2], [1, 0])), shape=(4, 3))  # values ignored
    F = np.array([1.0, -2.0, 0.5])
    u = np.zeros(4)
    for i in range(4):
        for j in range(3):
            r = math.hypot(*(t[i] - s[j]))
            if r > 0 and (i, j) not in [(1, 1), (2, 0)]:
                u[i] += F[j] / (math.pi * MAT.E_star * r)
    op = DensePointOperator(HS.point_compliance, t, s, exclude)
    np.testing.assert_allclose(op.apply(F), u, rtol=1e-14)
    np.testing.assert_allclose(op.apply(np.c_[F, 2 * F]), np.c_[u, 2 * u], rtol=1e-14)


@pytest.mark.parametrize("rtol", [1e-4, 1e-6])
def test_ewald_matches_dense(scene, rtol):
    t, s, exclude, F, u = scene
    op = HS.point_operator(t, s, exclude=exclude, rtol=rtol)
    assert isinstance(op, EwaldPointOperator)
    assert rel_error(op.apply(F), u) <= rtol
    u1 = op.apply(F[:, 0])
    assert u1.shape == (len(t),)
    assert rel_error(u1, u[:, 0]) <= rtol


def test_ewald_error_falls_with_rtol(scene):
    t, s, exclude, F, u = scene
    errors = [
        rel_error(EwaldPointOperator(MAT.E_star, t, s, exclude=exclude, rtol=r).apply(F), u)
        for r in (1e-2, 1e-4, 1e-6, 1e-8)
    ]
    assert all(e <= r for e, r in zip(errors, (1e-2, 1e-4, 1e-6, 1e-8)))
    assert all(b < 0.1 * a for a, b in zip(errors, errors[1:]))


def test_comparison_detects_a_coarse_mesh(scene):
    # The same check fails for an operator whose mesh is too coarse for rtol = 1e-4,
    # so the comparisons above are not vacuous.
    t, s, exclude, F, u = scene
    coarse = EwaldParameters(sigma=5.0, spacing=5.0, order=4, r_cut=20.0, error_bound=math.nan)
    op = EwaldPointOperator(MAT.E_star, t, s, exclude=exclude, rtol=1e-4, params=coarse)
    assert rel_error(op.apply(F), u) > 1e-4


def test_ewald_pair_error_within_bound():
    # One source, targets at all distances: |u - G| <= error_bound * G pair by pair
    # (the bound behind the rtol guarantee; checks the measured Lagrange table).
    rng = np.random.default_rng(1)
    for rtol in (1e-3, 1e-6):
        src = rng.uniform(0.0, 1.0, (1, 2))
        r = np.geomspace(1e-3, 200.0, 3000)
        th = rng.uniform(0.0, 2 * np.pi, r.size)
        t = src + np.c_[r * np.cos(th), r * np.sin(th)]
        op = EwaldPointOperator(MAT.E_star, t, np.r_[src, [[300.0, 300.0]]], rtol=rtol)
        G = 1.0 / (math.pi * MAT.E_star * np.hypot(*(t - src).T))
        err = np.abs(op.apply(np.array([1.0, 0.0])) - G) / G
        assert err.max() <= op.params.error_bound <= rtol


def test_halfspace_dispatch_by_size():
    rng = np.random.default_rng(2)
    small = rng.uniform(0, 10, (100, 2))
    assert isinstance(HS.point_operator(small, small), DensePointOperator)
    big = rng.uniform(0, 300, (2100, 2))
    op = HS.point_operator(big, big)
    assert isinstance(op, EwaldPointOperator)
    F = rng.uniform(0, 1, 2100)
    ref = DensePointOperator(HS.point_compliance, big, big).apply(F)
    assert rel_error(op.apply(F), ref) <= 1e-6


@pytest.mark.parametrize(
    "make",
    [
        lambda: EwaldPointOperator(MAT.E_star, np.zeros((5, 3)), np.zeros((4, 2))),
        lambda: HS.point_operator(np.zeros((5, 2)), np.zeros(4)),
        lambda: EwaldPointOperator(MAT.E_star, np.zeros((5, 2)), [[0.0, np.nan]]),
    ],
)
def test_bad_points_raise(make):
    with pytest.raises(ValueError, match="targets|sources"):
        make()


@pytest.mark.parametrize("rtol", [0.0, 1.0, -1e-3, math.nan, math.inf])
def test_bad_rtol_raises(rtol):
    pts = np.zeros((3, 2))
    with pytest.raises(ValueError, match="rtol"):
        EwaldPointOperator(MAT.E_star, pts, pts, rtol=rtol)
    with pytest.raises(ValueError, match="rtol"):
        HS.point_operator(pts, pts, rtol=rtol)


def test_bad_exclude_and_forces_raise():
    rng = np.random.default_rng(3)
    t, s = rng.uniform(0, 10, (6, 2)), rng.uniform(0, 10, (4, 2))
    with pytest.raises(ValueError, match="exclude.*\\(6, 4\\).*\\(4, 6\\)"):
        EwaldPointOperator(MAT.E_star, t, s, exclude=sp.csr_matrix((4, 6)))
    op = EwaldPointOperator(MAT.E_star, t, s)
    with pytest.raises(ValueError, match="forces"):
        op.apply(np.ones(6))
    with pytest.raises(ValueError, match="forces"):
        op.apply(np.ones((4, 2, 2)))


def test_choice_from_the_small_cut_offs_is_the_choice_from_all():
    # choose_parameters counts the near pairs of the large cut-offs only when a bound on
    # their cost does not rule them out; its choice must be the one every count gives
    from scipy.special import erfcinv

    from twoscale.influence import halfspace_points as hp

    rng = np.random.default_rng(11)
    sets = [clustered(n, rng, size=s) for n, s in [(9000, 300.0), (3000, 40.0), (200, 5.0), (40, 300.0)]]
    sets += [rng.uniform(0.0, 44.0, (8000, 2)), rng.uniform(0.0, 1.0, (30, 2)) * [50.0, 0.5]]
    for k, pts in enumerate(sets):
        rtol = [1e-6, 1e-4, 1e-9][k % 3]
        alpha = float(erfcinv(0.25 * rtol))
        boxes = hp._boxes(pts, pts)
        x0 = boxes[0][0]
        diag = float(np.hypot(*(boxes[0][1] - x0)))
        sigmas = diag / alpha * 2.0 ** (-np.arange(0, 60) / 3.0)
        sample = pts[:: max(1, len(pts) // hp._SAMPLE)]
        counts = cKDTree(sample).count_neighbors(cKDTree(pts), alpha * sigmas)
        full, _ = hp._cheapest(
            boxes, x0, sigmas, counts * (len(pts) / len(sample)), 2 * len(pts), rtol, alpha, floor=0.0
        )
        assert hp.choose_parameters(pts, pts, rtol) == full[1]


def test_the_parameters_are_those_of_every_cut_off_counted():
    # the pairs counted from the smallest cut-off up, stopping where their cost alone
    # exceeds the least found, choose what counting every cut-off (as written out here) does
    from twoscale.influence import halfspace_points as hp

    rng = np.random.default_rng(3)
    for n, side, rtol in ((6000, 120.0, 1e-6), (3000, 8.0, 1e-4), (9000, 40.0, 1e-8)):
        pts = rng.uniform(0.0, side, (n, 2)) * [1.0, 0.4]
        alpha = float(hp.erfcinv(0.25 * rtol))
        boxes = hp._boxes(pts, pts)
        x0 = boxes[0][0]
        sigmas = float(np.hypot(*(boxes[0][1] - x0))) / alpha * 2.0 ** (-np.arange(0, 60) / 3.0)
        sample = pts[:: max(1, n // hp._SAMPLE)]
        counts = cKDTree(sample).count_neighbors(cKDTree(pts), alpha * sigmas) * (n / len(sample))
        best = None
        for p in hp.ORDERS:
            h = hp.lagrange_spacing(p, 0.5 * rtol)
            for sigma, npair in zip(sigmas, counts):
                (_, ts), (_, ss) = hp._meshes(boxes, x0, h * sigma, p)
                P = float(np.prod(hp._fft_shape(ts, ss)))
                if P > hp.MESH_CAP:
                    break
                fft = P * math.log2(P)
                apply = hp._W_APPLY * p * p * 2 * n + hp._FFT_APPLY * fft + hp._PAIR_APPLY * npair
                build = hp._W_BUILD * p * p * 2 * n + hp._FFT_BUILD * fft + hp._PAIR_BUILD * npair
                cost = apply + build / hp._APPLIES_PER_BUILD
                if best is None or cost < best[0]:
                    best = (cost, p, float(sigma))
        got = hp.choose_parameters(pts, pts, rtol)
        assert (got.order, got.sigma) == (best[1], best[2])
