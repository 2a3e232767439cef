"""The Python route of docs/viscoelastic.md ("From Python") runs as printed and answers as
the physics and the scene file do: under a held load the approach creeps from the glassy
elastic answer towards the relaxed one (elastic solves at E_inf + sum E_k and E_inf bound
it), and the same scene written as a file gives the same history. The height-map route of
docs/surfaces.md and the moving indenters of docs/viscoelastic.md run as printed too."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import twoscale
from twoscale.io import read_scene

ROOT = Path(__file__).resolve().parents[1]

SCENE_FILE = """
[material]
E = 5.0
nu = 0.5
prony = [[20.0, 0.1], [10.0, 10.0]]

[load]
total = [[0.0, 0.0], [1.0, 20.0], [30.0, 20.0]]

[[asperity]]
x = -3.0
y = 0.0
R = 5.0

[[asperity]]
x = 3.0
y = 0.0
R = 5.0
z = 0.01
"""


def _section_code(path: Path, title: str) -> str:
    text = path.read_text(encoding="utf-8")
    section = text.split(f"## {title}\n", 1)[1].split("\n## ", 1)[0]
    [code] = re.findall(r"```python\n(.*?)```", section, re.S)
    return code


def test_the_viscoelastic_guides_python_route(tmp_path, capsys):
    ns: dict = {}
    exec(_section_code(ROOT / "docs" / "viscoelastic.md", "From Python"), ns)
    res, scene_tips = ns["res"], ns["tips"]
    assert "HistoryResult" in capsys.readouterr().out
    assert res.converged and res.forces.shape == (len(res.times), 2)
    np.testing.assert_allclose(res.total_load, ns["history"].value(res.times), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(res.forces.sum(axis=1), res.total_load, rtol=1e-6, atol=1e-9)
    # the held load: the approach grows, between the glassy and the relaxed elastic answers
    held = res.times >= 1.0
    assert np.all(np.diff(res.penetration[held]) > 0)
    glassy, relaxed = (
        twoscale.solve(scene_tips, material=twoscale.Material(E, 0.5), total_load=20.0).penetration for E in (35.0, 5.0)
    )
    assert glassy < res.penetration[held][0] < res.penetration[-1] < relaxed
    # the same scene as a file: the same history
    path = tmp_path / "creep.toml"
    path.write_text(SCENE_FILE, encoding="utf-8")
    from_file = twoscale.solve(read_scene(path))
    np.testing.assert_allclose(from_file.times, res.times, rtol=0, atol=1e-12)
    np.testing.assert_allclose(from_file.penetration, res.penetration, rtol=1e-9)


def test_the_surfaces_guides_python_route_is_the_scene_files(monkeypatch):
    # docs/surfaces.md "From Python: the same scene" runs as printed (from the repository,
    # where its map is) and gives the answer of the example road's scene file
    monkeypatch.chdir(ROOT)
    ns: dict = {}
    exec(_section_code(ROOT / "docs" / "surfaces.md", "From Python: the same scene"), ns)
    res = ns["res"]
    from_file = twoscale.solve(read_scene(ROOT / "examples" / "road" / "road.toml"))
    assert res.converged and res.total_load == pytest.approx(500.0) and from_file.total_load == pytest.approx(500.0)
    np.testing.assert_allclose(res.penetration, from_file.penetration, rtol=1e-8)
    np.testing.assert_allclose(res.forces, from_file.forces, rtol=0, atol=1e-6 * from_file.forces.max())


def test_the_moving_indenter_route_runs_as_printed():
    # docs/viscoelastic.md "Moving indenters": at a held approach every position's load lies
    # between the relaxed and the glassy elastic answers, and the rubber's lag drags on the
    # tips (positive drag resists the motion)
    ns: dict = {}
    exec(_section_code(ROOT / "docs" / "viscoelastic.md", "Moving indenters: the core of rolling"), ns)
    r, tips = ns["r"], ns["tips"]
    relaxed, glassy = (
        twoscale.solve(tips, material=twoscale.Material(E, 0.5), penetration=0.2, h=0.05).total_load
        for E in (10.0, 30.0)
    )
    assert np.all(relaxed * (1 - 1e-3) < r.total_load) and np.all(r.total_load < glassy * (1 + 1e-3))
    assert r.drag[-1] > 0.01 * r.total_load[-1]
