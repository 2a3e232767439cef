"""Newton's line search where the projection onto forces >= 0 blocks the Newton direction."""

import numpy as np

from twoscale.macro.newton import Stops, _line_search, newton

# Three tips with the macro equations' form r = P - f(offset - T P), f(d) = max(d, 0)^1.5,
# started with tip 1 at zero force while the Newton direction takes it below zero: clipping
# it at zero leaves no decrease of the residual along the path, the unclipped path has one.
T = np.array([[0.8, 0.55, 0.8], [0.55, 0.1, 1.35], [0.8, 1.35, 0.7]])
OFFSET = np.array([1.8, 2.4, 1.4])
P0 = np.array([0.2, 0.0, 1.2])


def _residual(P):
    return P - np.maximum(OFFSET - T @ P, 0.0) ** 1.5


def _step(P, r):
    d = OFFSET - T @ P
    D = 1.5 * np.sqrt(np.maximum(d, 0.0))
    return np.linalg.solve(np.eye(3) + D[:, None] * T, -r)


def _clip(P):
    return np.maximum(P, 0.0)


def test_the_projected_path_alone_finds_no_decrease():
    r = _residual(P0)
    s = _step(P0, r)
    assert s[1] < 0.0
    assert _line_search(_residual, P0, s, float(np.linalg.norm(r)), _clip) is None
    assert _line_search(_residual, P0, s, float(np.linalg.norm(r)), lambda x: x) is not None


def test_newton_steps_past_the_blocked_projection_to_an_admissible_root():
    kept = newton(_residual, _step, P0, scale=lambda P: 1.0, tol=1e-12, max_iter=50, project=_clip)
    assert not kept.converged and "line search failed" in kept.message
    out = newton(
        _residual, _step, P0, scale=lambda P: 1.0, tol=1e-12, max_iter=50, project=_clip, stops=Stops(unprojected=True)
    )
    assert out.converged, out.message
    assert np.all(out.x >= 0.0)
    # a root of the equations as written here, forces equal to the law at their penetration
    d = OFFSET - T @ out.x
    np.testing.assert_allclose(out.x, np.maximum(d, 0.0) ** 1.5, rtol=0, atol=1e-10)
    assert np.linalg.norm(_residual(out.x)) <= 1e-12


# One unknown, r(x) = 1 + exp(x) from x = 0, a short direction -0.1 (as at a kink, where
# the direction is poor): clipping at zero undoes every step below zero, the unclipped path
# creeps towards r = 1, with an Armijo decrease for 60 steps, and never reaches a root.
def _creeping(x):
    return 1.0 + np.exp(x)


def _creeping_step(x, r):
    return np.full_like(x, -0.1)


def test_newton_stops_where_the_unprojected_search_goes_on_without_gain(monkeypatch):
    import twoscale.macro.newton as newton_module

    args = dict(scale=lambda x: 10.0, tol=1e-8, max_iter=50, project=_clip, stops=Stops(unprojected=True))
    out = newton(_creeping, _creeping_step, np.array([0.0]), **args)
    assert not out.converged and "unprojected" in out.message
    # clipped at zero from the start: every step unprojected, stopped at the window's end
    assert out.iterations == newton_module.UNPROJECTED_STEPS
    assert out.residuals[-1] > 0.5 * out.residuals[0]
    # without the stop the same iteration creeps on to max_iter
    monkeypatch.setattr(newton_module, "UNPROJECTED_STEPS", 10**6)
    longer = newton(_creeping, _creeping_step, np.array([0.0]), **args)
    assert not longer.converged and longer.iterations == 50
    assert longer.residuals[-1] > 0.1
