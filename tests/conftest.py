"""Shared test fixtures: paths to the shipped examples, a scene-file writer and a one-sphere scene file."""

from __future__ import annotations

import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


@pytest.fixture
def examples_dir() -> pathlib.Path:
    """The repository's ``examples/`` folder (scene files)."""
    return EXAMPLES


@pytest.fixture
def write_scene(tmp_path):
    """``write_scene(text, name="scene.toml") -> path``: a scene file in a temporary folder."""

    def write(text: str, name: str = "scene.toml") -> pathlib.Path:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return path

    return write


#: One sphere (R = 10 mm) on a half-space (E = 10 MPa, nu = 0.5) under a 5 N load, h = 0.25 mm:
#: a scene that solves in well under a second.
ONE_SPHERE = """
[material]
E = 10.0
nu = 0.5
[load]
total = 5.0
[grid]
h = 0.25
[[asperity]]
x = 0.0
y = 0.0
R = 10.0
"""


@pytest.fixture
def scene(tmp_path) -> pathlib.Path:
    """A scene file of one sphere under load control (:data:`ONE_SPHERE`), in a temporary folder."""
    path = tmp_path / "scene.toml"
    path.write_text(ONE_SPHERE, encoding="utf-8")
    return path
