"""The shipped rolling example: its strip is what make_strip.py makes, its scene passes
every check, and (slow) it runs to the end with the load held."""

from __future__ import annotations

import csv
import importlib.util
import pathlib

import numpy as np
import pytest

from twoscale.cli.main import main
from twoscale.io.scene_file import read_scene
from twoscale.rolling.track import prepare

FOLDER = pathlib.Path(__file__).resolve().parents[1] / "examples" / "rolling"


def test_strip_is_what_make_strip_makes(tmp_path):
    spec = importlib.util.spec_from_file_location("make_strip", FOLDER / "make_strip.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    made = np.load(module.make(tmp_path / "strip.npz"))
    shipped = np.load(FOLDER / "strip.npz")
    assert np.array_equal(made["heights"], shipped["heights"])
    assert float(shipped["spacing"]) == module.SPACING


def test_example_scene_is_ready_to_roll():
    scene = read_scene(FOLDER / "tyre.toml")
    track = prepare(scene)
    assert len(track.shifts) == 31 and track.h == 0.25
    assert track.control == "load"


@pytest.mark.slow
def test_example_runs(tmp_path):
    out = tmp_path / "roll"
    assert main(["solve", str(FOLDER / "tyre.toml"), "--out", str(out), "--quiet"]) == 0
    with open(out / "signals.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 31
    assert all(abs(float(r["total_load_N"]) - 300.0) < 1e-3 for r in rows)
