"""What a body's on-disk cache did while the body was built is recorded by its first solve.

A finite block reads its correction fields (or drops a damaged entry) when it is built,
before any solve. ``twoscale solve``, ``twoscale compare`` and a
:class:`twoscale.ContactSolver` build the body first and then solve on it, and their results
used to say ``read: 0, dropped: []``
for a block whose fields came from the cache, or whose damaged entry was dropped and
solved again. A body standing in for the block reports a read and a dropped entry at
construction, and nothing during the solves: the first solve on it must carry both, the
later ones neither.
"""

from __future__ import annotations

import dataclasses

import twoscale
from twoscale.cli import compare as compare_cli
from twoscale.influence.halfspace import HalfSpace
from twoscale.io.cache_entry import CacheUsage, with_construction

BUILT = (CacheUsage("block-corrections", "/cache", read=1, dropped=("block-x.npz",)),)


@dataclasses.dataclass(frozen=True)
class _BodyReadAtConstruction(HalfSpace):
    """The half-space answering as a block whose cache was read when it was built."""

    def cache_usage(self) -> tuple:
        return BUILT


def _scene(load: float) -> twoscale.Scene:
    tips = twoscale.asperities([0.0, 8.0], [0.0, 0.0], 5.0)
    return twoscale.Scene(twoscale.Material(10.0, 0.5), tips, total_load=load)


def test_with_construction_adds_counts_and_appends_caches_the_solve_did_not_touch():
    saves = ("b.npz", "c.npz", "b.npz")  # b stored again: two files written
    solve_usage = (CacheUsage("block-corrections", "/cache", read=2, saves=saves, dropped=("b.npz",)),)
    [merged] = with_construction(solve_usage, BUILT)
    assert (merged.read, merged.written, merged.dropped) == (3, 2, ("block-x.npz", "b.npz"))
    built = (dataclasses.replace(BUILT[0], saves=("b.npz",)),)
    assert with_construction(solve_usage, built)[0].written == 2  # b, written at construction and after
    assert with_construction((), BUILT) == BUILT
    assert with_construction(solve_usage, ()) == solve_usage


def test_compare_records_the_construction_in_the_first_solve_on_each_body():
    scenes = [_scene(20.0), _scene(30.0)]
    body = _BodyReadAtConstruction(scenes[0].material)
    runs = compare_cli._solve_all(scenes, {"halfspace": body}, "twoscale", quiet=True)
    first, second = (r.result.caches for r in runs)
    assert [u.as_dict() for u in first] == [u.as_dict() for u in BUILT]
    assert [(u.read, u.written, u.dropped) for u in second] == [(0, 0, ())]


def test_contact_solver_records_the_construction_of_the_body_it_builds(monkeypatch):
    monkeypatch.setattr(twoscale.Scene, "provider", lambda self, **_: _BodyReadAtConstruction(self.material))
    solver = twoscale.ContactSolver()
    first = solver.solve(_scene(20.0))
    again = solver.solve(_scene(25.0))
    assert [u.as_dict() for u in first.caches] == [u.as_dict() for u in BUILT]
    assert [(u.read, u.dropped) for u in again.caches] == [(0, ())]


def test_a_body_given_to_the_solver_keeps_its_construction_to_its_builder():
    body = _BodyReadAtConstruction(twoscale.Material(10.0, 0.5))
    res = twoscale.ContactSolver(body).solve(_scene(20.0))
    assert [(u.read, u.dropped) for u in res.caches] == [(0, ())]


def _history_scene() -> twoscale.Scene:
    from twoscale.viscoelastic.history import LoadHistory

    tips = twoscale.asperities([0.0, 8.0], [0.0, 0.0], 5.0)
    material = twoscale.Material(10.0, 0.5, prony=((0.5, 0.1),))
    history = LoadHistory("total", ((0.0, 20.0), (0.2, 20.0)), output=(0.0, 0.2))
    return twoscale.Scene(material, tips, h=0.1, history=history)


def test_a_load_history_records_its_body_build_and_writes_it_to_result_json(monkeypatch):
    """A history scene's body is built inside its solve: ``twoscale.solve`` and a
    ContactSolver carry what its cache did then, and ``result.json`` lists it."""
    from twoscale.io.history_outputs import history_to_dict

    monkeypatch.setattr(twoscale.Scene, "provider", lambda self, **_: _BodyReadAtConstruction(self.material))
    scene = _history_scene()
    once = twoscale.solve(scene)
    assert [u.as_dict() for u in once.caches] == [u.as_dict() for u in BUILT]
    assert history_to_dict(once, scene)["caches"] == [u.as_dict() for u in BUILT]
    solver = twoscale.ContactSolver()
    first, again = solver.solve(scene), solver.solve(scene)
    assert [u.as_dict() for u in first.caches] == [u.as_dict() for u in BUILT]
    assert [(u.read, u.dropped) for u in again.caches] == [(0, ())]
