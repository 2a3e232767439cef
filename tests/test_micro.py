"""The micro step on its own: local solves (eq. 7, contact on one block), block
Gauss-Seidel (eq. 8-9), patches and ownership, growth, load and tilt corrections.

Independent checks: the contact problem ``min 1/2 p.A p - b.p, p >= 0`` on the union of
the blocks is also a non-negative least-squares problem (``A = L L^T``:
``min |L^T p - L^-1 b|``), solved here by ``scipy.optimize.nnls`` on the dense Love matrix,
which shares no code with the micro step's active sets, conjugate gradients or sweeps.
"""

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import nnls

from twoscale import Grid, Material
from twoscale.analytic import hertz
from twoscale.indenters import Asperity, Tilt
from twoscale.influence import HalfSpace
from twoscale.micro import BlockSettings, MicroProblem, build_patches, solve_micro
from twoscale.options import MicroOptions
from twoscale.micro.localblock import LocalBlock
from twoscale.micro.gauss_seidel import linear_gauss_seidel
from twoscale.micro.blocks import Coupling
from twoscale.micro.local import contact_solve, initial_pressure
from twoscale.micro.patches import make_patch

MAT = Material(10.0, 0.5)
HS = HalfSpace(MAT)
ES = MAT.E_star


def _nnls_contact(provider, patches, b_blocks):
    """Contact on the union of the blocks by NNLS on the dense matrix (independent)."""
    pts = np.concatenate([pt.grid.points()[pt.owned.ravel()] for pt in patches])
    A = provider.cell_block(pts, pts, patches[0].grid.h)
    A = 0.5 * (A + A.T)
    b = np.concatenate(b_blocks)
    L = np.linalg.cholesky(A)
    p, _ = nnls(L.T, sla.solve_triangular(L, b, lower=True), maxiter=50 * len(b))
    return p


def _blocks_of(res):
    return np.concatenate([p[pt.owned] for pt, p in zip(res.patches, res.pressures)])


# ---------------------------------------------------------------- one block
def _single_patch(n_half=14, h=0.1, R=5.0):
    a = Asperity(0.0, 0.0, 0.0, R, "paraboloid")
    g = Grid.covering(-n_half * h, n_half * h, -n_half * h, n_half * h, h)
    return make_patch(0, g, [a]), a


def test_eq7_carries_the_force_and_dense_and_cg_agree():
    pt, a = _single_patch()
    z = pt.height[pt.owned]
    P = 2.0
    dense = initial_pressure(LocalBlock(HS, pt, dense_max_cells=10_000), z, P, pt.grid.h, approach=0.2)
    cg = initial_pressure(LocalBlock(HS, pt, dense_max_cells=0), z, P, pt.grid.h, approach=0.2)
    for sol in (dense, cg):
        assert sol.converged
        assert pt.grid.h**2 * sol.pressure.sum() == pytest.approx(P, rel=1e-9)
        assert sol.pressure.min() >= 0.0
    assert np.linalg.norm(dense.pressure - cg.pressure) <= 1e-6 * np.linalg.norm(dense.pressure)
    # the rigid shift is the local approach; Hertz gives it to the discretisation error
    d_hertz = float(hertz.penetration(a.R, P, ES))
    assert dense.shift == pytest.approx(d_hertz, rel=0.02)
    assert cg.shift == pytest.approx(dense.shift, rel=1e-6)


def test_contact_solve_dense_cg_and_nnls_agree():
    pt, a = _single_patch(n_half=10)
    b = 0.15 - pt.height[pt.owned]
    ref = _nnls_contact(HS, [pt], [b])
    for dmc in (10_000, 0):
        blk = LocalBlock(HS, pt, dense_max_cells=dmc)
        sol = contact_solve(blk, b, np.zeros(blk.n), rtol=1e-12)
        assert sol.converged
        assert np.linalg.norm(sol.pressure - ref) <= 1e-6 * np.linalg.norm(ref)


def test_block_products_on_the_owned_box_equal_the_whole_patch_matrix():
    # a neighbour closer to the body owns the right part of the patch: the block works on
    # the box of its own cells, which must not change A_kk
    asps = [Asperity(0.0, 0.0, 0.0, 2.0), Asperity(0.5, 0.1, -0.01, 2.0)]
    pt = make_patch(0, Grid.covering(-0.7, 0.7, -0.7, 0.7, 0.05), asps)
    idx = np.flatnonzero(pt.owned.ravel())
    A = HS.cell_block(pt.grid.points()[idx], pt.grid.points()[idx], 0.05)  # independent of the grid code
    v = np.random.default_rng(3).uniform(0.0, 1.0, idx.size)
    for dmc in (10_000, 0):
        blk = LocalBlock(HS, pt, dense_max_cells=dmc)
        assert blk.box.size < pt.grid.size and blk.n == idx.size
        np.testing.assert_allclose(blk.matvec(v), A @ v, rtol=1e-10, atol=1e-14 * np.abs(A @ v).max())
        full = blk.full_operator().apply(_scatter(pt, v))
        np.testing.assert_allclose(full[pt.owned], A @ v, rtol=1e-10, atol=1e-14 * np.abs(A @ v).max())
        assert full.shape == pt.grid.shape


def _scatter(pt, v):
    out = np.zeros(pt.grid.shape)
    out[pt.owned] = v
    return out


# ---------------------------------------------------------------- patches
def test_patches_share_the_lattice_and_no_cell_is_counted_twice():
    asps = [Asperity(0.0, 0.0, 0.0, 2.0), Asperity(0.5, 0.1, 0.01, 1.5), Asperity(-0.3, 0.6, 0.0, 2.5)]
    h = 0.05
    patches = build_patches(
        asps,
        h=h,
        forces=np.array([1.0, 0.8, 1.2]),
        approaches=np.array([0.1, 0.09, 0.1]),
        E_star=ES,
        anchor=(0.01, -0.02),
    )
    assert len(patches) == 3
    big = Grid.covering(-2.0, 2.0, -2.0, 2.0, h, anchor=(0.01, -0.02))
    count = np.zeros(big.shape, int)
    for pt in patches:
        di, dj = pt.grid.offset_in(big)  # raises if not on the common lattice
        count[dj : dj + pt.grid.ny, di : di + pt.grid.nx] += pt.owned
    assert count.max() == 1
    # the patches overlap, yet the owned cells are disjoint
    assert sum(int(pt.owned.sum()) for pt in patches) < sum(pt.grid.size for pt in patches)


def test_asperity_out_of_reach_gets_no_patch():
    asps = [Asperity(0.0, 0.0, 0.0, 2.0), Asperity(3.0, 0.0, 0.5, 2.0)]
    patches = build_patches(asps, h=0.1, forces=np.array([1.0, 0.0]), approaches=np.array([0.2, -0.3]), E_star=ES)
    assert [pt.asperity for pt in patches] == [0]


# ---------------------------------------------------------------- Gauss-Seidel
CLOSE = [
    Asperity(0.0, 0.0, 0.0, 2.0, "paraboloid"),
    Asperity(0.9, 0.3, 0.005, 1.5, "paraboloid"),
    Asperity(-0.6, 0.8, 0.01, 2.5, "paraboloid"),
]


# two tips closer than their contact radii (0.4 mm): merged contacts, one block when merging
PAIR = [Asperity(-0.3, 0.0, 0.0, 2.0, "paraboloid"), Asperity(0.3, 0.05, 0.002, 2.0, "paraboloid")]


@pytest.mark.parametrize(
    "dense_max_cells,merge,scene",
    [
        (10_000, False, "close"),
        (0, False, "close"),
        (10_000, True, "close"),
        (10_000, False, "pair"),
        (0, False, "pair"),
        (10_000, True, "pair"),
        (0, True, "pair"),
    ],
)
def test_gauss_seidel_matches_nnls_on_the_same_cells(dense_max_cells, merge, scene):
    asps = CLOSE if scene == "close" else PAIR
    d, h = 0.08, 0.07
    forces = np.array([float(hertz.load(a.R, d - a.z, ES)) for a in asps])
    res = solve_micro(
        HS,
        asps,
        MicroProblem(h=h, forces=forces, penetration=d),
        MicroOptions(tol=1e-9, dense_max_cells=dense_max_cells, merge=merge),
    )
    assert res.converged, res.message
    # the overlapping pair, and the close three, are one block only when merging
    assert res.merged == ((tuple(range(len(asps))),) if merge else ())
    assert len(res.patches) == (1 if merge else len(asps))
    assert res.history[-1] <= 1e-9
    ref = _nnls_contact(HS, res.patches, [d - pt.height[pt.owned] for pt in res.patches])
    p = _blocks_of(res)
    assert np.linalg.norm(p - ref) <= 1e-6 * np.linalg.norm(ref)
    # eq. 7 is only a start: the interaction moves the pressure
    p0 = np.concatenate([q[pt.owned] for pt, q in zip(res.patches, res.initial)])
    assert np.linalg.norm(p0 - ref) > 1e-3 * np.linalg.norm(ref)


def test_patch_grows_when_pressure_reaches_its_edge():
    a = [Asperity(0.0, 0.0, 0.0, 2.0, "paraboloid")]
    d, h = 0.08, 0.07
    P = float(hertz.load(2.0, d, ES))
    res = solve_micro(HS, a, MicroProblem(h=h, forces=np.array([P / 20.0]), penetration=d), MicroOptions(tol=1e-9))
    assert res.converged, res.message
    assert res.growths >= 1
    good = solve_micro(HS, a, MicroProblem(h=h, forces=np.array([P]), penetration=d), MicroOptions(tol=1e-9))
    assert good.growths == 0
    f = [h * h * float(r.pressures[0].sum()) for r in (res, good)]
    assert f[0] == pytest.approx(f[1], rel=1e-6)


def test_sweep_limit_is_reported_not_hidden():
    d, h = 0.08, 0.07
    forces = np.zeros(3)  # eq. 7 gives nothing: the sweeps start from zero
    res = solve_micro(
        HS,
        CLOSE,
        MicroProblem(h=h, forces=forces, penetration=d),
        MicroOptions(tol=1e-12, max_sweeps=2),
        settings=BlockSettings(max_growths=0),
    )
    assert not res.converged
    assert "2 sweeps" in res.message
    assert res.sweeps == 2


def test_linear_gauss_seidel_solves_the_coupled_system():
    d, h = 0.08, 0.07
    patches = build_patches(CLOSE, h=h, forces=np.ones(3), approaches=np.full(3, d), E_star=ES)
    blocks = [LocalBlock(HS, pt) for pt in patches]
    active = [np.ones(b.n, bool) for b in blocks]
    rng = np.random.default_rng(0)
    rhs = [rng.uniform(0.5, 1.0, (b.n, 2)) for b in blocks]
    out = linear_gauss_seidel(blocks, Coupling(HS, patches), rhs, active, tol=1e-11, max_sweeps=500)
    assert out.converged
    pts = np.concatenate([pt.grid.points()[pt.owned.ravel()] for pt in patches])
    A = HS.cell_block(pts, pts, h)
    x = np.linalg.solve(A, np.concatenate(rhs))
    assert np.linalg.norm(np.concatenate(out.pressures) - x) <= 1e-7 * np.linalg.norm(x)


# ---------------------------------------------------------------- load and tilt
@pytest.mark.parametrize("merge", [False, True])
def test_load_control_and_tilt_meet_the_equations_exactly(merge):
    asps = CLOSE
    d, h, W, pivot = 0.08, 0.07, 1.5, (0.1, 0.2)
    forces = np.array([float(hertz.load(a.R, d - a.z, ES)) for a in asps])
    res = solve_micro(
        HS,
        asps,
        MicroProblem(h=h, forces=forces, penetration=d, tilt=(0.0, 0.0), pivot=pivot, total_load=W, free_tilt=True),
        MicroOptions(tol=1e-8, merge=merge),
    )
    assert res.converged, res.message
    # one block for the three close asperities, or one each
    assert res.merged == (((0, 1, 2),) if merge else ())
    P = np.concatenate([h * h * p[pt.owned] for pt, p in zip(res.patches, res.pressures)])
    X = np.concatenate([pt.grid.centres()[0][pt.owned] for pt in res.patches]) - pivot[0]
    Y = np.concatenate([pt.grid.centres()[1][pt.owned] for pt in res.patches]) - pivot[1]
    arm = 1.0  # mm: the scene's size
    assert P.sum() == pytest.approx(W, rel=1e-9)
    assert abs(P @ X) <= 1e-9 * W * arm and abs(P @ Y) <= 1e-9 * W * arm
    # same cells, tilted surface at the solved d, alpha, beta: NNLS gives the same pressure
    t = Tilt(res.tilt[0], res.tilt[1], pivot)
    b = [
        res.penetration - pt.height[pt.owned] - t.height(*(c[pt.owned] for c in pt.grid.centres()))
        for pt in res.patches
    ]
    ref = _nnls_contact(HS, res.patches, b)
    assert np.linalg.norm(_blocks_of(res) - ref) <= 1e-5 * np.linalg.norm(ref)


def test_growth_limit_is_reported_not_hidden():
    a = [Asperity(0.0, 0.0, 0.0, 2.0, "paraboloid")]
    d, h = 0.08, 0.07
    P = float(hertz.load(2.0, d, ES))
    res = solve_micro(
        HS,
        a,
        MicroProblem(h=h, forces=np.array([P / 50.0]), penetration=d),
        MicroOptions(tol=1e-8),
        settings=BlockSettings(max_growths=0),
    )
    assert not res.converged
    assert "patch edge" in res.message


def test_unsymmetric_dense_block_falls_back_to_lu():
    pt, a = _single_patch(n_half=8)
    blk = LocalBlock(HS, pt, dense_max_cells=10_000)
    assert blk.symmetric
    # perturb the stored matrix unsymmetrically (as a finite-element body may be)
    rng = np.random.default_rng(1)
    blk.matrix = blk.matrix * (1.0 + 1e-3 * rng.standard_normal(blk.matrix.shape))
    blk.symmetric = False
    active = np.ones(blk.n, bool)
    rhs = rng.uniform(0.5, 1.0, blk.n)
    x = blk.solve(active, rhs)
    assert np.allclose(blk.matrix @ x, rhs, rtol=1e-9, atol=0.0)


#: Three spheres with the pivot on the first tip.
PIVOT_ON_TIP = [Asperity(0.0, 0.0, 0.0, 5.0), Asperity(8.0, 0.0, 0.0, 5.0), Asperity(0.0, 8.0, 0.0, 4.0)]


def _from_the_lone_tip_answer(W, h, iteration="block-gs", **options):
    """The micro step started from all the load on tip 0 and a tilt of 0.08 rad about
    both axes, which leaves tips 1 and 2 without a patch."""
    problem = MicroProblem(
        h=h,
        forces=np.array([W, 0.0, 0.0]),
        penetration=float(hertz.penetration(5.0, W, ES)),
        tilt=(0.08, 0.08),
        pivot=(0.0, 0.0),
        total_load=W,
        free_tilt=True,
    )
    return solve_micro(HS, PIVOT_ON_TIP, problem, MicroOptions(tol=1e-9, **options), iteration=iteration)


def test_asperities_the_macro_step_left_out_get_patches():
    # Pivot on tip 0: point forces balance any tilt that lifts tips 1 and 2 (the macro
    # step may return all the load on tip 0), distributed pressure does not. Started from
    # such a macro answer (tilt large enough that tips 1 and 2 get no patch), the micro
    # step must bring them in and agree with the full-grid reference solving its own tilt.
    from twoscale.indenters import surface_on
    from twoscale.reference import solve_cg

    asp, h, W = PIVOT_ON_TIP, 0.1, 10.0
    res = _from_the_lone_tip_answer(W, h=h)
    assert res.converged, res.message
    assert sorted(pt.asperity for pt in res.patches) == [0, 1, 2]
    g = Grid.covering(-6.0, 14.0, -6.0, 14.0, h)
    ref = solve_cg(HS, surface_on(g, asp), total_load=W, tilt=True, pivot=(0.0, 0.0), tol=1e-10)
    assert ref.converged
    F = np.array([h * h * p.sum() for p in res.pressures])[np.argsort([pt.asperity for pt in res.patches])]
    Fr = np.asarray(ref.asperities.forces)
    assert Fr[1] > 0.02 * W and Fr[2] > 0.02 * W  # the case bites: tips 1 and 2 carry load
    assert np.max(np.abs(F - Fr)) <= 1e-5 * W
    assert np.allclose(res.tilt, ref.tilt, rtol=1e-4)


def test_two_level_says_when_one_patch_must_carry_the_moment():
    # Known limit of the two-level iteration: its coarse step moves the tilt through the
    # patches' resultants, and a lone patch on the pivot carries none, so from the same
    # bad start as above the tilt cannot move and tips 1 and 2 are never reached. It must
    # say so rather than return the lone-patch answer (solve_twoscale does not start there:
    # its patches are sized from the macro local penetrations, see the block test).
    res = _from_the_lone_tip_answer(10.0, h=0.1, far_tol=1e-4, iteration="two-level", max_sweeps=60)
    assert not res.converged
    # it stops at its budget, or sooner when its rate cannot reach the tolerance within it,
    # or its sweeps settle with the load unmet (the coarse step keeps a block's shape while
    # its contact moves little) and the final load check says by how much
    assert (
        "60 sweeps" in res.message
        or ("too slowly" in res.message and "left" in res.message)
        or "stopped with load residual" in res.message
    )


def test_eq7_starts_from_hertz_contact():
    # eq. 7 on a dense sphere block starts from Hertz's contact (z - min z < approach / 2):
    # at most two active-set passes (from the geometric overlap, approach, it took six
    # here), and the pressure satisfies the contact conditions and carries the force
    a = Asperity(0.0, 0.0, 0.0, 5.0)
    g = Grid.covering(-0.3, 0.3, -0.3, 0.3, 0.02)
    pt = make_patch(0, g, [a])
    X, Y = g.centres()
    z = a.height(X, Y)[pt.owned]
    P = 0.05  # contact radius 0.24 mm, 12 cells
    d = float(hertz.penetration(a.R, P, ES))
    block = LocalBlock(HS, pt, dense_max_cells=10_000)
    out = initial_pressure(block, z, P, g.h, approach=d)
    assert out.converged and out.iterations <= 2
    assert abs(out.pressure.sum() * g.h**2 - P) < 1e-10 * P
    gap = block.matvec(out.pressure) + z - out.shift
    assert np.all(out.pressure >= 0.0)
    assert np.all(gap[out.pressure == 0.0] >= -1e-10 * abs(out.shift))
    assert np.abs(gap[out.pressure > 0.0]).max() < 1e-10 * abs(out.shift)


@pytest.mark.parametrize("iteration", ["auto", "block-gs", "two-level", "union-cg"])
def test_no_tip_within_reach_is_no_answer_under_load_control(iteration):
    # the micro step started from an approach 0.05 mm short of both tips: under penetration
    # control no contact and no load is the answer; under load control the 2 N asked are
    # not carried, and the result must say so (it read "converged" with no load)
    tips = [Asperity(0.0, 0.0, 0.0, 10.0), Asperity(5.0, 0.0, 0.01, 10.0)]
    pb = MicroProblem(h=0.05, forces=np.array([1.0, 1.0]), penetration=-0.05, total_load=2.0)
    res = solve_micro(HS, tips, pb, MicroOptions(iteration=iteration))
    assert not res.converged and "2 N asked is not carried" in res.message
    free = solve_micro(HS, tips, MicroProblem(h=0.05, forces=np.zeros(2), penetration=-0.05), MicroOptions())
    assert free.converged and free.message == "no asperity reaches the body"
