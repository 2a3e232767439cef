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
    # (each minimisation to its own tolerance: the early hand-over to Newton is refused too)
    solve, _ = merged_eight
    calls = _counting_minimiser(monkeypatch)
    monkeypatch.setattr(robust.MacroSystem, "stable", lambda self, x: False)
    monkeypatch.setattr(robust, "EARLY_MAX_TIPS", 0)
    refused = solve()
    assert refused.converged and len(calls) == 4
    monkeypatch.undo()
    calls = _counting_minimiser(monkeypatch)
    monkeypatch.setattr(robust, "NEAR_MAX_TIPS", 0)
    monkeypatch.setattr(robust, "EARLY_MAX_TIPS", 0)
    plain = solve()
    assert len(calls) == 4
    assert np.max(np.abs(refused.forces - plain.forces)) <= 1e-12 * plain.forces.max()


@pytest.fixture(scope="module")
def merged_pairs():
    """Seed 2's 68 spheres under penetration control (#36), merged pairs: the secant start's
    problem is not definite and the safe path's minimiser runs from no force."""
    scene, tips, z, provider = sweep_macro_inputs(36, seed=2)
    laws = [law_for(a, provider.material) for a in scene.asperities]
    return lambda: solve_macro(provider, tips, z, laws, Loading(scene.penetration, None))


def test_the_minimiser_hands_over_to_newton_early_at_the_same_minimum(merged_pairs, monkeypatch):
    calls = _counting_minimiser(monkeypatch)
    early = merged_pairs()
    stages = list(calls)
    calls.clear()
    monkeypatch.setattr(robust, "EARLY_MAX_TIPS", 0)  # the minimiser to its own tolerance
    plain = merged_pairs()
    assert early.converged and plain.converged and early.safe_path and plain.safe_path
    assert "then by Newton" in early.message and "then polished" in plain.message
    assert len(stages) == 1 and len(calls) == 1 and stages[0] < calls[0]
    assert np.max(np.abs(early.forces - plain.forces)) <= 1e-9 * plain.forces.max()


def test_an_early_newton_that_ends_off_a_minimum_lets_the_minimiser_go_on(merged_pairs, monkeypatch):
    # every point Newton ends at declared a saddle: the minimiser goes on from where it
    # stopped to its own tolerance, and the forces are those of the minimiser alone
    calls = _counting_minimiser(monkeypatch)
    monkeypatch.setattr(robust.MacroSystem, "stable", lambda self, x: False)
    refused = merged_pairs()
    assert refused.converged and "then polished" in refused.message and len(calls) == 2
    monkeypatch.undo()
    monkeypatch.setattr(robust, "EARLY_MAX_TIPS", 0)
    plain = merged_pairs()
    assert np.max(np.abs(refused.forces - plain.forces)) <= 1e-9 * plain.forces.max()
