"""A rolling run's CPU time per position: the thread's CPU, not the wall clock (which on a
shared host counts the other jobs' turns), on the elastic and the viscoelastic paths, and
in ``rolling.json``."""

from __future__ import annotations

import time

import numpy as np
import pytest

from twoscale import Material
from twoscale.io.rolling_outputs import rolling_to_dict
from twoscale.rolling import RollingSpec, road_strip, roll
from twoscale.scene import Scene
from twoscale.surface import RawMap, build_surface

#: Wall-clock time each position is made to wait in the test below (s): no CPU spent.
NAP = 0.05


@pytest.fixture(scope="module")
def strip():
    return build_surface(RawMap(road_strip(50.0, 14.0, 0.25, seed=7), spacing=0.25, units="mm"))


def _scene(strip, material: Material) -> Scene:
    spec = RollingSpec(start=-3.0, end=-1.0, step=1.0, speed=50.0, tyre_radius=150.0, footprint=(36.0, 12.0))
    return Scene(material=material, surface=strip, total_load=20.0, rolling=spec)


def test_a_positions_cpu_time_leaves_out_the_time_it_waited(strip, monkeypatch):
    """Each position waits ``NAP`` s of wall-clock time inside its step (a sleep costs no
    CPU): its ``seconds`` count the wait, its ``cpu_seconds`` do not, and the positions' CPU
    adds up to no more than the thread's CPU over the whole run."""
    import twoscale.rolling.run as run

    drag_of = run.drag_of

    def napping(*args):
        time.sleep(NAP)
        return drag_of(*args)

    monkeypatch.setattr(run, "drag_of", napping)
    c0 = time.thread_time()
    result = roll(_scene(strip, Material(10.0, 0.5)))
    spent = time.thread_time() - c0
    assert result.all_converged and result.cpu_seconds.shape == result.shifts.shape
    assert np.all(result.seconds >= NAP)
    assert np.all(result.cpu_seconds >= 0.0)
    assert np.all(result.cpu_seconds <= result.seconds - 0.8 * NAP)
    assert 0.0 < result.cpu_seconds.sum() <= spent


def test_viscoelastic_positions_have_their_cpu_time(strip):
    """The viscoelastic stepping's positions: one CPU time each, adding up to no more than
    the thread's over the run."""
    c0 = time.thread_time()
    result = roll(_scene(strip, Material(10.0, 0.5, prony=((20.0, 1e-3),))))
    spent = time.thread_time() - c0
    assert result.cpu_seconds.shape == result.shifts.shape
    assert np.all(np.isfinite(result.cpu_seconds)) and np.all(result.cpu_seconds >= 0.0)
    assert 0.0 < result.cpu_seconds.sum() <= spent


def test_rolling_json_lists_each_positions_cpu_time(strip):
    scene = _scene(strip, Material(10.0, 0.5))
    result = roll(scene)
    listed = rolling_to_dict(result, scene)["positions"]
    assert [p["cpu_seconds"] for p in listed] == result.cpu_seconds.tolist()
    assert [p["seconds"] for p in listed] == result.seconds.tolist()


class Cycle:
    """An object that refers to itself: only the cyclic collector frees it."""

    def __init__(self):
        self.me = self


def test_the_objects_alive_before_a_run_are_out_of_the_collectors_passes_during_it():
    """The old objects frozen inside, given back at exit; garbage made inside still collected."""
    import gc
    import weakref

    from twoscale.collector import frozen_objects

    assert gc.get_freeze_count() == 0
    old = Cycle()
    with frozen_objects():
        assert gc.get_freeze_count() > 0
        assert not any(o is old for o in gc.get_objects())  # (the permanent generation is not listed)
        young = weakref.ref(Cycle())
        gc.collect()
        assert young() is None
    assert gc.get_freeze_count() == 0 and any(o is old for o in gc.get_objects())
    gc.freeze()  # a caller's own freeze is left as it is
    try:
        frozen = gc.get_freeze_count()
        with frozen_objects():
            assert gc.get_freeze_count() == frozen
        assert gc.get_freeze_count() == frozen
    finally:
        gc.unfreeze()


def test_a_run_runs_its_positions_frozen_and_thaws_after(strip):
    import gc

    seen = []
    result = roll(_scene(strip, Material(10.0, 0.5)), on_position=lambda pos: seen.append(gc.get_freeze_count()))
    assert result.all_converged and len(seen) == len(result.shifts)
    assert min(seen) > 0 and gc.get_freeze_count() == 0
