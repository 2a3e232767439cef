"""A static solve runs with the objects alive before it out of the collector's full passes,
and gives them back when it ends, also when it fails (twoscale.collector)."""

from __future__ import annotations

import gc

import pytest

import twoscale
from twoscale.material import Material


class Stop(Exception):
    """Raised by the test's method once it has looked at the collector."""


def test_a_solve_runs_frozen_and_thaws_after_also_on_failure():
    seen = []

    def method(provider, scene, h, **options):
        seen.append(gc.get_freeze_count())
        raise Stop

    assert gc.get_freeze_count() == 0
    with pytest.raises(Stop):
        twoscale.solve([[0.0, 0.0, 5.0]], method=method, material=Material(10.0, 0.5), penetration=0.01)
    assert seen and seen[0] > 0
    assert gc.get_freeze_count() == 0
