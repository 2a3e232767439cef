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
