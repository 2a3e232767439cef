"""A load history under a free tilt with the face set askew by 0.2 rad, and one turned
about a diagonal of loaded tips, the two-scale method against the full-grid reference with
the same steps.

Four spheres (R 5 mm) on a 20 mm square, one pair raised by 4 mm: the face turns by about
0.2 rad, where a sphere's nearest point to the turned face lies about ``R theta^2 / 2``
(0.1 mm) below its apex, so the micro step's approach is 0.1 mm below the macro step's
point tips' one, more than the tips' penetration. Each step starts from the last one's
answer; the history must carry on to the end and agree with the reference at every step.
"""

import warnings

import numpy as np

import twoscale.driver as driver
from twoscale.indenters import Asperity
from twoscale.material import Material
from twoscale.errors import TiltWarning
from twoscale.scene import Scene
from twoscale.viscoelastic import LoadHistory, TimeSteps, solve_history

PRONY = ((15.0, 1e-3), (15.0, 0.1), (15.0, 10.0))
TIPS = (
    Asperity(-10.0, -10.0, 0.0, 5.0),
    Asperity(10.0, -10.0, 0.0, 5.0),
    Asperity(-10.0, 10.0, 4.0, 5.0),
    Asperity(10.0, 10.0, 4.0, 5.0),
)


#: One tip raised 0.4 mm, one 4 mm: the load rests on the diagonal of the two low tips
#: through the pivot, the third low tip just touching (a few per cent of the load).
DIAGONAL = (
    Asperity(-10.0, -10.0, 0.0, 5.0),
    Asperity(10.0, -10.0, 0.0, 5.0),
    Asperity(-10.0, 10.0, 0.4, 5.0),
    Asperity(10.0, 10.0, 4.0, 5.0),
)


def askew_history(steps: TimeSteps, tips=TIPS) -> Scene:
    points = ((0.0, 20.0), (100.0, 20.0), (110.0, 2.0))
    history = LoadHistory("total", points, output=(0.0, 1.0, 100.0, 110.0), steps=steps)
    return Scene(Material(5.0, 0.5, prony=PRONY), tips, tilt=True, pivot=(0.0, 0.0), h=0.1, history=history)


def test_an_askew_history_matches_the_reference_at_every_output():
    scene = askew_history(TimeSteps(at=(0.0, 0.01, 0.1, 1.0, 10.0, 100.0, 105.0, 110.0)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TiltWarning)  # 0.2 rad: the linear tilt's terms it drops
        ts = solve_history(scene, method="twoscale")
        ref = solve_history(scene, method="cg")
    assert ts.converged and ref.converged, (ts.message, ref.message)
    np.testing.assert_array_equal(ts.times, ref.times)
    # the face did turn by about the heights' slope, and the high side carries load
    assert np.all(np.abs(ref.tilt[:, 0] + 0.2) < 0.01)
    assert np.all(ref.forces > 0.2 * ref.forces.max(axis=1, keepdims=True))
    # the tolerances of the two-scale histories against the reference with the same steps
    scale = ref.forces.max()
    assert np.abs(ts.forces - ref.forces).max() < 2e-4 * scale
    assert np.abs(ts.penetration - ref.penetration).max() < 1e-4 * np.abs(ref.penetration).max()
    assert np.abs(ts.tilt - ref.tilt).max() < 1e-4 * 0.2


def test_a_history_turned_about_a_loaded_diagonal_solves_each_step_once(monkeypatch):
    """The point forces on the diagonal have no moment about it: the macro step leaves the
    turn about it where it starts, and the micro step sets it from the contacts' widths.
    Each step must start near its answer (one solve from the last step's, no failed warm
    solve redone by the policy) and agree with the reference."""
    ends = (0.0, 0.01, 0.1, 1.0, 10.0, 100.0, 102.0, 104.0, 106.0, 108.0, 110.0)
    scene = askew_history(TimeSteps(at=ends), tips=DIAGONAL)
    solves = []  # (converged, micro sweeps) of every two-scale solve
    solve_twoscale = driver.solve_twoscale

    def counted(*args, **kwargs):
        result = solve_twoscale(*args, **kwargs)
        solves.append((result.converged, int(result.iterations["micro"])))
        return result

    monkeypatch.setattr(driver, "solve_twoscale", counted)
    ts = solve_history(scene, method="twoscale")
    monkeypatch.undo()
    ref = solve_history(scene, method="cg")
    assert ts.converged and ref.converged, (ts.message, ref.message)
    np.testing.assert_array_equal(ts.times, ref.times)
    # the face turns about the diagonal: the third low tip carries a small share
    assert np.all(ref.forces[:, 0] < 0.1 * ref.forces[:, 1]) and np.all(ref.forces[:, 0] > 0)
    scale = ref.forces.max()
    assert np.abs(ts.forces - ref.forces).max() < 2e-4 * scale
    assert np.abs(ts.penetration - ref.penetration).max() < 1e-4 * np.abs(ref.penetration).max()
    assert np.abs(ts.tilt - ref.tilt).max() < 1e-4 * np.abs(ref.tilt).max()
    # one solve a step, and at most the sweeps of the start from the last micro step's
    # approach and tilt (108 on these steps, the start before askew faces were solved),
    # with a quarter's slack: from the last macro tilt, 20 solves and 464 sweeps
    assert len(solves) == len(ts.steps), solves
    assert all(converged for converged, _ in solves)
    assert sum(sweeps for _, sweeps in solves) <= 135, solves
