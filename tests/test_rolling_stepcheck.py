"""The step of a viscoelastic rolling run against the road's samples and the active Prony
branches (:mod:`twoscale.rolling.stepcheck`): the criterion on values worked by hand, the
warning, and the Richardson estimate of the friction's step error on drags whose error is
known."""

from __future__ import annotations

import math
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from twoscale import Material
from twoscale.errors import StepWarning
from twoscale.rolling import RollingSpec
from twoscale.rolling.stepcheck import active_tau, check_step, friction, step_error, warn_if_coarse

V36 = 36.0  # km/h: 1e4 mm/s


def _spec(step: float) -> RollingSpec:
    return RollingSpec(start=0.0, end=10.0, step=step, speed=V36)


def test_speed_in_mm_per_second():
    assert _spec(1.0).speed_mm_s == pytest.approx(1e4)


@pytest.mark.parametrize(
    "prony, spacing, length, tau",
    [
        (((10.0, 1e-4), (10.0, 1e-3)), 0.25, 200.0, 1e-4),  # v tau = 1 and 10 mm: both active
        (((10.0, 1e-6), (10.0, 1e-3)), 0.25, 200.0, 1e-3),  # v tau = 0.01 mm < h / pi: too fast
        (((10.0, 1e-3), (10.0, 1.0)), 0.25, 200.0, 1e-3),  # 2 pi v tau = 63 km > L: too slow (not the shortest)
        (((10.0, 1.0),), 0.25, 200.0, None),  # only a glassy branch
        (((10.0, 1e-3), (0.05, 1e-4)), 0.25, 200.0, 1e-3),  # 0.5 % of the branches' modulus: inactive
        (((10.0, 1e-6),), None, math.inf, 1e-6),  # tips: no texture bound
    ],
)
def test_active_branches(prony, spacing, length, tau):
    got = active_tau(Material(5.0, 0.5, prony=prony), 1e4, spacing, length)
    assert got == (pytest.approx(tau) if tau is not None else None)


def test_limit_is_the_smaller_of_the_spacing_and_the_branch_length():
    mat = Material(5.0, 0.5, prony=((10.0, 1e-4),))  # v tau = 1 mm
    fine = check_step(_spec(0.25), mat, 0.25, 200.0)
    assert fine.limit == pytest.approx(0.25) and not fine.coarse and fine.message == ""
    coarse = check_step(_spec(0.5), mat, 0.25, 200.0)
    assert coarse.coarse and coarse.branch_length == pytest.approx(1.0)
    assert coarse.message.startswith("rolling.step = 0.5 mm") and "\n" not in coarse.message
    # a branch shorter than the spacing sets the limit: v tau = 0.1 mm on a 0.25 mm map
    fast = check_step(_spec(0.125), Material(5.0, 0.5, prony=((10.0, 1e-5),)), 0.25, 200.0)
    assert fast.limit == pytest.approx(0.1) and fast.coarse
    # an elastic body has no hysteresis to resolve: never coarse
    assert not check_step(_spec(2.0), Material(5.0, 0.5), 0.25, 200.0).coarse
    record = coarse.to_dict()
    assert record["coarse"] and record["limit_mm"] == pytest.approx(0.25) and record["message"] == coarse.message


def test_warning_only_when_coarse():
    mat = Material(5.0, 0.5, prony=((10.0, 1e-4),))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warn_if_coarse(check_step(_spec(0.25), mat, 0.25, 200.0))
        assert not caught
        warn_if_coarse(check_step(_spec(1.0), mat, 0.25, 200.0))
    assert len(caught) == 1 and issubclass(caught[0].category, StepWarning)
    assert "rolling.step" in str(caught[0].message)
    # the warning points at the user's line, not into the package
    assert caught[0].filename == __file__


def _run(step: float, length: float, drag) -> SimpleNamespace:
    s = np.arange(0.0, length + 1e-9, step)
    return SimpleNamespace(shifts=s, drag=drag(s, step))


def test_friction_is_the_drag_work_over_the_distance():
    run = _run(0.5, 10.0, lambda s, ds: 2.0 + 0.0 * s)
    assert friction(run) == pytest.approx(2.0)
    ramp = _run(0.5, 10.0, lambda s, ds: s)  # trapezoid exact on a line: mean of 0..L over L = L / 2
    assert friction(ramp) == pytest.approx(5.0) and friction(ramp, 4.0) == pytest.approx(2.0)


def test_richardson_recovers_a_first_order_error():
    """Drags whose mean is F - c step (first order, as measured): the estimate from the run
    at the step and at twice the step gives back F, whatever the texture's ripple."""
    F, c = 3.0, 0.8
    drag = lambda s, ds: F - c * ds + 0.7 * np.sin(2 * np.pi * s / 5.0)  # noqa: E731 (the ripple averages out over 10 mm)
    fine, coarse = _run(0.25, 10.0, drag), _run(0.5, 10.0, drag)
    est = step_error(fine, coarse)
    assert est["distance_mm"] == pytest.approx(10.0)
    assert est["estimated_error_N"] == pytest.approx(c * 0.25, rel=1e-6)
    assert est["extrapolated_friction_N"] == pytest.approx(F, rel=1e-6)
    # a fine run one step longer: compared over the distance both cover
    longer = _run(0.25, 10.25, drag)
    assert step_error(longer, coarse)["extrapolated_friction_N"] == pytest.approx(F, abs=2e-3)


@pytest.fixture(scope="module")
def one_branch_runs():
    """A chip-seal strip at 0.25 mm under a slice of tyre, one branch of 1 ms at 0.9 km/h
    (v tau = 0.25 mm: the limit is the spacing and the branch at once), rolled 8 mm at steps
    of 4, 2 and 1 times the limit."""
    from twoscale.rolling import road_strip, roll
    from twoscale.scene import Scene
    from twoscale.surface import RawMap, build_surface

    strip = build_surface(RawMap(road_strip(50.0, 14.0, 0.25, seed=7), spacing=0.25, units="mm"))
    material = Material(10.0, 0.5, prony=((40.0, 1e-3),))
    runs = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StepWarning)
        for step in (1.0, 0.5, 0.25):
            spec = RollingSpec(start=-4.0, end=4.0, step=step, speed=0.9, tyre_radius=150.0, footprint=(24.0, 12.0))
            runs[step] = roll(Scene(material=material, surface=strip, penetration=0.9, rolling=spec))
    return runs


def test_coarse_steps_lose_friction_and_the_limit_keeps_it(one_branch_runs):
    """The criterion's boundary on a real run: the friction grows as the step shrinks to the
    limit (measured 4.54, 6.91, 7.88 N; 7.886 N at 0.125 mm on the strip resampled), the
    energy balance closes at the limit (measured -0.4 %) and not at 4 x (-23 %), and
    :func:`step_check` flags exactly the coarse steps. The Richardson estimate with the
    first order is conservative here (the friction converges faster)."""
    runs = one_branch_runs
    assert all(r.all_converged for r in runs.values())
    F = {s: friction(r) for s, r in runs.items()}
    assert F[1.0] < F[0.5] < F[0.25]
    assert F[0.25] - F[0.5] < 0.6 * (F[0.5] - F[1.0])
    assert abs(runs[0.25].energy_balance()["mismatch"]) < 0.02
    assert runs[1.0].energy_balance()["mismatch"] < -0.1
    assert [runs[s].step_check.coarse for s in (1.0, 0.5, 0.25)] == [True, True, False]
    assert runs[0.25].step_check.limit == pytest.approx(0.25)
    est = step_error(runs[0.5], runs[1.0])
    assert est["extrapolated_friction_N"] > F[0.25] > est["friction_N"]


def test_no_active_branch_no_limit():
    elastic = check_step(_spec(2.0), Material(5.0, 0.5), 0.25, 200.0)
    assert math.isinf(elastic.limit) and elastic.to_dict()["limit_mm"] is None
    glassy = check_step(_spec(2.0), Material(5.0, 0.5, prony=((10.0, 10.0),)), 0.25, 200.0)
    assert glassy.branch_tau is None and not glassy.coarse
