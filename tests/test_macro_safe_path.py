"""The macro step's safe path under load control: the dual ascent's inner minimisations.

Expected figures come from the same solve with the minimiser at every dual point (the path
before Newton was tried there), and from the macro equations themselves.
"""

import numpy as np
import pytest

import twoscale.macro.robust as robust
from helpers import sweep_macro_inputs
from twoscale.control import Loading
from twoscale.laws import law_for
from twoscale.macro import solve_macro


@pytest.fixture(scope="module")
def merged_eight():
    """The sweep's eight spheres under load, two contacts merged (#31): Newton stalls and
    the dual ascent takes three steps from the cold start."""
    scene, tips, z, provider = sweep_macro_inputs(31)

    def solve():
        laws = [law_for(a, provider.material) for a in scene.asperities]
        return solve_macro(provider, tips, z, laws, Loading(None, scene.total_load))

    return solve, scene.total_load


def _counting_minimiser(monkeypatch) -> list:
    calls: list = []
    real = robust.minimize

    def counted(*args, **kwargs):
        out = real(*args, **kwargs)
        calls.append(out.nit)
        return out

    monkeypatch.setattr(robust, "minimize", counted)
    return calls


def test_dual_points_after_the_first_are_found_by_newton_on_the_same_path(merged_eight, monkeypatch):
    solve, load = merged_eight
    calls = _counting_minimiser(monkeypatch)
    near = solve()
    with_newton = list(calls)
    calls.clear()
    monkeypatch.setattr(robust, "NEAR_MAX_TIPS", 0)  # the minimiser at every dual point
    plain = solve()
    assert near.converged and plain.converged and near.safe_path and plain.safe_path
    # the same ascent (three steps), its three trial points by Newton instead of L-BFGS-B
    assert "dual ascent in 3 steps" in near.message and "dual ascent in 3 steps" in plain.message
    assert len(with_newton) == 1 and len(calls) == 4
    assert np.max(np.abs(near.forces - plain.forces)) <= 1e-12 * plain.forces.max()
    assert near.penetration == pytest.approx(plain.penetration, rel=1e-12)
    assert near.forces.sum() == pytest.approx(load, rel=1e-10)


def test_a_newton_dual_point_that_ends_on_a_saddle_is_minimised_instead(merged_eight, monkeypatch):
    # every point Newton ends at declared a saddle: each trial point falls back to the
    # minimiser, and the ascent ends where the minimiser's alone ends
    solve, _ = merged_eight
    calls = _counting_minimiser(monkeypatch)
    monkeypatch.setattr(robust.MacroSystem, "stable", lambda self, x: False)
    refused = solve()
    assert refused.converged and len(calls) == 4
    monkeypatch.undo()
    calls = _counting_minimiser(monkeypatch)
    monkeypatch.setattr(robust, "NEAR_MAX_TIPS", 0)
    plain = solve()
    assert len(calls) == 4
    assert np.max(np.abs(refused.forces - plain.forces)) <= 1e-12 * plain.forces.max()
