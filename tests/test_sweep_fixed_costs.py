"""Fixed costs of the default solve on the sweep's smallest scenes (one or two tips, where
the full-grid reference takes 10-30 ms): counted in law evaluations and products, not
timed."""
import numpy as np
import pytest

from twoscale.laws import HertzLaw, LawStack, SphereLaw
from twoscale.macro.solve import _independent_approach


class _Counting(LawStack):
    calls = 0

    def force(self, delta):
        type(self).calls += 1
        return super().force(delta)


@pytest.mark.parametrize("law, z", [(SphereLaw(20.0, 20.0), [0.0]),
                                    (HertzLaw(3.0, 5.0), [0.0, 0.01, 0.3])])
def test_the_load_control_start_carries_the_load_in_few_law_evaluations(law, z):
    # the cold start of the macro step under load control: the approach at which the tips,
    # alone, carry W; bisection to the last bit asked the laws 66 times (40 % of a
    # one-sphere solve's CPU time)
    z = np.array(z)
    stack = _Counting([law] * len(z))
    _Counting.calls = 0
    W = 0.0019
    d = _independent_approach(z, stack, W)
    carried = float(np.sum(LawStack([law] * len(z)).force(d - z)))
    assert carried == pytest.approx(W, rel=1e-12)
    assert _Counting.calls <= 35
