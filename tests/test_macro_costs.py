"""What the macro step no longer does twice: the penetrations kept between Newton's residual
and its step, the secant start's single-precision factor.

The answers are checked against closed forms written out here (the local penetrations
``offset - T P``, the secant start's linear problem solved in double precision) and against
the same solve from another start.
"""

import math

import numpy as np

from twoscale import Material
from twoscale.control import Loading
from twoscale.laws import HertzLaw, LawStack
from twoscale.macro import solve_macro
from twoscale.macro.system import MacroSystem

MAT = Material(10.0, 0.5)


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
    from twoscale.macro.solve import _build_system, _secant_forces
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
