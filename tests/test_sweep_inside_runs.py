"""The sweep's clock for short solves: a solve under ``INSIDE_BELOW`` s of CPU is run again
in its process until the runs add up to ``INSIDE_TOTAL`` s, and their mean is its time; a
longer one keeps its single reading."""

import time

import twoscale
from benchmarks import sweep


def _burn(seconds: float) -> None:
    c0 = time.process_time()
    while time.process_time() - c0 < seconds:
        pass


def test_a_short_solve_is_timed_by_the_mean_of_runs_adding_up_to_the_total(monkeypatch):
    calls = []
    monkeypatch.setattr(twoscale, "solve", lambda scene, **kw: (calls.append(kw), _burn(0.004)))
    wall, cpu, runs = sweep._timed_again(lambda: None, "reference", 0.1, None, 0.009, 0.009)
    assert runs == len(calls) + 1 >= 2
    assert calls[0] == {"method": "reference", "h": 0.1, "provider_options": None}
    total = cpu * runs
    assert total >= sweep.INSIDE_TOTAL or runs == sweep.INSIDE_MAX
    # the mean of the first reading (9 ms) and the repeats (4 ms and a little more each)
    assert 0.004 <= cpu <= (0.009 + 0.006 * (runs - 1)) / runs
    assert wall > 0


def test_a_solve_above_the_bound_keeps_its_single_reading(monkeypatch):
    monkeypatch.setattr(twoscale, "solve", lambda scene, **kw: (_ for _ in ()).throw(AssertionError("run again")))
    assert sweep._timed_again(lambda: None, "twoscale", None, None, 0.4, 0.25) == (0.4, 0.25, 1)
