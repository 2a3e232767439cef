"""Two-level micro iteration (many asperities): lagged far field + coarse correction.

Independent checks: whole solves with ``coarse=True`` against the same solves with every
cross-patch pair exact (plain block Gauss-Seidel, eq. 8), in the three load modes; the
load and moment equations against their closed-form statement; the coarse step against
its defining property (zero at a fixed point, exact load after the step).
"""

import numpy as np
import pytest

from twoscale import Material
from twoscale.analytic import hertz
from twoscale.indenters import Asperity
from twoscale.influence import HalfSpace
from twoscale.micro import solve_micro
from twoscale.krylov import block_cg
from twoscale.micro.coarse import CoarseSpace
from twoscale.driver import solve_twoscale

from helpers import small_block, spaced_spheres

MAT = Material(10.0, 0.5)
HS = HalfSpace(MAT)


def _compare(exact, approx, bound):
    fe, fa = np.asarray(exact.asperities.forces), np.asarray(approx.asperities.forces)
    touching = fe > 0.05 * fe[fe > 0].mean()
    assert 0.3 <= np.mean(fe > 0) <= 0.95
    assert np.max(np.abs(fa - fe)[touching] / fe[touching]) <= bound


@pytest.mark.parametrize("seed", [0, 1])
def test_two_level_load_control_matches_exact_coupling(seed):
    # 60 spheres on 24 mm, far_tol = 0.01: within 0.5 % of the exact coupling per
    # asperity (the far field by resultants at the tips is the only approximation)
    asp = spaced_spheres(60, seed, 24.0)
    kw = dict(h=0.1, total_load=3.0, tol=1e-7, max_sweeps=200)
    exact = solve_twoscale(HS, asp, **kw)
    approx = solve_twoscale(HS, asp, far_tol=0.01, coarse=True, **kw)
    assert exact.converged and approx.converged, approx.message
    _compare(exact, approx, 5e-3)
    assert np.asarray(approx.asperities.forces).sum() == pytest.approx(3.0, rel=1e-6)
    assert approx.iterations["sensitivity_sweeps"] == 0
    # far_tol alone selects the two-level iteration
    auto = solve_twoscale(HS, asp, far_tol=0.01, **kw)
    assert np.array_equal(auto.asperities.forces, approx.asperities.forces)


def test_two_level_penetration_control_matches_exact_coupling():
    asp = spaced_spheres(50, 2, 22.0)
    kw = dict(h=0.1, penetration=0.05, tol=1e-7, max_sweeps=200)
    exact = solve_twoscale(HS, asp, **kw)
    approx = solve_twoscale(HS, asp, far_tol=0.01, coarse=True, **kw)
    assert exact.converged and approx.converged, approx.message
    assert approx.penetration == 0.05
    _compare(exact, approx, 5e-3)


def test_two_level_tilt_meets_load_and_moments():
    # ball-and-socket joint: total load and both moments about the pivot vanish to 1e-6
    # of (W, W * RMS arm), and the forces and angles match the exact coupling
    asp = spaced_spheres(40, 3, 20.0)
    pivot = (9.0, 11.0)
    kw = dict(h=0.1, total_load=2.5, tilt=True, pivot=pivot, tol=1e-7, max_sweeps=300)
    exact = solve_twoscale(HS, asp, **kw)
    approx = solve_twoscale(HS, asp, far_tol=0.01, coarse=True, **kw)
    assert exact.converged and approx.converged, approx.message
    W = 0.0
    Mx = My = 0.0
    for f in approx.fields:
        X, Y = f.grid.centres()
        w = f.grid.h**2 * f.pressure
        W += w.sum()
        Mx += ((Y - pivot[1]) * w).sum()
        My += ((X - pivot[0]) * w).sum()
    arm = np.sqrt(np.mean([(a.x - pivot[0]) ** 2 + (a.y - pivot[1]) ** 2 for a in asp]))
    assert W == pytest.approx(2.5, rel=1e-6)
    assert abs(Mx) <= 1e-6 * 2.5 * arm and abs(My) <= 1e-6 * 2.5 * arm
    assert np.allclose(approx.tilt, exact.tilt, rtol=1e-2, atol=1e-6)
    _compare(exact, approx, 5e-3)


def test_iterations_take_only_the_couplings_they_accept():
    from twoscale.micro import MicroContext, MicroProblem
    from twoscale.micro.couplings import Exact, FarField
    from twoscale.micro.strategies import BlockGaussSeidel, UnionCG
    from twoscale.options import MicroOptions

    asp = spaced_spheres(3, 0, 6.0)
    problem = MicroProblem(h=0.1, forces=np.ones(3), penetration=0.05)
    ctx = MicroContext(HS, asp, problem, patches=())
    with pytest.raises(ValueError, match="union-cg iteration takes no coupling"):
        UnionCG().run(ctx, Exact(), max_sweeps=10)
    with pytest.raises(ValueError, match="block-gs iteration takes Exact or FarField"):
        BlockGaussSeidel().run(ctx, None, max_sweeps=10)
    with pytest.raises(ValueError, match="far_tol"):
        solve_micro(HS, asp, problem, MicroOptions(far_tol=0.1), iteration="union-cg")
    assert FarField(0.1).far_tol == 0.1 and Exact().far_tol is None


def test_two_level_with_exact_coupling_reaches_block_gauss_seidel_answer():
    # the same equations (every pair exact), two iterations: the answers agree to the tolerance
    from twoscale.micro import MicroProblem
    from twoscale.options import MicroOptions

    asp = spaced_spheres(6, 1, 7.0)
    forces = np.array([float(hertz.load(a.R, max(0.06 - a.z, 0.0), MAT.E_star)) for a in asp])
    problem = MicroProblem(h=0.1, forces=forces, penetration=0.06, total_load=0.8 * float(forces.sum()))
    opts = MicroOptions(tol=1e-9, merge=False, max_sweeps=200)
    gs = solve_micro(HS, asp, problem, opts, iteration="block-gs")
    two = solve_micro(HS, asp, problem, opts, iteration="two-level")
    assert gs.converged and two.converged, (gs.message, two.message)
    f_gs = sorted((pt.asperity, 0.01 * float(p.sum())) for pt, p in zip(gs.patches, gs.pressures))
    f_two = sorted((pt.asperity, 0.01 * float(p.sum())) for pt, p in zip(two.patches, two.pressures))
    assert [k for k, _ in f_gs] == [k for k, _ in f_two]
    assert np.allclose([f for _, f in f_gs], [f for _, f in f_two], rtol=1e-6, atol=1e-9 * problem.total_load)
    assert two.penetration == pytest.approx(gs.penetration, rel=1e-7)


def test_coarse_step_vanishes_at_a_fixed_point_and_meets_the_load():
    from twoscale.micro.constraints import Control
    from twoscale.micro.localblock import LocalBlock
    from twoscale.micro.sampling import build_patches

    asp = spaced_spheres(8, 4, 12.0)
    patches = build_patches(
        asp,
        h=0.1,
        forces=np.full(8, np.inf),
        approaches=np.full(8, 0.06),
        E_star=MAT.E_star,
        margin=1.3,
        anchor=(0.0, 0.0),
    )
    blocks = [LocalBlock(HS, pt) for pt in patches]
    rng = np.random.default_rng(0)
    p = [np.where(rng.random(b.n) < 0.5, rng.random(b.n), 0.0) for b in blocks]
    active = [v > 0 for v in p]
    tips = np.array([[asp[pt.asperity].x, asp[pt.asperity].y] for pt in patches])
    import scipy.sparse as sp

    coarse = CoarseSpace(HS, tips, sp.csr_matrix((len(patches), len(patches))))
    theta = np.array([0.05, 0.0, 0.0])
    # no change in the sweep, penetration control: nothing to correct
    step = coarse.correct(blocks, patches, p, active, np.zeros(len(patches)), theta, Control())
    assert all(np.array_equal(a, b) for a, b in zip(step.pressures, p))
    assert np.array_equal(step.theta, theta)
    # load control: after the step the pressures carry the load exactly (no clipping here)
    W = sum(0.01 * v.sum() for v in p) * 1.01
    step = coarse.correct(
        blocks, patches, p, active, np.zeros(len(patches)), theta, Control((0.0, 0.0), 1, np.array([W]))
    )
    assert sum(0.01 * v.sum() for v in step.pressures) == pytest.approx(W, rel=1e-12)
    assert step.theta[0] > theta[0]


def test_the_coarse_shape_is_kept_with_its_block_while_the_contact_moves_little(monkeypatch):
    # s_k = A_SS^-1 1 is solved once per block and kept through the rounds of a solve (each
    # round builds a new coarse space) while the active set differs in at most SHAPE_REUSE of
    # its cells; the step still meets the load exactly (any s_k does), and a block whose
    # contact moved more solves again
    import scipy.sparse as sp
    from twoscale.micro import coarse as coarse_mod
    from twoscale.micro.constraints import Control
    from twoscale.micro.localblock import LocalBlock
    from twoscale.micro.sampling import build_patches

    asp = spaced_spheres(8, 4, 12.0)
    patches = build_patches(
        asp, h=0.1, forces=np.full(8, np.inf), approaches=np.full(8, 0.06), E_star=MAT.E_star, anchor=(0.0, 0.0)
    )
    blocks = [LocalBlock(HS, pt) for pt in patches]
    solved, orig = [], LocalBlock.solve
    monkeypatch.setattr(LocalBlock, "solve", lambda self, *a, **k: (solved.append(self), orig(self, *a, **k))[1])
    # a cap of interference on each patch (a contact of a few cells across, s_k > 0 on it)
    p = [np.maximum(asp[pt.asperity].z + 0.02 - pt.height[pt.owned], 0.0) for pt in patches]
    tips = np.array([[asp[pt.asperity].x, asp[pt.asperity].y] for pt in patches])

    def step(q):
        W = sum(0.01 * v.sum() for v in q) * 1.01  # more load: no pressure clipped
        load = Control((0.0, 0.0), 1, np.array([W]))
        space = CoarseSpace(HS, tips, sp.csr_matrix((len(patches), len(patches))))  # a new round
        out = space.correct(blocks, patches, q, [v > 0 for v in q], np.zeros(len(patches)), np.zeros(3), load)
        assert sum(0.01 * v.sum() for v in out.pressures) == pytest.approx(W, rel=1e-12)
        return out

    step(p)
    assert {id(b) for b in solved} == {id(b) for b, v in zip(blocks, p) if np.any(v > 0)}
    solved.clear()
    q = [v.copy() for v in p]
    k = int(np.argmax([b.n for b in blocks]))
    ring = np.argsort(patches[k].height[patches[k].owned])  # cells from the tip outwards
    q[k][ring[np.count_nonzero(p[k])]] = 1e-3  # the next cell enters: within SHAPE_REUSE
    step(q)
    assert solved == []
    q[k][ring[: int((1.0 + coarse_mod.SHAPE_REUSE) * np.count_nonzero(p[k])) + 2]] += 1e-3
    step(q)
    assert [id(b) for b in solved] == [id(blocks[k])]


def test_block_cg_solves_spd_systems_column_by_column():
    rng = np.random.default_rng(1)
    B = rng.random((40, 40))
    M = B @ B.T + 40 * np.eye(40)
    rhs = rng.random((40, 3))
    out = block_cg(lambda v: M @ v, 1.0 / np.diag(M), rhs, rtol=1e-10, max_iter=200)
    assert out.converged and out.iterations < 200 and not out.breakdown
    assert np.allclose(M @ out.x, rhs, rtol=0, atol=1e-8 * np.abs(rhs).max())
    assert not block_cg(lambda v: M @ v, 1.0 / np.diag(M), rhs, rtol=1e-14, max_iter=2).converged
    # a warm start at the solution takes no product
    assert block_cg(lambda v: M @ v, 1.0 / np.diag(M), rhs, rtol=1e-8, max_iter=5, x0=out.x).iterations == 0
    # an indefinite matrix is reported, not silently solved
    Mi = M - 200 * np.eye(40)
    assert block_cg(lambda v: Mi @ v, np.ones(40), rhs, rtol=1e-10, max_iter=200).breakdown


def test_two_level_runs_unchanged_on_the_finite_block():
    # the same call on a small bonded block (60 x 60 x 10 mm, coarse mesh):
    # forces within 0.5 % of the exact coupling on the same block, and much nearer to it
    # than to the half-space answer (the block's own interaction is what it used)
    pytest.importorskip("fem_influence")
    block = small_block(MAT)
    asp = [a for a in spaced_spheres(30, 5, 18.0)]
    asp = [Asperity(a.x - 9.0, a.y - 9.0, a.z, a.R) for a in asp]
    kw = dict(h=0.1, total_load=2.0, tol=1e-7, max_sweeps=200)
    exact = solve_twoscale(block, asp, **kw)
    approx = solve_twoscale(block, asp, far_tol=0.01, **kw)
    half = solve_twoscale(HS, asp, far_tol=0.01, **kw)
    assert exact.converged and approx.converged, approx.message
    _compare(exact, approx, 5e-3)
    fe, fh = np.asarray(exact.asperities.forces), np.asarray(half.asperities.forces)
    fa = np.asarray(approx.asperities.forces)
    assert np.max(np.abs(fa - fe)) < 0.2 * np.max(np.abs(fh - fe))


def test_matrix_free_macro_step_gives_the_same_two_scale_answer():
    # below 4e6 pairs the point operator is exact, so a matrix-free macro step changes
    # nothing but the way the Newton steps are solved: the final answer is the same
    asp = spaced_spheres(40, 3, 20.0)
    kw = dict(h=0.1, total_load=2.0, tilt=True, pivot=(10.0, 10.0), tol=1e-7, far_tol=0.01)
    dense = solve_twoscale(HS, asp, **kw)
    free = solve_twoscale(HS, asp, macro_dense_max=1, **kw)
    assert dense.details.macro.interaction == "dense" and free.details.macro.interaction == "matrix-free"
    assert dense.converged and free.converged, free.message
    assert free.iterations["macro_krylov"] > 0 and free.details.macro.operator_error <= 1e-12
    fd, ff = np.asarray(dense.asperities.forces), np.asarray(free.asperities.forces)
    assert np.max(np.abs(ff - fd)) <= 1e-6 * fd.max()
    # result.json says how the macro step held the interaction
    from twoscale.io.result_json import result_to_dict
    from twoscale.scene import Scene

    scene = Scene(material=MAT, asperities=asp, total_load=2.0, tilt=True, pivot=(10.0, 10.0), h=0.1)
    assert result_to_dict(dense, scene)["macro"] == {"interaction": "dense", "operator_error": None}
    assert result_to_dict(dense, scene)["micro_iteration"] == "two-level (far-field coupling)"
    rec = result_to_dict(free, scene)["macro"]
    assert rec["interaction"] == "matrix-free" and 0.0 <= rec["operator_error"] <= 1e-12


def test_a_fallback_attempt_takes_the_first_pressures_its_context_kept(monkeypatch):
    # the driver runs a block iteration after a failed two-level attempt on the same
    # patches: eq. 7 is solved once per patch for both (2,117 clustered spheres: 11 s of
    # CPU per attempt), and the second attempt starts from the same pressures
    import twoscale.micro.setup as setup
    from twoscale.micro import MicroContext, MicroProblem
    from twoscale.micro.couplings import Exact
    from twoscale.micro.patches import TipTable
    from twoscale.micro.setup import block_setup, one_asperity_patches
    from twoscale.options import MicroOptions

    asp = TipTable(spaced_spheres(6, 1, 7.0))
    forces = np.array([float(hertz.load(a.R, max(0.06 - a.z, 0.0), MAT.E_star)) for a in asp])
    problem = MicroProblem(h=0.1, forces=forces, penetration=0.06)
    patches = tuple(one_asperity_patches(HS, asp, problem, MicroOptions().margin))
    ctx = MicroContext(HS, asp, problem, patches=patches)
    solved = []
    original = setup._initial
    monkeypatch.setattr(setup, "_initial", lambda *a, **k: solved.append(len(a[2])) or original(*a, **k))
    first = block_setup(ctx, Exact(), held=True, merge=False)
    again = block_setup(ctx, Exact(), held=False, merge=False)
    assert solved == [len(patches)] and len(patches) >= 4
    assert all(p is q for p, q in zip(first.p0, again.p0))
    fresh = block_setup(MicroContext(HS, asp, problem, patches=patches), Exact(), held=False, merge=False)
    assert all(np.array_equal(p, q) for p, q in zip(first.p0, fresh.p0)) and solved == [len(patches)] * 2


def test_a_grown_block_keeps_its_coarse_shape_on_the_same_contact(monkeypatch):
    # s_k = A_SS^-1 1 depends on the active cells only: a patch grown around the same
    # contact carries its block's shape over (zero on the new cells), the next coarse
    # step solves nothing for it, and the carried shape solves the grown block's system
    import scipy.sparse as sp
    from twoscale.micro.blocks import scatter
    from twoscale.micro.couplings import FarField
    from twoscale.micro.localblock import LocalBlock
    from twoscale.micro.sampling import build_patches
    from twoscale.micro.workset import WorkingSet

    asp = spaced_spheres(2, 2, 12.0)
    patches = build_patches(
        asp, h=0.05, forces=np.full(2, np.inf), approaches=np.full(2, 0.06), E_star=MAT.E_star, anchor=(0.0, 0.0)
    )
    engine = FarField(0.3).build(HS, patches, held=True, dense_max_entries=40_000, separated_rtol=None)
    state = WorkingSet(HS, asp, patches, engine, dense_max_cells=10)  # FFT blocks: shapes by CG
    p = [np.maximum(asp[pt.asperity].z + 0.02 - pt.height[pt.owned], 0.0) for pt in patches]
    tips = np.array([[asp[pt.asperity].x, asp[pt.asperity].y] for pt in patches])
    space = CoarseSpace(HS, tips, sp.csr_matrix((2, 2)))
    before = space._shape(state.blocks[0], p[0] > 0)
    old = state.patches[0]
    state.grow(0, (True, True, True, True), [p])
    blk, new = state.blocks[0], state.patches[0]
    assert blk.n > len(before) and not blk.dense
    assert scatter(new, blk.coarse_shape[1]).sum() == pytest.approx(before.sum(), rel=1e-12)
    np.testing.assert_array_equal(blk.coarse_shape[0], p[0] > 0)
    calls = []
    monkeypatch.setattr(LocalBlock, "solve", lambda self, *a, **k: calls.append(self))
    s = CoarseSpace(HS, tips, sp.csr_matrix((2, 2)))._shape(blk, p[0] > 0)
    assert calls == [] and s is blk.coarse_shape[1]
    monkeypatch.undo()
    active = p[0] > 0
    fresh = blk.solve(active, np.ones(int(active.sum())), rtol=1e-10)
    assert np.max(np.abs(s[active] - fresh)) <= 1e-3 * np.max(fresh)
    assert old.grid.size < new.grid.size  # grown on all four sides


def test_the_held_far_field_is_refreshed_only_when_a_block_vector_is_replaced():
    from twoscale.micro.couplings import FarField
    from twoscale.micro.sampling import build_patches

    asp = spaced_spheres(12, 3, 10.0)
    patches = build_patches(
        asp, h=0.05, forces=np.full(12, np.inf), approaches=np.full(12, 0.05), E_star=MAT.E_star, anchor=(0.0, 0.0)
    )
    engine = FarField(0.3).build(HS, patches, held=True, dense_max_entries=40_000, separated_rtol=None)
    p = [np.full(int(pt.owned.sum()), 0.1) for pt in patches]
    engine.refresh(p)
    table, count = engine._table, engine.far_products
    engine.refresh(list(p))  # the same vectors in another list: kept
    assert engine._table is table and engine.far_products == count
    q = list(p)
    q[5] = 2.0 * p[5]
    engine.refresh(q)
    assert engine.far_products == count + 1 and not np.array_equal(engine._table, table)
    fresh = FarField(0.3).build(HS, patches, held=True, dense_max_entries=40_000, separated_rtol=None)
    fresh.refresh(q)
    np.testing.assert_array_equal(engine._table, fresh._table)


def test_the_coarse_shapes_of_fft_blocks_are_solved_together_per_size_class(monkeypatch):
    # s_k = A_SS^-1 1 by one conjugate-gradient run per canvas size class (no solve one
    # block at a time), each within its tolerance of a tight solve of the block's own system
    import scipy.sparse as sp
    from twoscale.micro.couplings import FarField
    from twoscale.micro.localblock import LocalBlock
    from twoscale.micro.pk_stack import BlockStacks
    from twoscale.micro.sampling import build_patches
    from twoscale.micro.workset import WorkingSet

    asp = spaced_spheres(6, 4, 10.0)
    patches = build_patches(
        asp, h=0.05, forces=np.full(6, np.inf), approaches=np.full(6, 0.06), E_star=MAT.E_star, anchor=(0.0, 0.0)
    )
    engine = FarField(0.3).build(HS, patches, held=True, dense_max_entries=40_000, separated_rtol=None)
    state = WorkingSet(HS, asp, patches, engine, dense_max_cells=10)  # FFT blocks: shapes by CG
    active = [asp[pt.asperity].z + 0.03 - pt.height[pt.owned] > 0.0 for pt in patches]
    assert all(a.sum() > 20 for a in active) and not any(blk.dense for blk in state.blocks)
    space = CoarseSpace(HS, state.tips(), sp.csr_matrix((6, 6)))
    calls = []
    monkeypatch.setattr(LocalBlock, "solve", lambda self, *a, **k: calls.append(self))
    space._solve_shapes(BlockStacks(HS), state.blocks, list(range(6)), active)
    assert calls == []
    monkeypatch.undo()
    for blk, a in zip(state.blocks, active):
        kept_active, s = blk.coarse_shape
        np.testing.assert_array_equal(kept_active, a)
        assert np.all(s[~a] == 0.0)
        exact = blk.solve(a, np.ones(int(a.sum())), rtol=1e-12)
        residual = blk.product_on(a, s)[a] - 1.0
        assert np.linalg.norm(residual) <= 1e-4 * np.sqrt(a.sum())
        assert np.max(np.abs(s[a] - exact)) <= 1e-3 * np.max(exact)


def test_the_result_gaps_take_the_growth_checks_patches_at_the_same_state():
    from twoscale.micro.couplings import FarField
    from twoscale.micro.sampling import build_patches
    from twoscale.micro.workset import WorkingSet

    asp = spaced_spheres(8, 5, 8.0)
    patches = build_patches(
        asp, h=0.05, forces=np.full(8, np.inf), approaches=np.full(8, 0.05), E_star=MAT.E_star, anchor=(0.0, 0.0)
    )

    def state():
        engine = FarField(0.3).build(HS, patches, held=True, dense_max_entries=40_000, separated_rtol=None)
        return WorkingSet(HS, asp, patches, engine, dense_max_cells=10)

    p = [np.maximum(asp[pt.asperity].z + 0.02 - pt.height[pt.owned], 0.0) for pt in patches]
    theta, pivot = (0.03, 0.0, 0.0), (0.0, 0.0)
    a, b = state(), state()
    a.coupling.refresh(p)
    b.coupling.refresh(p)
    some = a.gaps_of([1, 6], p, theta, pivot)
    got, fresh = a.gaps(p, theta, pivot), b.gaps(p, theta, pivot)
    assert got[1] is some[1] and got[6] is some[6] and got[0] is not fresh[0]
    # the same state to rounding: a subset's gaps and all gaps may sum the far field's terms
    # in another order (last bits); a stale state would be off by the pressure's change
    for g, f in zip(got, fresh):
        np.testing.assert_allclose(g, f, rtol=1e-12, atol=1e-15)
    q = [v.copy() for v in p]  # other vectors: nothing taken over
    assert a.gaps(q, theta, pivot)[1] is not some[1]
