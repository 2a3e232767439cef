"""history.png's time axis: logarithmic when the output times span decades, unless a late
segment of the history (an unloading after a long hold) would be squeezed to a sliver."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale.plot.history import _log_axis

OUTPUTS = np.array([0.0, 1e-3, 1e-2, 0.1, 1.0, 10.0, 12.0])


@pytest.mark.parametrize(
    "kinks, log",
    [
        ((0.0, 12.0), True),  # one ramp or a step held: decades of creep
        ((0.0, 1e-3, 12.0), True),  # a fast ramp, then a long hold
        ((0.0, 0.5, 10.0, 12.0), False),  # ramp, hold, unload over 2 s at t = 10 s
        ((0.0, 1.0, 1.2, 12.0), False),  # a short segment after t = 1 s
    ],
)
def test_log_axis_unless_a_late_segment_is_squeezed(kinks, log):
    assert _log_axis(OUTPUTS, kinks) is log


def test_no_log_axis_over_less_than_two_decades():
    assert not _log_axis(np.array([0.0, 0.5, 10.0, 12.0]), (0.0, 12.0))
