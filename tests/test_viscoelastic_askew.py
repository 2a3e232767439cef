"""A load history under a free tilt with the face set askew by 0.2 rad, the two-scale
method against the full-grid reference with the same steps.

Four spheres (R 5 mm) on a 20 mm square, one pair raised by 4 mm: the face turns by about
0.2 rad, where a sphere's nearest point to the turned face lies about ``R theta^2 / 2``
(0.1 mm) below its apex, so the micro step's approach is 0.1 mm below the macro step's
point tips' one, more than the tips' penetration. Each step starts from the last one's
answer; the history must carry on to the end and agree with the reference at every step.
"""

import warnings

import numpy as np

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


def askew_history(steps: TimeSteps) -> Scene:
    points = ((0.0, 20.0), (100.0, 20.0), (110.0, 2.0))
    history = LoadHistory("total", points, output=(0.0, 1.0, 100.0, 110.0), steps=steps)
    return Scene(Material(5.0, 0.5, prony=PRONY), TIPS, tilt=True, pivot=(0.0, 0.0), h=0.1, history=history)


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
