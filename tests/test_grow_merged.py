"""A two-level round that stopped and merged touching contacts grows the patches whose
pressure reaches an edge at once (:func:`twoscale.micro.block_iterations._grow_merged`),
as a round's end grows them, instead of sweeping again to stop on the same edges. Checks,
with the working set's tests stood in for: the growth is asked with the merged pressures
where an edge is loaded and growth is allowed, merged contacts after it are merged, and
nothing is grown otherwise."""

from types import SimpleNamespace

import numpy as np
import pytest

from twoscale.micro import block_iterations


class _Coupling:
    def __init__(self):
        self.refreshed = []

    def refresh(self, p):
        self.refreshed.append(p)


def _setup():
    state = SimpleNamespace(coupling=_Coupling())
    control = SimpleNamespace(pivot=(0.0, 0.0))
    return SimpleNamespace(state=state, p0=[np.ones(2)], control=control)


@pytest.mark.parametrize(
    "loaded, can_grow, grown", [(True, True, 3), (True, True, 0), (True, False, 3), (False, True, 3)]
)
def test_patches_grow_at_the_merge_only_where_an_edge_is_loaded(monkeypatch, loaded, can_grow, grown):
    setup, p, theta = _setup(), [np.array([0.0, 1.0])], np.zeros(3)
    calls = []
    monkeypatch.setattr(block_iterations, "edges_loaded_any", lambda state, q: calls.append("edges") or loaded)

    def grow(state, q, p0, th, pivot, tol):
        calls.append("grow")
        assert state is setup.state and q is p and p0 is setup.p0 and th is theta and tol == 1e-6
        assert setup.state.coupling.refreshed == [p]  # the far field of the merged blocks first
        return grown

    monkeypatch.setattr(block_iterations, "grow", grow)
    monkeypatch.setattr(block_iterations, "merge_touching", lambda state, q, p0: calls.append("merge") or 0)
    out = block_iterations._grow_merged(setup, p, theta, 1e-6, can_grow)
    if loaded and can_grow:
        assert out == grown
        assert calls == ["edges", "grow"] + (["merge"] if grown else [])
    else:
        assert out == 0 and "grow" not in calls and setup.state.coupling.refreshed == []
