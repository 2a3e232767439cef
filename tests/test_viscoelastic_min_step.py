"""The automatic time steps end with a message where the error estimate does not fall
with the step: a step rejected at the shortest step stops the history (no march of
ever shorter steps until the step budget runs out)."""

import math

import numpy as np

import twoscale.viscoelastic.solve as history_solve
from twoscale.indenters import Asperity
from twoscale.material import Material
from twoscale.scene import Scene
from twoscale.viscoelastic import LoadHistory, TimeSteps, solve_history
from twoscale.viscoelastic.stepping import MIN_STEP_FRACTION, Controller


def test_the_controller_stops_at_the_shortest_step():
    steps = TimeSteps()
    ctl = Controller(steps, np.array([0.0, 10.0]), 1.0, 10.0)
    ctl.restart(0.0)
    t, calls = 0.0, 0
    while ctl.stuck is None:
        dt = ctl.propose(t) - t
        assert not ctl.accept(dt, 1.0)  # an estimate that never falls
        calls += 1
        assert calls < 200
    # halvings from the first step (0.05 s) down to the shortest, and no more
    assert calls <= math.ceil(math.log2(0.05 / (MIN_STEP_FRACTION * 10.0))) + 2
    assert "time.tol" in ctl.stuck and "shortest step" in ctl.stuck
    assert ctl.dt >= 0.5 * MIN_STEP_FRACTION * 10.0


def test_a_history_whose_estimate_never_falls_stops_with_a_message(monkeypatch):
    monkeypatch.setattr(history_solve, "local_error", lambda *args: 1.0)
    tip = (Asperity(0.0, 0.0, 0.0, 10.0, "paraboloid"),)
    history = LoadHistory("total", ((0.0, 0.0), (1.0, 1.0), (3.0, 1.0)), steps=TimeSteps(max_steps=200))
    scene = Scene(Material(2.0, 0.5, prony=((8.0, 1.0),)), tip, h=0.1, history=history)
    res = solve_history(scene, method="cg")
    assert not res.converged
    assert "stopped at t = " in res.message and "error estimate" in res.message
    # the steps before the estimate starts, then the halvings down to the shortest step
    assert len(res.steps) < 10 and res.rejected < 60


def test_an_approach_that_returns_to_zero_converges_with_automatic_steps():
    # pressed 0.1 mm over 1 s and withdrawn over the next: the rubber lags, so the contact
    # opens before the approach is back to zero, and from there the forces are zero. The step
    # error of a quantity near zero is measured against 1 % of its largest value so far (it
    # was measured against zero, and the history stopped at t = 1.86 s)
    R, d = 10.0, 0.1
    tip = (Asperity(0.0, 0.0, 0.0, R, "paraboloid"),)
    history = LoadHistory("penetration", ((0.0, 0.0), (1.0, d), (2.0, 0.0)), output=(1.0, 2.0))
    material = Material(2.0, 0.5, prony=((8.0, 0.3),))
    res = solve_history(Scene(material, tip, h=0.1, history=history), method="cg")
    assert res.converged, res.message
    load = [r.total_load for r in res.results]
    assert load[1] == 0.0
    # at 1 s the load lies between the relaxed and the glassy Hertz loads at that approach
    relaxed = 4.0 / 3.0 * (2.0 / 0.75) * math.sqrt(R) * d**1.5
    assert relaxed < load[0] < 5.0 * relaxed
