"""The gallery's scripts run as a user runs them after ``pip install .``: from the
repository's root, with ``twoscale`` imported from outside the repository (an installed
package does not ship ``examples/``), and from ``docs/examples/`` as the documentation build
runs them, and from a folder outside the repository (the script finds the examples from its
own place); a copy of the script outside the repository stops with one line saying so."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _installed(tmp_path) -> dict:
    site = tmp_path / "site"
    shutil.copytree(ROOT / "twoscale", site / "twoscale", ignore=shutil.ignore_patterns("__pycache__"))
    return {**os.environ, "PYTHONPATH": str(site), "MPLBACKEND": "Agg"}


@pytest.mark.parametrize("cwd", [".", "docs/examples", None])
def test_a_gallery_script_finds_the_examples_with_an_installed_twoscale(tmp_path, cwd):
    script = ROOT / "docs" / "examples" / "plot_seven_spheres.py"
    run = subprocess.run(
        [sys.executable, str(script)],
        cwd=tmp_path if cwd is None else ROOT / cwd,
        env=_installed(tmp_path),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert "<ContactResult twoscale: 7 tips" in run.stdout


@pytest.mark.parametrize("name", ["plot_seven_spheres.py", "plot_road_segmentation.py", "plot_full_pressure_map.py"])
def test_a_gallery_script_copied_out_of_the_repository_says_where_to_run_it(tmp_path, name):
    script = tmp_path / name
    shutil.copy(ROOT / "docs" / "examples" / name, script)
    run = subprocess.run(
        [sys.executable, str(script)],
        cwd=tmp_path,
        env=_installed(tmp_path),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 1 and "Traceback" not in run.stderr
    [line] = run.stderr.strip().splitlines()
    assert line.startswith("this example reads examples/") and "clone of the twoscale repository" in line
