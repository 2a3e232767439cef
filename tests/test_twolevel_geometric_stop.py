"""The two-level iteration's stop on a geometric contraction.

A round whose changes fall geometrically stops once the sum of the changes still to come,
bounded by ``c r / (1 - r)`` (:func:`~twoscale.micro.twolevel.remaining_change`), is within
the tolerance, not only once the last change is. Checks: the bound against the geometric
series it sums; the verdict's use of it (contact sets unchanged, the round's own changes);
and on small seeded scenes that stop a sweep sooner by it, the tip forces of the eq. 9 stop
within the tolerance and both the full-grid reference's within the far field's accuracy.
"""

import math

import numpy as np
import pytest

from twoscale.micro import twolevel
from twoscale.micro.twolevel import GEOMETRIC_RATE_MAX, SweepLimits, remaining_change, verdict
from twoscale.stopping import StopReason


@pytest.mark.parametrize("rate", [0.05, 0.2, 0.5])
def test_the_bound_is_the_geometric_series_of_the_changes_to_come(rate):
    changes = [0.3 * rate**j for j in range(4)]
    to_come = sum(changes[-1] * rate**j for j in range(1, 400))
    assert remaining_change(changes) == pytest.approx(to_come, rel=1e-12)
    assert remaining_change(changes) <= changes[-1]  # at r <= 1/2: never stricter than eq. 9


def test_the_bound_reads_the_slower_of_the_last_two_ratios_and_needs_both():
    assert remaining_change([1e-2, 1e-3, 4e-4]) == pytest.approx(4e-4 * 0.4 / 0.6)
    assert remaining_change([1e-2, 4e-3, 4e-4]) == pytest.approx(4e-4 * 0.4 / 0.6)
    assert remaining_change([1e-3, 1e-4]) == math.inf  # one ratio: no rate read
    assert remaining_change([1e-2, 1e-3, 0.9e-3]) == math.inf  # slower than GEOMETRIC_RATE_MAX
    assert GEOMETRIC_RATE_MAX <= 0.5


def test_the_verdict_stops_on_the_round_bound_with_contact_sets_unchanged():
    limits = SweepLimits(tol=1e-6, max_sweeps=50)
    p, theta = [np.ones(3)], np.zeros(3)
    # 1e-4, 1e-5, 1.5e-6: eq. 9 goes on; what is to come is 1.5e-6 * 0.15 / 0.85 <= 1e-6
    seen = [0.2, 1e-4, 1e-5, 1.5e-6]
    assert verdict(seen, False, limits, 3, p, theta)[1] is StopReason.CONVERGED
    assert verdict(seen, True, limits, 3, p, theta) is None  # a contact set changed
    # the round is its last two sweeps: the earlier round's change is not read as a rate
    assert verdict(seen, False, limits, 2, p, theta) is None


def _forces(scene, rate_max: float, monkeypatch):
    import twoscale

    with monkeypatch.context() as m:
        m.setattr(twolevel, "GEOMETRIC_RATE_MAX", rate_max)
        res = twoscale.solve(scene, iteration="two-level", far_tol=0.3)
    assert res.converged
    return np.asarray(res.asperities.forces, dtype=float), res.iterations["micro"]


@pytest.mark.parametrize("index", [9, 16])
def test_the_geometric_stop_keeps_the_forces_within_the_tolerance(index, monkeypatch):
    import twoscale
    from twoscale.scenespace import build, sweep

    # seed 0's #9 (4 paraboloids, penetration control) and #16 (5, load control): their
    # last rounds contract by 0.1-0.3 a sweep, so the bound stops them a sweep sooner
    (spec,) = [s for s in sweep(200, 0) if s.index == index]
    scene = build(spec)
    geometric, fewer = _forces(scene, GEOMETRIC_RATE_MAX, monkeypatch)
    eq9, more = _forces(scene, -1.0, monkeypatch)  # no rate is read: eq. 9 alone
    assert fewer < more
    # the iteration's tolerance (1e-6 on the pressure's relative change)
    assert np.max(np.abs(geometric - eq9)) <= 1e-6 * np.max(eq9)
    ref = np.asarray(twoscale.solve(scene, method="reference").asperities.forces, dtype=float)
    # both within the far field's accuracy of the full grid's CG at the same h
    assert np.max(np.abs(geometric - ref)) <= 1e-4 * np.max(ref)
    assert np.max(np.abs(eq9 - ref)) <= 1e-4 * np.max(ref)
