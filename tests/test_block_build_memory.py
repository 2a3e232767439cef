"""What a block's first answers will build (fem_influence.build_memory): its factorisation
where the cache lacks a field the loads' region needs, nothing where it holds them."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("skfem")
pytest.importorskip("meshio")

from fem_influence import BlockProvider  # noqa: E402
from fem_influence.build_memory import FACTORISATION_BYTES  # noqa: E402
from twoscale import Material  # noqa: E402
from twoscale.influence import HalfSpace  # noqa: E402

MAT = Material(E=10.0, nu=0.45)


def test_a_cold_cache_builds_the_factorisation_and_a_warm_one_nothing(tmp_path):
    provider = BlockProvider(material=MAT, size=(60.0, 60.0, 10.0), cache_dir=tmp_path, progress=False)
    rect = (-3.0, 3.0, -2.0, 2.0)
    assert provider.build_bytes(rect) == FACTORISATION_BYTES  # an empty cache
    # the fields of every lattice node near the region known (mirrored: i, j >= 0 solved)
    state = provider._state
    top = np.zeros((3, 2))
    state.fields.add([(i, j) for i in range(4) for j in range(4)], np.zeros((16, 3)), top)
    state.refresh()
    assert provider.build_bytes(rect) == 0.0
    assert provider.build_bytes((10.0, 20.0, -2.0, 2.0)) == FACTORISATION_BYTES  # nodes past i = 3
    assert HalfSpace(MAT).build_bytes(rect) == 0.0  # the half-space builds nothing
