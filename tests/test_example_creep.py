"""The shipped creep example (examples/creep/seven_spheres.toml) as a user runs it.

The command line writes the history files with the documented columns, and its answers
obey the correspondence principle, checked by an independent route (elastic solves of the
same scene). Under a load stepped on at t = 0 and held, contacts only grow; in the
relaxation form the load is then ``W = int E(t - s) dW_1(d(s))`` with ``W_1(d)`` the
unit-modulus elastic load at approach ``d``, so ``W_1(d(t)) = W J(t)``: the approach and
the contact area at time t are the elastic ones at the modulus 1/J(t), J the creep
compliance. The forces are not (each is ``int E(t - s) dF_1(d(s))``, and the tips' shares
change with the approach: 0.6 % apart at 10 s here), except at t = 0 (the glassy modulus
E_inf + sum E_k) and once every branch has relaxed (E_inf).
"""

from __future__ import annotations

import csv
import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import pytest

from twoscale import solve
from twoscale.io.scene_file import read_scene
from twoscale.material import Material
from twoscale.viscoelastic.prony import creep_compliance

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "creep" / "seven_spheres.toml"
HEADER = ["time_s", "penetration_mm", "total_load_N", "contact_area_mm2"] + [f"force_{k}" for k in range(1, 8)]


@pytest.fixture(scope="module")
def history_rows(tmp_path_factory) -> list[dict[str, float]]:
    out = tmp_path_factory.mktemp("creep") / "out"
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run(
        [sys.executable, "-m", "twoscale", "solve", str(EXAMPLE), "--out", str(out), "--quiet"],
        capture_output=True,
        text=True,
        env=env,
        cwd=str(ROOT),
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    for name in ("history.csv", "history.png", "fields.pvd", "result.json"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    with open(out / "history.csv", newline="") as f:
        reader = csv.reader(f)
        assert next(reader) == HEADER
        return [dict(zip(HEADER, map(float, row))) for row in reader]


def elastic_at(modulus: float):
    """The example's scene, elastic at ``modulus``, under its held load."""
    scene = read_scene(EXAMPLE)
    load = scene.history.peak
    elastic = dataclasses.replace(scene, material=Material(modulus, scene.material.nu), history=None, total_load=load)
    return solve(elastic)


def test_reported_times_are_the_listed_ones(history_rows):
    assert [r["time_s"] for r in history_rows] == [0.0, 0.001, 0.01, 0.1, 1.0, 10.0, 100.0, 1000.0]
    for r in history_rows:
        assert r["total_load_N"] == pytest.approx(70.0, rel=1e-9)
        assert sum(r[f"force_{k}"] for k in range(1, 8)) == pytest.approx(70.0, rel=1e-6)


@pytest.mark.parametrize("t", [0.0, 1.0, 10.0, 1000.0])
def test_approach_and_area_equal_elastic_solve_at_one_over_J(history_rows, t):
    material = read_scene(EXAMPLE).material
    modulus = 1.0 / creep_compliance(material)(t)
    row = next(r for r in history_rows if r["time_s"] == t)
    ref = elastic_at(modulus)
    # the time steps' error is held below 1e-2 of the largest value (the target: 1 %); the
    # two routes share the cells, so the areas differ only by the approach's error
    assert row["penetration_mm"] == pytest.approx(ref.penetration, rel=1e-2)
    assert row["contact_area_mm2"] == pytest.approx(ref.contact_area, rel=1e-2)


@pytest.mark.parametrize("t", [0.0, 1000.0])
def test_forces_glassy_at_the_step_and_relaxed_at_the_end(history_rows, t):
    material = read_scene(EXAMPLE).material
    modulus = material.E + sum(E for E, _ in material.prony) if t == 0 else material.E
    row = next(r for r in history_rows if r["time_s"] == t)
    ref = elastic_at(modulus)
    for k, f in enumerate(ref.forces, start=1):
        assert row[f"force_{k}"] == pytest.approx(f, rel=1e-2)
