"""What the macro step no longer does twice: the stall's one-step stop, the penetrations kept
between Newton's residual and its step, the secant start's single-precision factor.

The answers are checked against closed forms written out here (a Newton iteration on a line,
the local penetrations ``offset - T P``, the secant start's linear problem solved in double
precision) and against the same solve without the shortcut.
"""

import math

import numpy as np

from twoscale import Material
from twoscale.control import Loading
from twoscale.laws import HertzLaw, LawStack
from twoscale.macro import solve_macro
from twoscale.macro.newton import STALL_RESIDUAL, STALL_STEP_DROP, Stops, newton
from twoscale.macro.system import MacroSystem

from helpers import newton_on_a_line

MAT = Material(10.0, 0.5)


def _line(x0: float, factor: float, max_iter: int, stall):
    """Newton on r(x) = x whose step is ``-factor r`` (:func:`helpers.newton_on_a_line`)."""
    return newton_on_a_line(newton, x0, factor, max_iter, Stops(stall=stall))


def test_a_step_that_removes_almost_nothing_near_a_solution_stops_newton_at_once():
    # below STALL_RESIDUAL a step taking off 0.05 % of the residual stops after that step
    # (the four-step window alone stopped after four); 0.2 % a step is left to the window;
    # above STALL_RESIDUAL the same 0.05 % steps go on to max_iter
    tiny = 0.5 * STALL_STEP_DROP
    once = _line(0.5 * STALL_RESIDUAL, tiny, 40, 4)
    assert not once.converged and once.iterations == 1
    assert "down by under 0.1% in one step" in once.message
    slow = _line(0.5 * STALL_RESIDUAL, 2.0 * STALL_STEP_DROP, 40, 4)
    assert slow.iterations == 4 and "not halved in 4 steps" in slow.message
    far = _line(5.0 * STALL_RESIDUAL, tiny, 40, 4)
    assert far.iterations == 40 and "stagnated" not in far.message


class _Counted:
    """A dense ``T`` that counts its products (stands in for the interaction)."""

    def __init__(self, T: np.ndarray):
        self.matrix, self.products = T, 0

    @property
    def shape(self):
        return self.matrix.shape

    def __matmul__(self, P):
        self.products += 1
        return self.matrix @ P


def test_penetrations_at_the_same_unknowns_cost_one_product():
    rng = np.random.default_rng(3)
    n = 12
    T = rng.uniform(0.0, 1e-3, (n, n))
    counted = _Counted(T)
    offset = rng.uniform(0.0, 0.01, n)
    laws = LawStack([HertzLaw(1.0, MAT.E_star)] * n)
    system = MacroSystem(counted, offset, np.zeros((n, 0)), np.zeros((0, n)), np.zeros(0), laws)
    x = rng.uniform(0.0, 1.0, n)
    first = system.delta(x)
    system.residual(x)  # Newton's residual, then its step's stiffnesses, at the same x
    system.contact_stiffness(x)
    assert counted.products == 1
    np.testing.assert_allclose(first, offset - T @ x, rtol=0, atol=1e-15)
    first[:] = 0.0  # the caller's copy: what is kept is not changed
    np.testing.assert_allclose(system.delta(x), offset - T @ x, rtol=0, atol=1e-15)
    x[0] += 0.5  # the caller's unknowns changed in place: a new product, the new values
    np.testing.assert_allclose(system.delta(x), offset - T @ x, rtol=0, atol=1e-15)
    assert counted.products == 2


def _boussinesq(tips: np.ndarray) -> np.ndarray:
    r = np.hypot(*(tips[:, None, :] - tips[None, :, :]).transpose(2, 0, 1))
    with np.errstate(divide="ignore"):
        T = 1.0 / (math.pi * MAT.E_star * r)
    np.fill_diagonal(T, 0.0)
    return T


def test_the_secant_start_solves_its_linear_problem_to_single_precision():
    # the secant start: (diag(o/f(o)) + T) P = o on the tips that reach the body, clipped at
    # zero; solved here in double precision by numpy, it agrees to 1e-5 of the largest force,
    # and the macro step's answer is the same as from no force
    from twoscale.influence.halfspace import HalfSpace
    from twoscale.macro.solve import _build_system
    from twoscale.macro.start import secant_forces as _secant_forces
    from twoscale.macro.start import MacroStart

    rng = np.random.default_rng(7)
    tips = rng.uniform(-3.0, 3.0, (60, 2))
    z = rng.uniform(0.0, 0.004, 60)
    laws = [HertzLaw(float(R), MAT.E_star) for R in rng.uniform(1.0, 3.0, 60)]
    stack = LawStack(laws)
    d = 0.003
    T = _boussinesq(tips)
    P = _secant_forces(_build_system(T, tips, z, stack, d, None, False, (0.0, 0.0)), stack)
    o = d - z
    A = np.flatnonzero(o > 0)
    K = T[np.ix_(A, A)] + np.diag(o[A] / stack.force(o)[A])
    exact = np.zeros(60)
    exact[A] = np.maximum(np.linalg.solve(K, o[A]), 0.0)
    assert A.size > 20 and np.count_nonzero(exact) > 20
    assert np.max(np.abs(P - exact)) <= 1e-5 * exact.max()
    provider = HalfSpace(MAT)
    cold = solve_macro(provider, tips, z, laws, Loading(d, None))
    zero = solve_macro(provider, tips, z, laws, Loading(d, None), start=MacroStart(np.zeros(60)))
    assert cold.converged and zero.converged
    assert np.max(np.abs(cold.forces - zero.forces)) <= 1e-9 * zero.forces.max()


def test_a_merged_pair_hands_over_to_the_safe_path_a_step_sooner(monkeypatch):
    # seed 2's 68 spheres under penetration (#36), merged pairs: Newton's seventh step takes
    # off under 0.1 % of its residual, below STALL_RESIDUAL; it hands over there instead of
    # after the four-step window, and the safe path gives the forces it gives after the later
    # hand-over
    import twoscale.macro.newton as macro_newton
    from helpers import sweep_macro_inputs
    from twoscale.laws import law_for

    from twoscale.macro.start import MacroStart

    scene, tips, z, provider = sweep_macro_inputs(36, seed=2)

    def solve():  # from no force given: the cold start would take the safe path without Newton
        laws = [law_for(a, provider.material) for a in scene.asperities]
        start = MacroStart(np.zeros(len(z)))
        return solve_macro(provider, tips, z, laws, Loading(scene.penetration, scene.total_load), start=start)

    quick = solve()
    monkeypatch.setattr(macro_newton, "STALL_STEP_DROP", 0.0)
    slow = solve()
    assert quick.converged and quick.safe_path and "down by under 0.1% in one step" in quick.message
    assert slow.converged and slow.safe_path and "not halved in 4 steps" in slow.message
    assert quick.iterations < slow.iterations
    assert np.max(np.abs(quick.forces - slow.forces)) <= 1e-10 * slow.forces.max()


def test_a_cold_start_whose_secant_problem_is_not_definite_takes_the_safe_path_at_once():
    # the same merged pairs from the cold start: the secant start's problem is not definite,
    # so the safe path runs without Newton first (one polishing step), and its forces are
    # those of Newton's stall then the safe path, from no force given
    from helpers import sweep_macro_inputs
    from twoscale.laws import law_for
    from twoscale.macro.start import MacroStart

    scene, tips, z, provider = sweep_macro_inputs(36, seed=2)
    laws = [law_for(a, provider.material) for a in scene.asperities]
    loading = Loading(scene.penetration, scene.total_load)
    cold = solve_macro(provider, tips, z, laws, loading)
    newton = solve_macro(provider, tips, z, laws, loading, start=MacroStart(np.zeros(len(z))))
    assert cold.converged and cold.safe_path and "secant start's problem is not definite" in cold.message
    assert newton.converged and newton.safe_path and "Newton stalled" in newton.message
    assert cold.iterations < newton.iterations
    assert np.max(np.abs(cold.forces - newton.forces)) <= 1e-9 * newton.forces.max()
