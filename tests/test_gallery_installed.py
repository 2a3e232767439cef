"""The gallery's scripts run as a user runs them after ``pip install .``: from the
repository's root, with ``twoscale`` imported from outside the repository (an installed
package does not ship ``examples/``), and from ``docs/examples/`` as the documentation build
runs them."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("cwd", [".", "docs/examples"])
def test_a_gallery_script_finds_the_examples_with_an_installed_twoscale(tmp_path, cwd):
    site = tmp_path / "site"
    shutil.copytree(ROOT / "twoscale", site / "twoscale", ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "PYTHONPATH": str(site), "MPLBACKEND": "Agg"}
    script = ROOT / "docs" / "examples" / "plot_seven_spheres.py"
    run = subprocess.run(
        [sys.executable, str(script)], cwd=ROOT / cwd, env=env, capture_output=True, text=True, timeout=300
    )
    assert run.returncode == 0, run.stderr[-2000:]
    assert "<ContactResult twoscale: 7 tips" in run.stdout
