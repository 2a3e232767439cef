"""Macro step: tip forces with interaction, load control, tilt (docs/method.md section 2).

Checks are independent of the solver: equations are recomputed from scratch with the
Boussinesq kernel written out here, scalar cases are solved with brentq.
"""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from twoscale import Material
from twoscale.influence.halfspace import HalfSpace
from twoscale.laws import CompliantLaw, HertzLaw, SphereLaw, TabulatedLaw
from twoscale.control import Loading
from twoscale.macro import solve_macro as _solve_macro
from twoscale.options import MacroOptions

from helpers import newton_on_a_line


def solve_macro(provider, tips, z, laws, *, start=None, self_compliance=True, **keywords):
    """``twoscale.macro.solve_macro`` with its loading and options given as keywords here."""
    load = {k: keywords.pop(k) for k in ("penetration", "total_load", "tilt", "pivot") if k in keywords}
    return _solve_macro(
        provider, tips, z, laws, Loading(**load), MacroOptions(**keywords), start=start, self_compliance=self_compliance
    )


MAT = Material(10.0, 0.5)
E_STAR = MAT.E_star
HS = HalfSpace(MAT)


def boussinesq_interaction(tips):
    r = np.hypot(*(tips[:, None, :] - tips[None, :, :]).transpose(2, 0, 1))
    with np.errstate(divide="ignore"):
        T = 1.0 / (math.pi * E_STAR * r)
    np.fill_diagonal(T, 0.0)
    return T


def check_equations(res, tips, z, laws, T, pivot=(0.0, 0.0), rtol=1e-10):
    """Recompute delta_k from scratch and check P_k = f_k(delta_k) H(delta_k)."""
    P = res.forces
    alpha, beta = res.tilt if res.tilt is not None else (0.0, 0.0)
    delta = res.penetration - z - beta * (tips[:, 0] - pivot[0]) - alpha * (tips[:, 1] - pivot[1]) - T @ P
    f = np.array([law.force(max(dk, 0.0)) for law, dk in zip(laws, delta)])
    assert np.all(P >= 0)
    assert np.linalg.norm(P - f) <= rtol * np.linalg.norm(P)  # the documented criterion
    assert np.all(P[delta <= 0] == 0)  # complementarity: no force out of contact
    assert np.array_equal(res.in_contact, delta > 0)
    assert np.allclose(res.local_penetrations, delta, rtol=0, atol=1e-12 * max(1.0, np.max(np.abs(delta))))


def random_scene(seed, *, close=(2.5, 3.5), close_fraction=1 / 6, spheres_only=False):
    """10-30 asperities, radii 4-6 mm: a jittered 8 mm lattice, a fraction of them placed
    ``close`` (mm) from a neighbour, a few recessed far out of contact."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(10, 31))
    n_close = max(2, int(n * close_fraction))
    base = n - n_close
    side = int(math.ceil(math.sqrt(base)))
    lattice = 8.0 * np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:base]
    tips = lattice + rng.uniform(-1.5, 1.5, lattice.shape)
    partner = rng.choice(base, n_close, replace=False)
    ang = rng.uniform(0, 2 * np.pi, n_close)
    s = rng.uniform(*close, n_close)
    tips = np.vstack([tips, tips[partner] + np.column_stack([s * np.cos(ang), s * np.sin(ang)])])
    z = rng.uniform(0.0, 0.15, n)
    z[rng.choice(n, max(2, n // 8), replace=False)] = rng.uniform(1.0, 2.0)  # out of contact
    radii = rng.uniform(4.0, 6.0, n)
    kinds = np.ones(n, bool) if spheres_only else rng.random(n) < 0.5
    laws = [SphereLaw(r, E_STAR) if k else HertzLaw(r, E_STAR) for r, k in zip(radii, kinds)]
    return tips, z, laws


def test_single_asperity_equals_its_law():
    law = SphereLaw(5.0, E_STAR)
    tips, z = np.array([[1.0, 2.0]]), np.array([0.1])
    res = solve_macro(HS, tips, z, [law], penetration=0.4)
    assert res.converged and res.forces[0] == pytest.approx(float(law.force(0.3)), rel=1e-12)
    res = solve_macro(HS, tips, z, law, total_load=7.0)
    assert res.converged and res.forces[0] == pytest.approx(7.0, rel=1e-12)
    assert res.penetration == pytest.approx(0.1 + float(law.penetration(7.0)), rel=1e-10)
    res = solve_macro(HS, tips, z, law, penetration=0.05)
    assert res.converged and res.forces[0] == 0.0 and not res.in_contact[0]


@pytest.mark.parametrize("W", [1e-100, 1e-200])
def test_a_load_far_below_the_first_bracket_step_is_found(W):
    # the start's root lies ~60-130 decades below the bracket's first step: Brent's method
    # bisects once per halving there, past scipy's default of 100 iterations (a traceback)
    law = HertzLaw(5.0, E_STAR)
    res = solve_macro(HS, np.array([[0.0, 0.0]]), np.zeros(1), law, total_load=W)
    d_hertz = (3.0 * W / (4.0 * E_STAR * math.sqrt(5.0))) ** (2.0 / 3.0)  # closed form
    assert res.converged and res.penetration == pytest.approx(d_hertz, rel=1e-9)


def test_a_load_no_finite_approach_carries_is_refused_naming_it():
    with pytest.raises(ValueError, match=r"load.total = 1e\+300 N") as info:
        solve_macro(HS, np.array([[0.0, 0.0]]), np.zeros(1), SphereLaw(5.0, E_STAR), total_load=1e300)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("s", [1.5, 3.0, 10.0])
@pytest.mark.parametrize("law", [HertzLaw(5.0, E_STAR), SphereLaw(4.0, E_STAR)], ids=["hertz", "sphere"])
def test_two_identical_asperities_solve_the_scalar_equation(s, law):
    d = 0.3
    t = 1.0 / (math.pi * E_STAR * s)
    P_ref = brentq(lambda P: P - law.force(d - t * P), 0.0, float(law.force(d)), xtol=1e-15, rtol=1e-15)
    res = solve_macro(HS, np.array([[0.0, 0.0], [s, 0.0]]), np.zeros(2), law, penetration=d)
    assert res.converged
    assert np.allclose(res.forces, P_ref, rtol=1e-11)
    assert P_ref < 0.99 * law.force(d)  # the interaction matters in this test


def test_far_apart_asperities_are_independent():
    # 1e9 mm apart: the interaction shifts delta by ~T P = 3e-10 mm, P by ~1e-9 relative
    tips = np.array([[0.0, 0.0], [1e9, 0.0], [0.0, 1e9]])
    z = np.array([0.0, 0.1, 0.2])
    laws = [HertzLaw(4.0, E_STAR), SphereLaw(5.0, E_STAR), HertzLaw(6.0, E_STAR)]
    res = solve_macro(HS, tips, z, laws, penetration=0.5)
    alone = [float(l.force(0.5 - zk)) for l, zk in zip(laws, z)]
    assert res.converged and np.allclose(res.forces, alone, rtol=3e-9)


@pytest.mark.parametrize("seed", range(8))
def test_random_scene_penetration_control(seed):
    tips, z, laws = random_scene(seed)
    res = solve_macro(HS, tips, z, laws, penetration=0.4)
    assert res.converged, res.message
    assert res.iterations <= 20
    assert res.residuals[-1] <= 1e-10
    check_equations(res, tips, z, laws, boussinesq_interaction(tips))
    assert 0 < res.in_contact.sum() < len(z)  # the scene mixes contact and no contact


@pytest.mark.parametrize("seed", range(8))
def test_random_scene_load_control_matches_penetration_control(seed):
    tips, z, laws = random_scene(seed)
    W = 10.0 * len(z)
    res = solve_macro(HS, tips, z, laws, total_load=W)
    assert res.converged, res.message
    assert res.iterations <= 20
    assert abs(res.forces.sum() - W) <= 1e-10 * W
    check_equations(res, tips, z, laws, boussinesq_interaction(tips))
    again = solve_macro(HS, tips, z, laws, penetration=res.penetration)
    assert again.converged and np.allclose(again.forces, res.forces, rtol=1e-9, atol=1e-9 * W)


def _tilt_equations(res, tips, pivot, W):
    P = res.forces
    X, Y = tips[:, 0] - pivot[0], tips[:, 1] - pivot[1]
    assert abs(P.sum() - W) <= 1e-10 * W
    assert abs(X @ P) <= 1e-10 * (np.abs(X) @ P)
    assert abs(Y @ P) <= 1e-10 * (np.abs(Y) @ P)


@pytest.mark.parametrize("seed", range(6))
def test_random_scene_tilt(seed):
    tips, z, laws = random_scene(seed)
    W = 10.0 * len(z)
    pivot = tuple(tips.mean(axis=0) + np.array([1.0, -0.5]))
    res = solve_macro(HS, tips, z, laws, total_load=W, tilt=True, pivot=pivot)
    assert res.converged, res.message
    assert res.iterations <= 25
    _tilt_equations(res, tips, pivot, W)
    check_equations(res, tips, z, laws, boussinesq_interaction(tips), pivot=pivot)


def hexagon(radius, centre=True):
    ang = np.arange(6) * np.pi / 3
    ring = radius * np.column_stack([np.cos(ang), np.sin(ang)])
    return np.vstack([[0.0, 0.0], ring]) if centre else ring


def test_tilt_vanishes_on_a_symmetric_scene():
    tips = hexagon(6.0) + np.array([3.0, -2.0])
    res = solve_macro(HS, tips, np.zeros(7), SphereLaw(6.0, E_STAR), total_load=100.0, tilt=True, pivot=(3.0, -2.0))
    assert res.converged
    assert max(abs(res.tilt[0]), abs(res.tilt[1])) < 1e-14
    plain = solve_macro(HS, tips, np.zeros(7), SphereLaw(6.0, E_STAR), total_load=100.0)
    assert np.allclose(res.forces, plain.forces, rtol=1e-12)


def test_tilt_balances_an_asymmetric_scene():
    # an extra asperity at +x would carry a moment about y: the joint tilts the surface
    # up on the +x side (beta > 0) and shares the load so that the moment vanishes
    tips = np.vstack([hexagon(6.0), [[12.0, 0.0]]])
    z = np.zeros(8)
    res = solve_macro(HS, tips, z, SphereLaw(6.0, E_STAR), total_load=100.0, tilt=True)
    assert res.converged
    alpha, beta = res.tilt
    assert beta > 1e-4 and abs(alpha) < 1e-14
    _tilt_equations(res, tips, (0.0, 0.0), 100.0)
    check_equations(res, tips, z, [SphereLaw(6.0, E_STAR)] * 8, boussinesq_interaction(tips))


class ScaledLayer(HalfSpace):
    """A fake body: Boussinesq cut off smoothly, u = (1/(pi E* r)) exp(-r/t), plus a
    smooth self-compliance -1/(pi E* t). Not a real body; it only proves the macro step
    takes the compliance from the provider."""

    t = 4.0

    def point_compliance(self, targets, sources):
        r = np.hypot(*(np.asarray(targets)[:, None, :] - np.asarray(sources)[None, :, :]).transpose(2, 0, 1))
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.exp(-r / self.t) / (math.pi * self.E_star * r)

    def smooth_self_compliance(self, points):
        return np.full(len(points), -1.0 / (math.pi * self.E_star * self.t))


def test_macro_uses_the_provider_compliance():
    body = ScaledLayer(MAT)
    law = HertzLaw(5.0, E_STAR)
    s, d = 3.0, 0.3
    c = -1.0 / (math.pi * E_STAR * body.t)
    t = math.exp(-s / body.t) / (math.pi * E_STAR * s)
    own = CompliantLaw(law, c)  # delta = delta_law(P) + c P, independently inverted
    P_ref = brentq(lambda P: P - own.force(d - t * P), 0.0, 2 * float(law.force(d)), xtol=1e-15, rtol=1e-15)
    res = solve_macro(body, np.array([[0.0, 0.0], [0.0, s]]), np.zeros(2), law, penetration=d)
    assert res.converged and np.allclose(res.forces, P_ref, rtol=1e-10)
    half = solve_macro(HS, np.array([[0.0, 0.0], [0.0, s]]), np.zeros(2), law, penetration=d)
    assert abs(half.forces[0] - P_ref) > 0.02 * P_ref
    # laws that already hold the body's own compliance: self_compliance=False
    res = solve_macro(body, np.array([[0.0, 0.0], [0.0, s]]), np.zeros(2), own, penetration=d, self_compliance=False)
    assert res.converged and np.allclose(res.forces, P_ref, rtol=1e-9)


def test_tabulated_law_in_the_macro_step():
    hertz = HertzLaw(5.0, E_STAR)
    dt = np.linspace(0.0, 0.6, 121)
    tab = TabulatedLaw(dt, hertz.force(dt))
    tips, z, _ = random_scene(3)
    a = solve_macro(HS, tips, z, hertz, penetration=0.4)
    b = solve_macro(HS, tips, z, tab, penetration=0.4)
    assert a.converged and b.converged
    # the table's interpolation error near delta = 0 is ~1e-5 of P(0.6)
    assert np.max(np.abs(a.forces - b.forces)) <= 1e-4 * np.max(a.forces)


def test_iteration_limit_is_reported():
    tips, z, laws = random_scene(1)
    res = solve_macro(HS, tips, z, laws, penetration=0.4, max_iter=1)
    assert not res.converged and res.iterations == 1
    assert "max_iter=1" in res.message and len(res.residuals) == 2
    res = solve_macro(HS, tips, z, laws, total_load=100.0, tilt=True, max_iter=1)
    assert not res.converged


def test_result_fields():
    tips, z, laws = random_scene(2)
    res = solve_macro(HS, tips, z, laws, total_load=50.0)
    assert res.tilt is None and res.total_load == pytest.approx(50.0, rel=1e-12)
    assert res.forces.shape == res.local_penetrations.shape == res.in_contact.shape == (len(z),)
    assert set(res.timings_s) >= {"compliance", "newton", "total"}
    assert len(res.residuals) == res.iterations + 1
    with pytest.raises(ValueError):
        res.forces[0] = 1.0


@pytest.mark.parametrize(
    "kwargs, shown",
    [
        (dict(), "exactly one"),
        (dict(penetration=0.1, total_load=1.0), "exactly one"),
        (dict(penetration=0.1, tilt=True), "tilt"),
        (dict(total_load=-1.0), "-1.0"),
        (dict(penetration=float("nan")), "nan"),
        (dict(penetration=0.1, max_iter=0), "max_iter"),
        (dict(penetration=0.1, tol=0.0), "tol"),
    ],
)
def test_invalid_load_raises(kwargs, shown):
    tips = np.array([[0.0, 0.0], [5.0, 0.0]])
    with pytest.raises(ValueError, match=shown):
        solve_macro(HS, tips, np.zeros(2), HertzLaw(5.0, E_STAR), **kwargs)


def test_invalid_scene_raises():
    law = HertzLaw(5.0, E_STAR)
    with pytest.raises(ValueError, match="coincide"):
        solve_macro(HS, np.array([[0.0, 0.0], [0.0, 0.0]]), np.zeros(2), law, penetration=0.1)
    with pytest.raises(ValueError, match="shape"):
        solve_macro(HS, np.zeros((2, 3)), np.zeros(2), law, penetration=0.1)
    with pytest.raises(ValueError, match="one law per asperity"):
        solve_macro(HS, np.array([[0.0, 0.0], [5.0, 0.0]]), np.zeros(2), [law], penetration=0.1)
    with pytest.raises(ValueError, match="z must be finite"):
        solve_macro(HS, np.array([[0.0, 0.0], [5.0, 0.0]]), np.array([0.0, np.inf]), law, penetration=0.1)


def merged_scene(seed):
    """A quarter of the asperities 0.3-2 mm from a neighbour: contacts merge, the
    compliance loses definiteness, plain Newton stalls."""
    return random_scene(seed, close=(0.3, 2.0), close_fraction=1 / 4, spheres_only=True)


def load_kwargs(mode, W, pivot):
    """solve_macro's load arguments for a mode: penetration 0.4 mm, total W, or W with tilt."""
    return {
        "penetration": dict(penetration=0.4),
        "load": dict(total_load=W),
        "tilt": dict(total_load=W, tilt=True, pivot=pivot),
    }[mode]


def merged_case(seed, mode):
    """A merged scene, its load W = 10 N per asperity, the pivot at the tips' mean and the
    solve_macro load arguments of ``mode``."""
    tips, z, laws = merged_scene(seed)
    W = 10.0 * len(z)
    pivot = tuple(tips.mean(axis=0))
    return tips, z, laws, W, pivot, load_kwargs(mode, W, pivot)


@pytest.mark.parametrize("mode", ["penetration", "load", "tilt"])
def test_merged_contacts_converge_on_the_safe_path(mode):
    used_safe_path = False
    for seed in (0, 2, 5, 13):
        tips, z, laws, W, pivot, kwargs = merged_case(seed, mode)
        res = solve_macro(HS, tips, z, laws, **kwargs)
        assert res.converged, (seed, res.message)
        used_safe_path |= "safe path" in res.message
        assert res.safe_path == ("safe path" in res.message)
        check_equations(res, tips, z, laws, boussinesq_interaction(tips), pivot=pivot)
        if mode != "penetration":
            assert abs(res.forces.sum() - W) <= 1e-10 * W
        if mode == "tilt":
            _tilt_equations(res, tips, pivot, W)
    assert used_safe_path  # the scenes do exercise it


@pytest.mark.parametrize("ratio", [0.1, 0.2, 0.5, 5.0])
def test_paper_seven_spheres(ratio):
    # docs/method.md section 4: centre + hexagon of radius d_c = 2R ratio, d = 0.1 R
    R = 10.0
    tips = hexagon(2 * R * ratio)
    law = SphereLaw(R, E_STAR)
    res = solve_macro(HS, tips, np.zeros(7), law, penetration=0.1 * R)
    assert res.converged, res.message
    check_equations(res, tips, np.zeros(7), [law] * 7, boussinesq_interaction(tips))
    assert np.allclose(res.forces[1:], res.forces[1], rtol=1e-9)  # six-fold symmetry
    assert res.forces[0] < res.forces[1]  # the centre is shielded


def test_unbalanceable_tilt_is_reported():
    # the pivot lies outside the tips' convex hull: no tilt can cancel the moment
    tips = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]])
    res = solve_macro(
        HS, tips, np.zeros(4), SphereLaw(5.0, E_STAR), total_load=40.0, tilt=True, pivot=(50.0, 5.0), max_iter=30
    )
    assert not res.converged and res.message
    # no forces at the tips can balance it: the safe path is not tried, Newton's iterate is handed on
    assert "convex hull" in res.message and res.safe_path
    assert res.iterations <= 30


# --- matrix-free interaction (many asperities): point operator + conjugate gradients ----------


@pytest.mark.parametrize("mode", ["penetration", "load", "tilt"])
@pytest.mark.parametrize("seed", [0, 3])
def test_matrix_free_equals_dense(mode, seed):
    # below 4e6 pairs the half-space operator is exact, so the two paths solve the same
    # equations: they agree to the Newton tolerance, and both satisfy them from scratch
    tips, z, laws = random_scene(seed)
    W = 10.0 * len(z)
    pivot = tuple(tips.mean(axis=0) + np.array([1.0, -0.5]))
    kwargs = load_kwargs(mode, W, pivot)
    dense = solve_macro(HS, tips, z, laws, **kwargs)
    free = solve_macro(HS, tips, z, laws, dense_max=1, **kwargs)
    assert dense.interaction == "dense" and free.interaction == "matrix-free"
    assert free.converged, free.message
    assert free.krylov_iterations > 0 and free.operator_error <= 1e-12
    assert np.allclose(free.forces, dense.forces, rtol=0, atol=1e-8 * dense.forces.max())
    check_equations(free, tips, z, laws, boussinesq_interaction(tips), pivot=pivot)
    if mode == "tilt":
        _tilt_equations(free, tips, pivot, W)


def _smallest_active_eigenvalue(res, laws, T):
    # independent of the solver: eigenvalues of I + D^1/2 T_AA D^1/2 at the result
    dl = np.asarray(res.local_penetrations)
    D = np.array([law.stiffness(max(v, 0.0)) for law, v in zip(laws, dl)])
    A = np.flatnonzero((dl > 0) & (D > 0))
    s = np.sqrt(D[A])
    return float(np.linalg.eigvalsh(np.eye(A.size) + s[:, None] * T[np.ix_(A, A)] * s[None, :])[0])


@pytest.mark.parametrize("mode", ["penetration", "load", "tilt"])
def test_merged_contacts_give_the_stable_solution_on_both_paths(mode):
    # Where contacts merge the macro equations have several solutions; Newton can
    # converge to a saddle of the potential. Both paths must return the stable one (the
    # active compliance positive definite), hence the same forces; so must Newton from no
    # force (a start given: under penetration control the dense cold start finds its
    # secant problem not definite and takes the safe path without Newton).
    from twoscale.macro.start import MacroStart

    saddle_rejected = False
    for seed in (0, 2, 5, 13):
        tips, z, laws, W, pivot, kwargs = merged_case(seed, mode)
        T = boussinesq_interaction(tips)
        dense = solve_macro(HS, tips, z, laws, **kwargs)
        free = solve_macro(HS, tips, z, laws, dense_max=1, **kwargs)
        newton = solve_macro(HS, tips, z, laws, start=MacroStart(np.zeros(len(z))), **kwargs)
        assert np.allclose(newton.forces, dense.forces, rtol=0, atol=1e-8 * dense.forces.max()), seed
        for res in (dense, free, newton):
            assert res.converged, (seed, res.message)
            check_equations(res, tips, z, laws, T, pivot=pivot)
            assert _smallest_active_eigenvalue(res, laws, T) > 0, (seed, res.message)
            if mode == "tilt":
                _tilt_equations(res, tips, pivot, W)
            saddle_rejected |= "unstable equilibrium" in res.message
        assert np.allclose(free.forces, dense.forces, rtol=0, atol=1e-8 * dense.forces.max()), seed
    assert saddle_rejected


def lattice_scene(n, seed, pitch=3.0):
    """``n`` spheres of R 2-6 mm jittered on a square lattice of ``pitch`` mm, recesses
    0-0.06 mm: the many-asperity benchmark's kind of scene."""
    rng = np.random.default_rng(seed)
    side = int(math.ceil(math.sqrt(n)))
    grid = pitch * np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:n]
    tips = grid + rng.uniform(-0.7, 0.7, grid.shape)
    z = rng.uniform(0.0, 0.06, n)
    laws = [SphereLaw(r, E_STAR) for r in rng.uniform(2.0, 6.0, n)]
    return tips, z, laws


def test_matrix_free_with_the_fast_operator_is_within_its_tolerance():
    # 2,100 tips: 4.4e6 pairs, so the half-space returns its Ewald operator (error <=
    # rtol of max|u|). A displacement error eps moves a force by at most its stiffness
    # times eps (the coupled system only spreads it), which bounds the force difference
    # against the dense solve independently of the solver.
    tips, z, laws = lattice_scene(2100, seed=4)
    W = 0.05 * len(z)
    rtol = 1e-6
    dense = solve_macro(HS, tips, z, laws, total_load=W, tilt=True, pivot=(60.0, 70.0))
    free = solve_macro(
        HS, tips, z, laws, total_load=W, tilt=True, pivot=(60.0, 70.0), dense_max=2000, operator_rtol=rtol
    )
    assert free.interaction == "matrix-free" and free.converged, free.message
    assert 0.3 < free.in_contact.mean() < 0.9
    T = boussinesq_interaction(tips)
    u_max = np.abs(T @ dense.forces).max()
    assert 0 < free.operator_error <= rtol  # measured on a sample, as promised
    stiff = np.array([law.stiffness(max(d, 0.0)) for law, d in zip(laws, dense.local_penetrations)])
    bound = 3.0 * rtol * u_max * stiff.max()  # 3x: the load and moment rows shift d, alpha, beta too
    assert np.max(np.abs(free.forces - dense.forces)) <= bound
    assert abs(free.forces.sum() - W) <= 1e-10 * W
    # the equations with the exact T hold to the operator's error: delta_k within
    # rtol max|u| (the solver's delta came from the fast product), P_k = f_k(delta_k) within
    # the force bound above
    a, b = free.tilt
    delta = free.penetration - z - b * (tips[:, 0] - 60.0) - a * (tips[:, 1] - 70.0) - T @ free.forces
    assert np.max(np.abs(free.local_penetrations - delta)) <= 3.0 * rtol * u_max
    f = np.array([law.force(max(dk, 0.0)) for law, dk in zip(laws, delta)])
    assert np.max(np.abs(free.forces - f)) <= bound


def test_matrix_free_input_errors():
    law = SphereLaw(5.0, E_STAR)
    tips = np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 0.0]])
    with pytest.raises(ValueError, match="tips 0 and 2 coincide"):
        solve_macro(HS, tips, np.zeros(3), law, penetration=0.1, dense_max=1)
    with pytest.raises(ValueError, match="dense_max must be an integer >= 1, got 0"):
        solve_macro(HS, tips[:2], np.zeros(2), law, penetration=0.1, dense_max=0)
    with pytest.raises(ValueError, match="operator_rtol must be a number in \\(0, 1\\), got 2"):
        solve_macro(HS, tips[:2], np.zeros(2), law, penetration=0.1, operator_rtol=2)


def test_newton_stops_where_it_stagnates_near_a_solution_and_only_there():
    # above SAFE_PATH_MAX_TIPS a stagnating Newton is stopped (2,596 spheres: 20 dense
    # steps, 11 s of CPU, the residual stuck at 3.3e-4 from step 11): a step that removes a
    # tenth of the residual stagnates; far from a solution (relative residual above
    # STALL_RESIDUAL) the same slow steps go on, and plain Newton converges as before
    from twoscale.macro.newton import STALL_RESIDUAL, Stops, newton

    def run(x0, factor, stall):
        return newton_on_a_line(newton, x0, factor, 60, Stops(stall=stall))

    slow = run(0.02, 0.1, 4)
    assert not slow.converged and "stagnated" in slow.message
    h = slow.residuals
    assert h[-5] <= STALL_RESIDUAL < h[-6] and h[-1] > 0.5 * h[-5]
    assert run(0.02, 0.1, None).iterations == 60  # without the check: to max_iter
    fast = run(0.02, 1.0, 4)
    assert fast.converged and fast.iterations == 1
    halving = run(0.02, 0.2, 4)  # 0.8 a step: halves within 4 steps, never stagnates
    assert halving.iterations == 60 and "stagnated" not in halving.message


def test_newton_hands_over_on_a_plateau_above_the_stall_level():
    # up to SAFE_PATH_MAX_TIPS a Newton whose residual, at most PLATEAU_RESIDUAL, falls by
    # under PLATEAU_DROP in ``plateau`` steps stops, above STALL_RESIDUAL too (8 spheres with
    # merged contacts sat at 1.14e-2 for 18 steps before the safe path): 0.2 % a step
    # stops after 4 steps; 5 % a step (19 % in 4) goes on to max_iter; above
    # PLATEAU_RESIDUAL (a cold start's residual at its cap of 1) the slow steps go on too;
    # plain Newton converges as before
    from twoscale.macro.newton import PLATEAU_DROP, PLATEAU_RESIDUAL, STALL_RESIDUAL, Stops, newton

    def run(factor, plateau, x0=0.05):
        return newton_on_a_line(newton, x0, factor, 30, Stops(plateau=plateau))

    flat = run(0.002, 4)
    assert not flat.converged and "stagnated" in flat.message and flat.iterations == 4
    h = flat.residuals
    assert STALL_RESIDUAL < h[-1] <= PLATEAU_RESIDUAL and h[-1] > (1.0 - PLATEAU_DROP) * h[0]
    assert run(0.002, None).iterations == 30  # without the check: to max_iter
    assert run(0.05, 4).iterations == 30 and "stagnated" not in run(0.05, 4).message
    high = run(0.002, 4, x0=2.0 * PLATEAU_RESIDUAL)
    assert high.iterations == 30 and "stagnated" not in high.message
    fast = run(1.0, 4)
    assert fast.converged and fast.iterations == 1


def test_merged_spheres_under_load_hand_over_after_two_flat_steps(monkeypatch):
    # the sweep's eight spheres under load, two of them 0.127 mm apart (merged contacts):
    # Newton sits at 1.14e-2 from its second step; it hands over to the safe path after two
    # flat steps instead of four, and the safe path gives the same forces
    import twoscale.macro.solve as macro_solve
    from helpers import sweep_macro_inputs
    from twoscale.laws import law_for

    scene, tips, z, provider = sweep_macro_inputs(31)

    def solve():
        laws = [law_for(a, provider.material) for a in scene.asperities]
        return _solve_macro(provider, tips, z, laws, Loading(None, scene.total_load))

    quick = solve()
    monkeypatch.setattr(macro_solve, "PLATEAU_STEPS", 4)
    slow = solve()
    assert quick.converged and quick.safe_path and "down by under 1% in 2 steps" in quick.message
    assert slow.converged and quick.iterations == slow.iterations - 2
    assert np.max(np.abs(quick.forces - slow.forces)) <= 1e-12 * slow.forces.max()


def test_a_stall_near_a_solution_hands_over_to_the_safe_path_sooner(monkeypatch):
    # the sweep's 340 spheres under load (seed 0's #77), merged pairs: below STALL_RESIDUAL
    # Newton's residual falls by a few per cent a step, over the plateau's 1 % in two steps;
    # the stall stop hands over once four steps have not halved it, and the safe path gives
    # the forces it gives after a later hand-over (without the stall stop)
    import twoscale.macro.solve as macro_solve
    from helpers import sweep_macro_inputs
    from twoscale.laws import law_for
    from twoscale.macro.newton import STALL_RESIDUAL

    scene, tips, z, provider = sweep_macro_inputs(77)

    def solve():
        laws = [law_for(a, provider.material) for a in scene.asperities]
        return _solve_macro(provider, tips, z, laws, Loading(scene.penetration, scene.total_load))

    quick = solve()
    monkeypatch.setattr(macro_solve, "STALL_STEPS", None)
    slow = solve()
    assert quick.converged and quick.safe_path and "not halved in 4 steps" in quick.message
    h = quick.residuals[:-1]  # Newton's, then the safe path's final one
    assert h[-5] <= STALL_RESIDUAL and h[-1] > 0.5 * h[-5]
    assert slow.converged and slow.safe_path and "not halved in 4 steps" not in slow.message
    assert quick.iterations <= slow.iterations - 4
    assert np.max(np.abs(quick.forces - slow.forces)) <= 1e-10 * slow.forces.max()


def test_two_thousand_tips_go_matrix_free_by_default_with_the_dense_forces():
    """From 2,001 tips the default macro step is matrix-free (the dense step's
    factorisations of the active block cost seconds there): the same forces as the dense
    interaction to its operator's accuracy (1e-6), and those meet the equations."""
    rng = np.random.default_rng(5)
    side = 45  # 2,025 tips on a jittered 6 mm lattice
    lattice = 6.0 * np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)
    tips = lattice + rng.uniform(-1.0, 1.0, lattice.shape)
    z = rng.uniform(0.0, 0.05, len(tips))
    laws = [SphereLaw(5.0, E_STAR)] * len(tips)
    free = solve_macro(HS, tips, z, laws, penetration=0.1)
    dense = solve_macro(HS, tips, z, laws, penetration=0.1, dense_max=3000)
    assert free.interaction == "matrix-free" and dense.interaction == "dense"
    assert free.converged and dense.converged, (free.message, dense.message)
    assert np.max(np.abs(free.forces - dense.forces)) <= 1e-6 * dense.forces.max()
    assert free.krylov_iterations > 0 and np.count_nonzero(dense.forces) > 1000
    check_equations(dense, tips, z, laws, boussinesq_interaction(tips))


def test_newton_steps_refined_single_precision_solve_is_a_double_precision_solve():
    # the Newton step's linear solve: a single-precision LU refined in double precision
    # must give the double-precision solution (a plain single-precision solve is ~1e-6 off)
    # on the macro Jacobian I + D T of close tips, where diag(1/D) + T is indefinite; and
    # the least-squares step where the matrix is singular
    from twoscale.macro.system import _refined_solve

    rng = np.random.default_rng(3)
    n = 400
    pts = rng.uniform(0.0, 6.0, (n, 2))
    r = np.hypot(*(pts[:, None, :] - pts[None, :, :]).transpose(2, 0, 1))
    T = np.where(r > 0, 1.0 / (math.pi * 10.0 * np.where(r > 0, r, 1.0)), 0.0)
    D = rng.uniform(0.5, 20.0, n)
    K = np.eye(n) + D[:, None] * T
    assert np.linalg.eigvalsh(np.diag(1.0 / D) + T)[0] < 0.0
    b = rng.normal(size=n)
    x = _refined_solve(K, b)
    exact = np.linalg.solve(K, b)
    assert np.max(np.abs(x - exact)) <= 1e-11 * np.max(np.abs(exact))
    single = np.linalg.solve(K.astype(np.float32), b.astype(np.float32))
    assert np.max(np.abs(single - exact)) > 1e-9 * np.max(np.abs(exact))  # the refinement is needed
    S = np.array([[1.0, 1.0], [1.0, 1.0]])
    assert np.allclose(_refined_solve(S, np.array([2.0, 0.0])), [0.5, 0.5])


def test_sampled_operator_error_is_the_error_of_the_sampled_rows_written_out():
    # the exact rows made a few at a time (300 rows: the last chunk short) give the error
    # written out with the dense Boussinesq rows, the diagonal left out
    from twoscale.macro.interaction import MatrixFreeInteraction, sampled_operator_error

    tips, _, _ = lattice_scene(2100, seed=4)
    P = np.where(np.arange(len(tips)) % 3 == 0, 1.0 + 0.01 * np.arange(len(tips)), 0.0)
    T = MatrixFreeInteraction(HS.point_operator(tips, tips, rtol=1e-4), np.zeros(len(tips)))
    got = sampled_operator_error(HS, tips, T, P, samples=300, seed=1)
    rows = np.sort(np.random.default_rng(1).choice(len(tips), size=300, replace=False))
    G = boussinesq_interaction(tips)[rows]
    exact = G @ P
    want = np.max(np.abs(T.operator.apply(P)[rows] - exact)) / np.max(np.abs(exact))
    assert 1e-9 < want and got == pytest.approx(want, rel=1e-9)


@pytest.mark.parametrize("slope", [0.01, 0.05])
def test_a_face_set_askew_is_levelled(slope):
    """Four equal spheres on a square, heights rising by ``slope`` along x, pivot at the
    centre: by symmetry each carries W/4 and the face turns by ``beta = -slope`` (from no
    tilt only the low pair touched and the macro step stalled)."""
    tips = np.array([(x, y) for x in (-10.0, 10.0) for y in (-10.0, 10.0)])
    z = slope * tips[:, 0]
    law = SphereLaw(5.0, E_STAR)
    res = solve_macro(HS, tips, z, law, total_load=4.0, tilt=True)
    assert res.converged, res.message
    assert np.allclose(res.forces, 1.0, rtol=1e-10)
    assert abs(res.tilt[1] + slope) < 1e-12 and abs(res.tilt[0]) < 1e-12
    check_equations(res, tips, z, [law] * 4, boussinesq_interaction(tips))


def test_cholesky_in_place_solves_and_refuses_an_indefinite_matrix():
    """The in-place factor solves ``K x = b`` as a dense solve does and overwrites ``K``; an
    indefinite ``K`` (two tips closer than their laws' compliance: the stability test's
    case) gives None."""
    from scipy.linalg import cho_solve

    from twoscale.macro.system import cholesky_in_place

    rng = np.random.default_rng(5)
    tips = rng.uniform(0.0, 20.0, (40, 2))
    T = boussinesq_interaction(tips)
    K = T + np.diag(np.full(40, 1.0))
    b = rng.uniform(0.0, 1.0, 40)
    want = np.linalg.solve(K, b)
    factor = cholesky_in_place(K)
    assert factor is not None and np.shares_memory(factor[0], K)  # (overwritten: no copy)
    assert np.allclose(cho_solve(factor, b), want, rtol=1e-12, atol=0.0)
    close = np.array([[1.0, 2.0], [2.0, 1.0]])  # eigenvalues 3 and -1
    assert cholesky_in_place(close) is None


def test_exact_symmetry_by_blocks_of_rows_is_numpys_comparison_with_the_transpose():
    """The check that lets the secant start and the stability test use ``T`` itself: the
    same answer as ``np.array_equal(M, M.T)``, a block of rows at a time, where one entry off
    the diagonal breaks the symmetry in the last block, or a NaN anywhere."""
    from twoscale.macro.system import SYMMETRY_BLOCK_ENTRIES, exactly_symmetric

    rng = np.random.default_rng(9)
    for n in (1, 2, 63, 64, 65, SYMMETRY_BLOCK_ENTRIES // 64 + 3, 700):
        A = rng.normal(size=(n, n))
        S = A + A.T
        assert exactly_symmetric(S) and exactly_symmetric(S) == np.array_equal(S, S.T)
        if n > 1:
            off = S.copy()
            off[n - 1, 0] += 1e-12 * abs(off[n - 1, 0])
            assert not exactly_symmetric(off) and np.array_equal(off, off.T) is False
            nan = S.copy()
            nan[0, n - 1] = nan[n - 1, 0] = np.nan
            assert exactly_symmetric(nan) == np.array_equal(nan, nan.T)
    assert not exactly_symmetric(np.ones((3, 4)))
