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
def test_the_block_iterations_get_the_macro_step_to_its_tolerance(monkeypatch, iteration):
    import twoscale.driver as driver

    asps = spaced_spheres(20, 4, 10.0)
    whole = solve_twoscale(HS, asps, h=0.05, penetration=0.06, iteration=iteration)
    monkeypatch.setattr(driver, "STAGED_MIN_TIPS", 1)
    res = solve_twoscale(HS, asps, h=0.05, penetration=0.06, iteration=iteration)
    assert res.details.macro.converged and res.residuals["macro"][-1] <= 1e-10
    assert res.converged, res.message
    assert "macro step" not in res.message
    # the second stage goes on from the first: both stages' steps counted, the same path
    history = res.residuals["macro"]
    assert history[0] > SIZING_RESIDUAL and len(history) == res.iterations["macro"] + 1
    assert res.iterations["macro"] == whole.iterations["macro"]
    assert np.allclose(history, whole.residuals["macro"], rtol=1e-6, atol=1e-14)
    F, Fw = np.asarray(res.asperities.forces), np.asarray(whole.asperities.forces)
    assert np.max(np.abs(F - Fw)) <= 1e-5 * Fw.max()  # patches sized by the first stage: the micro tolerance


def test_a_first_stage_ended_on_the_safe_paths_skip_is_not_refined(monkeypatch):
    # among more tips than the safe path is tried on, a first stage that stalled (or met an
    # unstable equilibrium of merged contacts) hands its iterate to the micro step as it is:
    # Newton from there stalled again on the sweep's 1,013 and 1,485 spheres (five steps and
    # one), so the block iterations are not given a second stage
    import twoscale.driver as driver
    import twoscale.macro.solve as macro_solve

    asps = spaced_spheres(20, 4, 10.0)
    whole = solve_twoscale(HS, asps, h=0.05, penetration=0.06, iteration="two-level")
    monkeypatch.setattr(driver, "STAGED_MIN_TIPS", 1)
    monkeypatch.setattr(macro_solve, "SAFE_PATH_MAX_TIPS", 1)
    # the first stage (to 1e-3 here) stops short after one step, 2.4e-3: a stall
    monkeypatch.setattr(driver, "SIZING_RESIDUAL", 1e-3)
    monkeypatch.setattr(macro_solve, "FAST_STEPS", 1)
    res = solve_twoscale(HS, asps, h=0.05, penetration=0.06, iteration="two-level")
    macro = res.details.macro
    assert not macro.converged and "micro step starts from Newton's last iterate" in res.message
    # the first stage's one step only (refined, one more, to 5e-7)
    assert res.iterations["macro"] == 1 and len(res.residuals["macro"]) == 2
    assert res.converged, res.message
    F, Fw = np.asarray(res.asperities.forces), np.asarray(whole.asperities.forces)
    assert np.max(np.abs(F - Fw)) <= 1e-5 * Fw.max()


@pytest.mark.parametrize("iteration", ["union-cg", "block-gs"])
def test_the_first_stage_holds_its_matrix_free_operator_to_a_looser_error(monkeypatch, iteration):
    # the first stage only sizes the patches and starts the micro step: its Ewald operator
    # is built to FIRST_STAGE_OPERATOR_RTOL; a second stage (the block iterations) builds
    # one to the macro options' operator_rtol; the forces are the unstaged solve's
    import twoscale.driver as driver
    import twoscale.influence.halfspace_points as hp

    monkeypatch.setattr(hp, "FAST_ENTRIES", 0)  # the Ewald operator for 80 tips
    asked = []

    class Spy(hp.EwaldPointOperator):
        def __init__(self, *args, rtol, **kw):
            asked.append(rtol)
            super().__init__(*args, rtol=rtol, **kw)

    monkeypatch.setattr(hp, "EwaldPointOperator", Spy)
    asps = spaced_spheres(20, 4, 10.0)
    kw = dict(h=0.05, penetration=0.06, iteration=iteration, macro_dense_max=1, tol=1e-9)
    whole = solve_twoscale(HS, asps, **kw)
    assert asked == [1e-6] and whole.details.macro.converged
    monkeypatch.setattr(driver, "STAGED_MIN_TIPS", 1)
    asked.clear()
    staged = solve_twoscale(HS, asps, **kw)
    assert asked == ([driver.FIRST_STAGE_OPERATOR_RTOL] + ([1e-6] if iteration == "block-gs" else []))
    assert driver.FIRST_STAGE_OPERATOR_RTOL > 1e-6
    assert staged.converged, staged.message
    assert staged.details.macro.converged == (iteration == "block-gs")
    F, Fw = np.asarray(staged.asperities.forces), np.asarray(whole.asperities.forces)
    assert np.max(np.abs(F - Fw)) <= (1e-6 if iteration == "union-cg" else 1e-5) * Fw.max()
