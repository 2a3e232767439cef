"""The staged macro step of many asperities (``twoscale.driver.STAGED_MIN_TIPS``): Newton
stops at the sizing residual, and goes on to the macro tolerance only when the micro step
is not the union CG."""

import numpy as np
import pytest

from helpers import spaced_spheres
from twoscale import Material
from twoscale.driver import solve_twoscale
from twoscale.influence import HalfSpace
from twoscale.micro.problem import SIZING_RESIDUAL

HS = HalfSpace(Material(E=10.0, nu=0.5))


@pytest.fixture
def staged(monkeypatch):
    import twoscale.driver as driver

    monkeypatch.setattr(driver, "STAGED_MIN_TIPS", 1)  # these 20 spheres count as many


@pytest.mark.parametrize("load", [{"penetration": 0.06}, {"total_load": 3.0}])
def test_the_union_cg_starts_from_the_first_stage_and_gives_the_same_forces(monkeypatch, load):
    import twoscale.driver as driver

    asps = spaced_spheres(20, 4, 10.0)
    whole = solve_twoscale(HS, asps, h=0.05, iteration="union-cg", tol=1e-9, **load)
    monkeypatch.setattr(driver, "STAGED_MIN_TIPS", 1)
    staged = solve_twoscale(HS, asps, h=0.05, iteration="union-cg", tol=1e-9, **load)
    full, first = whole.residuals["macro"], staged.residuals["macro"]
    # the first stage stopped at the sizing residual, short of the macro tolerance, and says so
    assert whole.details.macro.converged and full[-1] <= 1e-10
    assert first[-1] <= SIZING_RESIDUAL < first[-2] and len(first) < len(full)
    assert not staged.details.macro.converged
    assert "stopped at relative residual" in staged.message
    assert staged.converged, staged.message
    F, Fw = np.asarray(staged.asperities.forces), np.asarray(whole.asperities.forces)
    assert np.max(np.abs(F - Fw)) <= 1e-6 * Fw.max()


@pytest.mark.parametrize("iteration", ["block-gs", "two-level"])
def test_the_block_iterations_get_the_macro_step_to_its_tolerance(staged, iteration):
    asps = spaced_spheres(20, 4, 10.0)
    res = solve_twoscale(HS, asps, h=0.05, penetration=0.06, iteration=iteration)
    assert res.details.macro.converged and res.residuals["macro"][-1] <= 1e-10
    assert res.converged, res.message
    assert "macro step" not in res.message
