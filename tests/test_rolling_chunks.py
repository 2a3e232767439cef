"""A viscoelastic run split into chunks: each chunk starts earlier by a warm-up over which the
memory its different start leaves decays below the tolerance (the bound of
``twoscale.rolling.chunks``), and then gives the sequential run's signals; without the
warm-up it does not.

One Prony branch (E_1 = 40 MPa, tau = 2 ms on E = 10 MPa): one Kelvin-Voigt unit with
c / J(0) = 4 and retardation time lambda = 10 ms, 0.5 mm at 0.18 km/h (50 mm/s).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from twoscale import Material
from twoscale.rolling import RollingSpec, road_strip, roll
from twoscale.rolling.chunks import plan, roll_chunks, warmup_bound, warmup_positions
from twoscale.rolling.track import prepare
from twoscale.scene import Scene
from twoscale.surface import RawMap, build_surface

TREAD = Material(10.0, 0.5, prony=((40.0, 2e-3),))


@pytest.fixture(scope="module")
def scene():
    strip = build_surface(RawMap(road_strip(50.0, 14.0, 0.25, seed=7), spacing=0.25, units="mm"))
    spec = RollingSpec(start=-6.0, end=6.0, step=0.5, speed=0.18, tyre_radius=150.0, footprint=(24.0, 12.0))
    return Scene(material=TREAD, surface=strip, penetration=0.9, rolling=spec)


def test_warmup_bound_is_the_units_decay():
    """One unit: B = (c / J0) (1 - exp(-t_a / lambda)) exp(-T_w / lambda), lambda = 10 ms,
    c / J0 = 4; an elastic material needs no warm-up."""
    lam = 2e-3 * 50.0 / 10.0
    for t_a, T_w in ((0.01, 0.02), (1.0, 0.05), (0.0, 1.0)):
        expected = 4.0 * -math.expm1(-t_a / lam) * math.exp(-T_w / lam)
        assert warmup_bound(TREAD, t_a, T_w) == pytest.approx(expected, rel=1e-9)
    assert warmup_bound(Material(10.0, 0.5), 1.0, 0.0) == 0.0
    times = np.arange(40) * 0.01  # 10 ms a position: exp(-w) <= 1e-3 / 4 from w = 9 (t_a large)
    assert warmup_positions(TREAD, times, 30, 1e-3) == 9
    assert warmup_positions(TREAD, times, 3, 1e-3) == 3  # not enough before it: from the start


def test_viscoelastic_chunks_with_warmup_give_the_sequential_run(scene):
    """Measured, largest load difference over the largest load: 1.4e-5, 1.1e-6 and 3.0e-7 with
    warm-ups of 6, 9 and 11 positions (warmup_tol 1e-2, 1e-3, 1e-4: the bound is
    conservative); 0.53 without a warm-up."""
    whole = roll(scene)
    track = prepare(scene)
    parts = plan(track, 2, 1e-3)
    assert parts == [(0, 12, 0), (12, 25, 9)]  # 4.5 mm of warm-up before the second chunk
    split = roll_chunks(scene, chunks=2, scheduler="synchronous", warmup_tol=1e-3)
    assert split.all_converged and split.timings_s["warmup_positions"] == 9
    assert np.array_equal(split.shifts, whole.shifts) and np.allclose(split.times, whole.times)
    scale = float(np.max(whole.total_load))
    # the memory left from the chunk's start: below 1e-3 of the glassy strain
    assert np.max(np.abs(split.total_load - whole.total_load)) < 1e-3 * scale
    assert np.max(np.abs(split.drag - whole.drag)) < 1e-3 * scale
    assert np.allclose(split.stored, whole.stored, rtol=2e-3)
    assert np.allclose(split.dissipated[1:], whole.dissipated[1:], rtol=5e-3, atol=1e-6)
    assert np.array_equal(split.asperities.position, whole.asperities.position)
    # without the warm-up the second chunk starts at rest: its first positions are far off
    cold = roll_chunks(scene, chunks=2, scheduler="synchronous", warmup_tol=10.0)
    assert cold.timings_s["warmup_positions"] == 0
    assert np.max(np.abs(cold.total_load - whole.total_load)) > 2e-2 * scale


def test_elastic_chunks_need_no_warmup(scene):
    track = prepare(dataclasses.replace(scene, material=Material(10.0, 0.5)))
    assert [w for _, _, w in plan(track, 3)] == [0, 0, 0]


def test_spawned_workers_get_one_blas_thread_each(monkeypatch):
    """Dask's spawned worker processes read their BLAS/OpenMP threads from the environment:
    one each while a run on ``scheduler="processes"`` lasts, a caller's own setting kept, the
    environment as it was afterwards; other schedulers leave it alone."""
    import os

    from twoscale.rolling.chunks import THREAD_VARIABLES, _one_thread_each

    for k in THREAD_VARIABLES:
        monkeypatch.delenv(k, raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")
    with _one_thread_each("processes"):
        assert [os.environ.get(k) for k in THREAD_VARIABLES] == ["1", "1", "3"]
    assert [os.environ.get(k) for k in THREAD_VARIABLES] == [None, None, "3"]
    with _one_thread_each("threads"):
        assert os.environ.get("OMP_NUM_THREADS") is None
