"""The warnings a solve raises are listed in the files it writes (``warnings`` of
``result.json``, of a history's ``result.json``), each once with a count, while stderr shows
them as it always did: a tilt beyond small angles, a clean Hertz solve, a stone reaching a
height map's edge, a warning raised at every step of a history."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from twoscale.cli.main import main
from twoscale.errors import StepWarning, TiltWarning
from twoscale.io.warning_log import WarningLog

TILTED = """
[material]
E = 10.0
nu = 0.5
[load]
{load}
tilt = true
[grid]
h = {h}
{time}
"""


def _tilted_scene(path, *, load="total = 4.0", h=0.05, time=""):
    """Four equal spheres on a 20 mm square rising by 0.2 along x: the face balances them by
    turning beta = -0.2 rad (by symmetry), beyond the linear tilt's 0.1 rad."""
    tips = "".join(
        f"[[asperity]]\nx = {x}\ny = {y}\nz = {0.2 * x}\nR = 5.0\n" for x in (-10.0, 10.0) for y in (-10.0, 10.0)
    )
    path.write_text(TILTED.format(load=load, h=h, time=time) + tips, encoding="utf-8")
    return str(path)


def _stderr_warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("warning:")]


def test_a_tilt_beyond_small_angles_is_in_result_json(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["solve", _tilted_scene(tmp_path / "tilt.toml"), "--out", str(out), "--quiet"]) == 0
    record = json.loads((out / "result.json").read_text())
    beta = record["tilt"][1]
    assert abs(beta + 0.2) < 0.01  # the symmetric balance: the warning is due
    (entry,) = record["warnings"]
    assert entry["category"] == "TiltWarning" and entry["count"] == 1
    assert f"beta {beta:.3g}" in entry["message"] and "\n" not in entry["message"]
    # stderr as before: the one warning line, with the same text
    assert _stderr_warnings(capsys.readouterr().err) == [f"warning: {entry['message']}"]


def test_a_clean_hertz_solve_has_an_empty_list(examples_dir, tmp_path, capsys):
    out = tmp_path / "hertz"
    assert main(["solve", str(examples_dir / "hertz_sphere.toml"), "--out", str(out), "--quiet"]) == 0
    assert json.loads((out / "result.json").read_text())["warnings"] == []
    assert _stderr_warnings(capsys.readouterr().err) == []


def test_a_stone_at_the_maps_edge_is_in_result_json(tmp_path, capsys):
    """Two Gaussian stones, one centred on the map's lower edge: its contact reaches the
    edge (a SurfaceWarning naming it); a hole of missing samples away from both is filled
    and reported in ``height_map``, not warned about."""
    y, x = np.mgrid[0:121, 0:121] * 0.1  # 12 x 12 mm at 0.1 mm
    heights = sum(0.5 * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / 2.0) for cx, cy in ((6.0, 6.0), (6.0, 0.0)))
    heights[100:105, 10:15] = np.nan
    np.save(tmp_path / "m.npy", heights)
    scene = tmp_path / "s.toml"
    scene.write_text(
        '[material]\nE = 6.0\nnu = 0.5\n[load]\ntotal = 2.0\n[surface]\nfile = "m.npy"\n'
        'spacing = 0.1\nunits = "mm"\nlaw = "sphere"\n',
        encoding="utf-8",
    )
    out = tmp_path / "map"
    assert main(["solve", str(scene), "--out", str(out), "--quiet"]) == 0
    record = json.loads((out / "result.json").read_text())
    assert record["height_map"]["missing_samples"] == 25
    edge = record["height_map"]["edge_asperities"]
    assert len(edge) == 1
    (entry,) = record["warnings"]
    assert entry["category"] == "SurfaceWarning" and entry["count"] == 1
    assert f"asperity {edge[0]} reaches the edge" in entry["message"]
    assert _stderr_warnings(capsys.readouterr().err) == [f"warning: {entry['message']}"]


def test_a_warning_at_every_step_of_a_history_is_counted_once(tmp_path, capsys, monkeypatch):
    """A load history under the tilt of 0.2 rad warns of the tilt once (its largest); a
    warning raised at every step (put there by the test) is listed once with its count,
    and stderr shows it once, as Python's default filter always did."""
    from twoscale.viscoelastic import solve as history_solve

    steps = []
    step = history_solve._Run._solve

    def warning_step(self, t, dt):
        steps.append(t)
        warnings.warn("the same caveat at every step", StepWarning)
        return step(self, t, dt)

    monkeypatch.setattr(history_solve._Run, "_solve", warning_step)
    scene = _tilted_scene(
        tmp_path / "history.toml",
        load="total = [[0.0, 0.0], [1.0, 4.0]]",
        h=0.1,
        time="[time]\noutput = [0.5, 1.0]\nsteps = 2",
    )
    out = tmp_path / "history"
    assert main(["solve", scene, "--method", "reference", "--out", str(out), "--quiet"]) == 0
    record = json.loads((out / "result.json").read_text())
    assert len(steps) > 1
    assert [(e["category"], e["count"]) for e in record["warnings"]] == [
        ("StepWarning", len(steps)),
        ("TiltWarning", 1),
    ]
    assert record["warnings"][0]["message"] == "the same caveat at every step"
    shown = _stderr_warnings(capsys.readouterr().err)
    assert shown == [f"warning: {e['message']}" for e in record["warnings"]]


def test_the_log_leaves_the_filters_in_force():
    """What the filters in force say still holds inside the log: an "error" filter raises,
    an "ignore" filter hides (the log counts both), "default" shows a repeat once."""
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("default")
        warnings.filterwarnings("ignore", category=StepWarning)
        with WarningLog() as log:
            for _ in range(3):
                warnings.warn("tilt", TiltWarning)
            warnings.warn("step", StepWarning)
    assert [str(w.message) for w in shown] == ["tilt"]
    assert log.entries() == [
        {"category": "TiltWarning", "message": "tilt", "count": 3},
        {"category": "StepWarning", "message": "step", "count": 1},
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("error", TiltWarning)
        with pytest.raises(TiltWarning), WarningLog():
            warnings.warn("tilt", TiltWarning)
    # a warning from code of no loaded module (``python -c``, a notebook cell) still shows
    with warnings.catch_warnings(record=True) as shown:
        warnings.simplefilter("default")
        with WarningLog() as log:
            warnings.warn_explicit("cell", TiltWarning, "<string>", 3)
    assert [(str(w.message), w.filename) for w in shown] == [("cell", "<string>")]


STUDY = """
[study]
name = "warned"
[[scene]]
file = "tilt.toml"
name = "tilted"
[[scene]]
file = "one.toml"
name = "one"
[[body]]
name = "halfspace"
kind = "halfspace"
[load]
total = [4.0]
"""


def test_a_studys_case_json_lists_its_cases_warnings(tmp_path, capsys):
    """The tilted scene's case lists its TiltWarning (the angle its own result records), the
    one-sphere case none; stderr shows the warning once, as before."""
    _tilted_scene(tmp_path / "tilt.toml", load="total = 1.0", h=0.1)
    (tmp_path / "one.toml").write_text(
        "[material]\nE = 10.0\nnu = 0.5\n[load]\ntotal = 1.0\n[[asperity]]\nx = 0.0\ny = 0.0\nR = 5.0\n",
        encoding="utf-8",
    )
    (tmp_path / "study.toml").write_text(STUDY, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["study", str(tmp_path / "study.toml"), "--out", str(out), "--workers", "0", "--quiet"]) == 0
    cases = {c["label"].split()[0]: c for c in (json.loads(p.read_text()) for p in out.glob("cases/*/case.json"))}
    assert cases["one"]["warnings"] == []
    (entry,) = cases["tilted"]["warnings"]
    beta = cases["tilted"]["result"]["tilt"][1]
    assert entry["category"] == "TiltWarning" and entry["count"] == 1 and f"beta {beta:.3g}" in entry["message"]
    assert _stderr_warnings(capsys.readouterr().err) == [f"warning: {entry['message']}"]


def test_compares_runs_keep_their_own_warnings(tmp_path):
    """``twoscale compare`` solves every load on every body under one log: each run keeps the
    warnings of its own solve (for its ``runs/<body>_<load>/result.json``): the tilted load's
    TiltWarning, none for the single sphere solved after it."""
    import twoscale
    from twoscale.cli.compare import _solve_all
    from twoscale.io.scene_file import read_scene

    (tmp_path / "one.toml").write_text(
        "[material]\nE = 10.0\nnu = 0.5\n[load]\ntotal = 1.0\n[[asperity]]\nx = 0.0\ny = 0.0\nR = 5.0\n",
        encoding="utf-8",
    )
    scenes = [read_scene(_tilted_scene(tmp_path / "tilt.toml", h=0.1)), read_scene(tmp_path / "one.toml")]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # shown or not, the runs record them
        tilted, single = _solve_all(scenes, {"halfspace": twoscale.HalfSpace(scenes[0].material)}, "twoscale", True)
    (entry,) = tilted.warnings
    assert entry["category"] == "TiltWarning" and f"beta {tilted.result.tilt[1]:.3g}" in entry["message"]
    assert single.warnings == ()
