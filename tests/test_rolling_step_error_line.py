"""The ``--step-error`` summary line offers the extrapolated friction only where the two runs
are close enough for a first-order correction.

Seen: a viscoelastic roll of the example strip at 2 mm steps (8 times the 0.25 mm limit)
gave a friction of 3.412 N and -1.286 N at twice the step, and the line offered "about
+4.7 N to add (extrapolated 8.111 N)": a correction larger than the friction, from runs of
opposite sign. The records' runs at 0.5 and 0.25 mm (1.65 and 2.17 N, within the first-order
range) keep the plain line.
"""

from __future__ import annotations

from twoscale.cli.rolling import step_error_line
from twoscale.rolling.stepcheck import StepCheck


def _error(fine: float, coarse: float) -> dict:
    err = fine - coarse  # first order: the fine run's error is the difference of the two
    return {
        "friction_N": fine,
        "friction_at_twice_the_step_N": coarse,
        "estimated_error_N": err,
        "extrapolated_friction_N": fine + err,
    }


def test_runs_of_opposite_sign_are_not_extrapolated():
    check = StepCheck(step=2.0, spacing=0.25, branch_length=1.39, branch_tau=1e-4)
    line = step_error_line(_error(3.412, -1.286), check)
    assert "the extrapolation is not an answer" in line and "step <= 0.25 mm" in line


def test_a_correction_larger_than_half_the_friction_is_not_offered():
    assert "not an answer" in step_error_line(_error(2.0, 0.9))


def test_close_runs_keep_the_extrapolation():
    line = step_error_line(_error(2.17, 1.65))
    assert "not an answer" not in line and "extrapolated 2.69 N" in line


def test_rolling_json_says_whether_the_correction_holds():
    """``step_error`` (what ``rolling.json`` keeps) carries the same verdict as the line."""
    from types import SimpleNamespace

    import numpy as np

    from twoscale.rolling.stepcheck import step_error

    def run(drag, step):
        shifts = np.arange(len(drag)) * step
        return SimpleNamespace(shifts=shifts, drag=np.asarray(drag, dtype=float))

    far = step_error(run([3.412] * 9, 0.5), run([-1.286] * 5, 1.0))
    close = step_error(run([2.17] * 9, 0.5), run([1.65] * 5, 1.0))
    assert far["first_order"] is False and close["first_order"] is True
    assert "not an answer" in step_error_line(far) and "not an answer" not in step_error_line(close)
