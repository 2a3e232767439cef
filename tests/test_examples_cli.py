"""The command line as a subprocess on every shipped scene in examples/.

Default run: each scene at a coarser cell size (``--h``, about 1/3 of the scene's
resolution, a few seconds in all) as a smoke test of the installed entry point
``python -m twoscale``; ``-m slow``: each scene at its own cell size (~20 s in all).
Checks exit code 0, the four output files, and that result.json describes the scene
that was run (asperity count, cell size, a total load equal to the scene's under load
control).
"""

from __future__ import annotations

import json
from twoscale.io.scene_file import tomllib
import os
import subprocess
import sys
from pathlib import Path

import pytest

from twoscale.io.scene_file import read_scene

ROOT = Path(__file__).resolve().parent.parent
# example scenes; study files (with a [study] table) are run by the studies' tests
EXAMPLES = sorted(p for p in (ROOT / "examples").glob("*.toml") if "study" not in tomllib.loads(p.read_text()))
OUTPUTS = ("result.json", "fields.vtm", "pressure.png", "forces.png")


def coarse_h(scene) -> float:
    """Three times the scene's cell size, capped so the smallest sphere keeps ~8 cells per radius."""
    h = scene.h if scene.h is not None else 0.13  # the default rule's choice for hertz_sphere
    r_min = min(a.R for a in scene.asperities)
    return min(3.0 * h, r_min / 16.0)


def run_cli(scene_path: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run(
        [sys.executable, "-m", "twoscale", "solve", str(scene_path), "--out", str(out), "--quiet", *extra],
        capture_output=True,
        text=True,
        env=env,
        cwd=str(ROOT),
        timeout=600,
    )


def check_outputs(proc, scene, out: Path, h: float, h_source: str = "scene") -> None:
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == ""  # --quiet
    for name in OUTPUTS:
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    res = json.loads((out / "result.json").read_text())
    assert res["converged"] is True
    assert len(res["asperities"]) == len(scene.asperities)
    if h is not None:  # None: the default rule chose it
        assert res["h"] == pytest.approx(h)
    assert res["h_source"] == (h_source if h is not None else "default")
    if scene.total_load is not None:
        assert res["total_load"] == pytest.approx(scene.total_load, rel=1e-3)
    assert sum(a["force"] for a in res["asperities"]) == pytest.approx(res["total_load"], rel=1e-6)


def test_every_scene_is_tested():
    assert {p.name for p in EXAMPLES} >= {
        "paper_two_spheres.toml",
        "paper_seven_spheres.toml",
        "S1.toml",
        "S2.toml",
        "S3.toml",
    }


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_example_cli_coarse(path, tmp_path):
    scene = read_scene(path)
    h = coarse_h(scene)
    out = tmp_path / "out"
    check_outputs(run_cli(path, out, "--h", repr(h)), scene, out, h, h_source="--h")


@pytest.mark.slow
@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_example_cli_full(path, tmp_path):
    scene = read_scene(path)
    out = tmp_path / "out"
    check_outputs(run_cli(path, out), scene, out, scene.h)
