"""Shared test fixtures: paths to the shipped examples and a scene-file writer."""
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
