"""`twoscale compare`: outputs, indicators, bodies, and bad input (exit 2, nothing written)."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from twoscale.cli import compare
from twoscale.cli.main import main

from helpers import THREE_SPHERES_TILT, half_space_as_block

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
TWO = str(EXAMPLES / "paper_two_spheres.toml")


def _csv_rows(path):
    """Rows of forces.csv (header on the first line); its metadata JSON records version, units and scene."""
    meta = json.loads(path.with_name(path.name + "-metadata.json").read_text())["twoscale"]
    assert meta["units"]["force"] == "N" and meta["source"].startswith("compare ")
    assert meta["scene"]["material"]["nu"] == 0.5
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def test_half_space_only_says_so(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(compare, "_block_factory", lambda: (None, "no block in this test"))
    out = tmp_path / "cmp"
    assert main(["compare", TWO, "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "half-space only" in err and "no block in this test" in err
    assert "half-space only" in (out / "forces.md").read_text()
    rows = list(_csv_rows(out / "forces.csv"))
    assert [(r["body"], r["asperity"]) for r in rows] == [("halfspace", "1"), ("halfspace", "2")]
    res = json.loads((out / "runs" / "halfspace_d0.5mm" / "result.json").read_text())
    assert [float(r["force_N"]) for r in rows] == pytest.approx([a["force"] for a in res["asperities"]], rel=1e-9)
    # symmetric scene: equal forces
    assert float(rows[0]["force_N"]) == pytest.approx(float(rows[1]["force_N"]), rel=1e-5)
    for name in ("forces_d0.5mm.png", "maps_d0.5mm.png", "sensor_d0.5mm.png", "summary.json"):
        assert (out / name).stat().st_size > 0
    assert not (out / "difference_d0.5mm.png").exists()  # one body: nothing to subtract
    summary = json.loads((out / "summary.json").read_text())
    assert summary["notes"] and summary["units"]["force"] == "N"


def test_three_bodies_and_loads(tmp_path, monkeypatch):
    monkeypatch.setattr(compare, "_block_factory", lambda: (half_space_as_block, ""))
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT)
    out = tmp_path / "cmp"
    code = main(["compare", str(scene), "--loads", "50", "100", "--out", str(out), "--quiet", "--vtk"])
    assert code == 0
    rows = list(_csv_rows(out / "forces.csv"))
    assert len(rows) == 2 * 3 * 3
    by = {}
    for r in rows:
        by.setdefault((r["load_N"], r["body"]), []).append(float(r["force_N"]))
    for load, total in (("50", 50.0), ("100", 100.0)):
        assert sum(by[load, "halfspace"]) == pytest.approx(total, rel=1e-6)
        # the stand-in block is the half-space: identical forces, zero indicators
        assert by[load, "block-bonded"] == by[load, "halfspace"] == by[load, "block-sliding"]
    ind = json.loads((out / "summary.json").read_text())["indicators_percent"]
    assert ind["50N"]["halfspace"]["block-bonded"] == {"e_M": 0.0, "e_m": 0.0}
    md = (out / "forces.md").read_text()
    assert "| halfspace | - | 0 / 0 | 0 / 0 |" in md
    assert (out / "runs" / "block-sliding_100N" / "fields.vtm").exists()


class _Res:
    def __init__(self, forces, fields):
        from twoscale.results import AsperitySummary

        f = np.asarray(forces, float)
        self.asperities = AsperitySummary(f, f, f)
        self.fields = fields


def test_indicators_closed_form():
    from twoscale import comparison
    from twoscale.grid import Grid
    from twoscale.results import PressureField
    from twoscale.sensor import Sensor

    g = Grid(0.05, 0.05, 0.1, 10, 10)
    f = PressureField(g, np.ones(g.shape), np.zeros(g.shape), np.zeros(g.shape))
    f2 = PressureField(g, 1.1 * np.ones(g.shape), np.zeros(g.shape), np.zeros(g.shape))
    runs = [
        comparison.Run("50N", "halfspace", None, _Res([1.0, 2.0], (f,)), 0.0),
        comparison.Run("50N", "block-bonded", None, _Res([1.1, 2.2], (f2,)), 0.0),
    ]
    ind = comparison.indicators(runs, Sensor())
    # 10 % everywhere: e_M = e_m = 100 * 0.1^2 = 1 %, relative to the row's body
    assert ind["50N"]["halfspace"]["block-bonded"]["e_M"] == pytest.approx(1.0, rel=1e-12)
    assert ind["50N"]["halfspace"]["block-bonded"]["e_m"] == pytest.approx(1.0, rel=1e-12)
    # the other way round the denominator is the larger map: 100 * (0.1/1.1)^2
    assert ind["50N"]["block-bonded"]["halfspace"]["e_M"] == pytest.approx(100 / 121, rel=1e-12)


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--loads", "50"], "--loads needs a scene under load control"),
        (["--h", "-1"], "--h must be"),
    ],
)
def test_bad_input_exit_2_nothing_written(tmp_path, capsys, extra, match):
    out = tmp_path / "cmp"
    assert main(["compare", TWO, "--out", str(out), "--quiet"] + extra) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("error:") and match in err[-1]
    assert not out.exists()


@pytest.mark.parametrize("loads, match", [(["0"], "> 0"), (["nan"], "> 0"), (["50", "50"], "repeated")])
def test_bad_loads(tmp_path, capsys, loads, match):
    out = tmp_path / "cmp"
    assert main(["compare", str(EXAMPLES / "S1.toml"), "--loads", *loads, "--out", str(out), "--quiet"]) == 2
    assert match in capsys.readouterr().err
    assert not out.exists()


_TIMED = {
    "load history": "[material]\nE = 3.0\nnu = 0.5\nprony = [[10.0, 0.1]]\n\n[load]\ntotal = [[0.0, 0.0], [1.0, 20.0]]\n",
    "[rolling] table": "[material]\nE = 3.0\nnu = 0.5\n\n[load]\ntotal = 20.0\n\n"
    "[rolling]\nstart = -2.0\nend = 2.0\nstep = 1.0\nspeed = 10.0\nfootprint = [20.0, 20.0]\n",
}


@pytest.mark.parametrize("what", sorted(_TIMED))
def test_a_history_or_a_rolling_scene_is_refused_in_one_line(tmp_path, capsys, what):
    # a history's result reached the per-load table and stopped with a TypeError traceback
    scene = tmp_path / "timed.toml"
    scene.write_text(_TIMED[what] + "\n[[asperity]]\nx = 0.0\ny = 0.0\nR = 5.0\n")
    out = tmp_path / "cmp"
    assert main(["compare", str(scene), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and what in err[0] and "twoscale solve" in err[0]
    assert not out.exists()


def test_missing_scene(tmp_path, capsys):
    assert main(["compare", str(tmp_path / "none.toml"), "--out", str(tmp_path / "o")]) == 2
    assert "not found" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_measured_data_and_pivot_centring(tmp_path, monkeypatch):
    from twoscale.io.vtk import read_vtk
    from twoscale.sensor import Sensor

    monkeypatch.setattr(compare, "_block_factory", lambda: (None, "no block in this test"))
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT)
    forces = tmp_path / "forces.csv"
    forces.write_text("index,force\n0,2\n1,3\n2,5\n")
    smap = np.zeros((44, 44))
    smap[21:23, 21:23] = 1.0
    mpath = tmp_path / "map.csv"
    mpath.write_text("\n".join(",".join(f"{v:g}" for v in row) for row in smap) + "\n")
    out = tmp_path / "cmp"
    code = main(
        [
            "compare",
            str(scene),
            "--loads",
            "10",
            "--measured-forces",
            str(forces),
            "--measured-map",
            str(mpath),
            "--centre-pivot",
            "--vtk",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert code == 0
    # eq. 13 with the applied load 10 N: x0 = 8 * 3 / 10 = 2.4, y0 = 8 * 5 / 10 = 4.0
    res = json.loads((out / "runs" / "halfspace_10N" / "result.json").read_text())
    tips = [(a["x"], a["y"]) for a in res["scene"]["asperity"]]
    # flat list: pytest >= 9.1 (what a fresh `pip install .[test]` gets) rejects nested approx
    assert [c for t in tips for c in t] == pytest.approx([-2.4, -4.0, 5.6, -4.0, -2.4, 4.0])
    assert "eq. 13" in (out / "forces.md").read_text()
    # indicators against the measurement, recomputed here from the written forces and fields
    rows = [r for r in _csv_rows(out / "forces.csv")]
    m = np.array([float(r["force_N"]) for r in rows if r["body"] == "measured"])
    F = np.array([float(r["force_N"]) for r in rows if r["body"] == "halfspace"])
    assert m.tolist() == [2.0, 3.0, 5.0]
    fields = read_vtk(out / "runs" / "halfspace_10N" / "fields.vtm").fields
    P = sum(Sensor().average_field(f.grid, f.pressure) for f in fields)
    loaded = (P != 0) | (smap != 0)
    e_m_expected = 100 * np.sum((P - smap)[loaded] ** 2) / np.sum(smap**2)
    ind = json.loads((out / "summary.json").read_text())["indicators_percent"]["10N"]["measured"]["halfspace"]
    assert ind["e_M"] == pytest.approx(100 * np.sum((F - m) ** 2) / np.sum(m**2), rel=1e-8)
    assert ind["e_m"] == pytest.approx(e_m_expected, rel=1e-8)


@pytest.mark.parametrize(
    "extra, match",
    [
        (["--centre-pivot"], "needs measured data"),
        (["--loads", "10", "20", "--measured-forces", "F"], "one load case"),
    ],
)
def test_measured_option_errors(tmp_path, capsys, extra, match):
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT)
    out = tmp_path / "cmp"
    assert main(["compare", str(scene), "--out", str(out), "--quiet"] + extra) == 2
    assert match in capsys.readouterr().err
    assert not out.exists()


def test_measured_forces_wrong_count(tmp_path, capsys):
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT)
    f = tmp_path / "f.csv"
    f.write_text("index,force\n0,1\n1,1\n")
    assert main(["compare", str(scene), "--measured-forces", str(f), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "2 forces for a scene of 3 asperities" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_real_finite_block_is_stiffer(tmp_path):
    # the finite block (20 mm thick on a rigid base) is stiffer than the half-space, and a
    # bonded base stiffer than a sliding one (docs/method.md section 6), so at one rigid
    # approach the loads are ordered: half-space < sliding < bonded
    pytest.importorskip("skfem")
    if compare._block_factory()[0] is None:
        pytest.skip("finite-block provider not available")
    out = tmp_path / "cmp"
    assert main(["compare", TWO, "--out", str(out), "--quiet"]) == 0
    runs = {r["body"]: r["total_load"] for r in json.loads((out / "summary.json").read_text())["runs"]}
    assert runs["halfspace"] < runs["block-sliding"] < runs["block-bonded"]


def test_measured_map_only_gives_forces_from_the_map(tmp_path, monkeypatch):
    monkeypatch.setattr(compare, "_block_factory", lambda: (None, "no block in this test"))
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT)
    smap = np.zeros((44, 44))
    smap[22, 22] = 1.0  # cell centred at (0.95, 0.95) mm: nearest tip is (0, 0)
    smap[22, 26] = 2.0  # (8.55, 0.95): nearest tip (8, 0)
    mpath = tmp_path / "map.csv"
    mpath.write_text("\n".join(",".join(f"{v:g}" for v in row) for row in smap) + "\n")
    out = tmp_path / "cmp"
    assert main(["compare", str(scene), "--measured-map", str(mpath), "--out", str(out), "--quiet"]) == 0
    rows = [r for r in _csv_rows(out / "forces.csv") if r["body"] == "measured"]
    assert [float(r["force_N"]) for r in rows] == pytest.approx([1.9**2, 2 * 1.9**2, 0.0])
    assert "integrated from the sensor map" in (out / "forces.md").read_text()


@pytest.mark.slow
def test_subprocess_compare_on_shipped_scene(tmp_path):
    # the installed entry point as a user runs it (builds the finite block when available)
    import subprocess
    import sys

    out = tmp_path / "cmp"
    proc = subprocess.run(
        [sys.executable, "-m", "twoscale", "compare", TWO, "--out", str(out), "--quiet"],
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == ""
    rows = _csv_rows(out / "forces.csv")
    bodies = {r["body"] for r in rows}
    assert bodies in ({"halfspace"}, {"halfspace", "block-bonded", "block-sliding"})
    if bodies == {"halfspace"}:
        assert "half-space only" in proc.stderr


# ---------------------------------------------------------------- load cases of the scene
def test_scene_load_cases_run_without_loads_and_loads_override(tmp_path, monkeypatch):
    monkeypatch.setattr(compare, "_block_factory", lambda: (None, "no block in this test"))
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT.replace("total = 10.0", "total = 10.0\ncases = [10.0, 20.0]"))
    out = tmp_path / "cases"
    assert main(["compare", str(scene), "--out", str(out), "--quiet"]) == 0
    runs = json.loads((out / "summary.json").read_text())["runs"]
    assert [(r["load"], r["total_load"]) for r in runs] == [("10N", pytest.approx(10.0)), ("20N", pytest.approx(20.0))]
    assert {float(r["load_N"]) for r in _csv_rows(out / "forces.csv")} == {10.0, 20.0}  # numbers, not "10N"
    # --loads replaces the scene's cases, and the files record the cases actually run
    out2 = tmp_path / "override"
    assert main(["compare", str(scene), "--loads", "15", "--out", str(out2), "--quiet"]) == 0
    summary = json.loads((out2 / "summary.json").read_text())
    assert [r["load"] for r in summary["runs"]] == ["15N"]
    assert summary["scene"]["load"]["cases"] == [15.0] and summary["scene"]["load"]["total"] == 15.0


@pytest.mark.parametrize(
    "name, cases",
    [("S1.toml", [50.0, 100.0, 150.0]), ("S2.toml", [200.0, 250.0, 300.0]), ("S3.toml", [200.0, 250.0, 300.0])],
)
def test_shipped_scenes_compare_every_load_case(name, cases):
    # what `twoscale compare examples/S2.toml` (no --loads) would solve, without solving
    args = compare_args([str(EXAMPLES / name)])
    assert [s.total_load for s in compare._scenes(args)] == cases
    assert [s.total_load for s in compare._scenes(compare_args([str(EXAMPLES / name), "--loads", "70"]))] == [70.0]


def compare_args(argv):
    from twoscale.cli.main import build_parser

    return build_parser().parse_args(["compare", *argv])


@pytest.mark.parametrize(
    "cases, field, value",
    [
        ("[10.0, 0.0]", "load.cases[1]", "0.0"),
        ("[10.0, inf]", "load.cases[1]", "inf"),
        ("[10.0, 10.0]", "load.cases", "[10.0, 10.0]"),
        ("[]", "load.cases", "[]"),
        ('"10, 20"', "load.cases", "'10, 20'"),
    ],
)
def test_bad_scene_load_cases_exit_2(tmp_path, capsys, cases, field, value):
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT.replace("total = 10.0", f"total = 10.0\ncases = {cases}"))
    out = tmp_path / "cmp"
    assert main(["compare", str(scene), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert field in err and value in err, err
    assert not out.exists()


def test_measured_data_with_several_scene_cases_asks_for_one(tmp_path, capsys):
    f = tmp_path / "f.csv"
    f.write_text("index,force\n" + "".join(f"{k},1\n" for k in range(7)))
    out = tmp_path / "o"
    assert main(["compare", str(EXAMPLES / "S1.toml"), "--measured-forces", str(f), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "load.cases = [50.0, 100.0, 150.0]" in err and "--loads" in err
    assert not out.exists()


# ---------------------------------------------------------------- sensor position and size
def test_sensor_options_feed_map_reading_forces_and_e_m(tmp_path, monkeypatch):
    from twoscale.io.vtk import read_vtk
    from twoscale.sensor import Sensor

    monkeypatch.setattr(compare, "_block_factory", lambda: (None, "no block in this test"))
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT)
    # 8 x 6 cells of 2 mm centred at (4, 0): cell centres x = -3, -1, ..., 11 and y = -5, ..., 5
    sensor = Sensor(8, 6, 2.0, (4.0, 0.0))
    smap = np.zeros((6, 8))
    smap[2, 1] = 1.0  # centre (-1, -1): nearest tip (0, 0)
    smap[2, 5] = 2.0  # centre (7, -1): nearest tip (8, 0)
    mpath = tmp_path / "map.csv"
    mpath.write_text("\n".join(",".join(f"{v:g}" for v in row) for row in smap) + "\n")
    out = tmp_path / "cmp"
    assert (
        main(
            [
                "compare",
                str(scene),
                "--sensor",
                "8",
                "6",
                "2.0",
                "--sensor-centre",
                "4",
                "0",
                "--measured-map",
                str(mpath),
                "--vtk",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    rows = [r for r in _csv_rows(out / "forces.csv") if r["body"] == "measured"]
    assert [float(r["force_N"]) for r in rows] == pytest.approx([4.0, 8.0, 0.0])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["sensor"] == {"nx": 8, "ny": 6, "cell_mm": 2.0, "centre_mm": [4.0, 0.0]}
    fields = read_vtk(out / "runs" / "halfspace_10N" / "fields.vtm").fields
    P = sum(sensor.average_field(f.grid, f.pressure) for f in fields)
    loaded = (P != 0) | (smap != 0)
    expected = 100 * np.sum((P - smap)[loaded] ** 2) / np.sum(smap**2)
    assert summary["indicators_percent"]["10N"]["measured"]["halfspace"]["e_m"] == pytest.approx(expected, rel=1e-8)
    assert "8 x 6 sensor cells of 2 mm centred at (4, 0) mm" in (out / "forces.md").read_text()


def test_measured_map_must_have_the_sensor_shape(tmp_path, capsys):
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT)
    mpath = tmp_path / "map.csv"
    mpath.write_text("\n".join(",".join(["0"] * 44) for _ in range(44)) + "\n")  # the default 44 x 44
    out = tmp_path / "cmp"
    assert (
        main(
            [
                "compare",
                str(scene),
                "--sensor",
                "20",
                "10",
                "1.9",
                "--measured-map",
                str(mpath),
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "44 rows" in err and "ny = 10" in err, err
    assert not out.exists()


@pytest.mark.parametrize(
    "extra, name, value",
    [
        (["--sensor", "0", "44", "1.9"], "--sensor NX", "'0'"),
        (["--sensor", "44", "4.5", "1.9"], "--sensor NY", "'4.5'"),
        (["--sensor", "x", "44", "1.9"], "--sensor NX", "'x'"),
        (["--sensor", "44", "44", "-1"], "--sensor CELL", "'-1'"),
        (["--sensor", "44", "44", "nan"], "--sensor CELL", "'nan'"),
        (["--sensor-centre", "inf", "0"], "--sensor-centre X", "'inf'"),
        (["--sensor-centre", "0", "up"], "--sensor-centre Y", "'up'"),
    ],
)
def test_bad_sensor_options_exit_2(tmp_path, capsys, extra, name, value):
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT)
    out = tmp_path / "cmp"
    assert main(["compare", str(scene), "--out", str(out), "--quiet", *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert name in err and value in err, err
    assert not out.exists()


def test_sensor_away_from_the_contact_is_noted_not_fatal(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(compare, "_block_factory", lambda: (half_space_as_block, ""))
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT)
    out = tmp_path / "cmp"
    assert (
        main(
            [
                "compare",
                str(scene),
                "--sensor",
                "4",
                "4",
                "1",
                "--sensor-centre",
                "100",
                "100",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    assert "carries 0 N of the 10 N of halfspace" in capsys.readouterr().err
    ind = json.loads((out / "summary.json").read_text())["indicators_percent"]["10N"]
    assert ind["halfspace"]["block-bonded"] == {"e_M": 0.0, "e_m": None}


# ---------------------------------------------------------------- every top-level file records each body
BLOCK_SCENE = (
    THREE_SPHERES_TILT.replace("total = 10.0", "total = 10.0\ncases = [10.0, 20.0]")
    + """
[influence]
kind = "block"
size = [100.0, 120.0, 20.0]
base = "sliding"
origin = [3.0, -4.0]
"""
)


def _png_description(path):
    from PIL import Image

    with Image.open(path) as im:
        return json.loads(im.text["Description"])


def test_every_top_level_file_records_each_body_and_all_loads(tmp_path, monkeypatch):
    from twoscale.io.scene_file import scene_from_dict

    monkeypatch.setattr(compare, "_block_factory", lambda: (half_space_as_block, ""))
    scene = tmp_path / "block.toml"
    scene.write_text(BLOCK_SCENE)
    out = tmp_path / "cmp"
    assert main(["compare", str(scene), "--out", str(out), "--quiet"]) == 0
    loads = [{"label": "10N", "total": 10.0}, {"label": "20N", "total": 20.0}]
    block = {"kind": "block", "size": [100.0, 120.0, 20.0], "origin": [3.0, -4.0], "source_spacing": 5.0}
    expected = {
        "halfspace": {"influence": {"kind": "halfspace"}, "loads": loads},
        "block-bonded": {"influence": {**block, "base": "bonded"}, "loads": loads},
        "block-sliding": {"influence": {**block, "base": "sliding"}, "loads": loads},
    }

    csv_meta = json.loads((out / "forces.csv-metadata.json").read_text())["twoscale"]
    summary = json.loads((out / "summary.json").read_text())
    md = (out / "forces.md").read_text()
    md_meta = json.loads(md.split("```json\n", 1)[1].split("\n```", 1)[0])
    records = {"forces.csv": csv_meta, "summary.json": summary, "forces.md": md_meta}
    for name in ("forces_10N.png", "maps_20N.png", "sensor_10N.png", "difference_20N.png"):
        records[name] = _png_description(out / name)
    for name, rec in records.items():
        assert rec["bodies"] == expected, name
        assert rec["scene"]["load"]["cases"] == [10.0, 20.0] and rec["scene"]["load"]["total"] == 10.0, name
        assert rec["scene"]["influence"]["base"] == "sliding", name  # the file's own [influence]
        assert rec["sensor"] == {"nx": 44, "ny": 44, "cell_mm": 1.9, "centre_mm": [0.0, 0.0]}, name
    assert "| block-bonded | block | 100 x 120 x 20 | bonded | (3, -4) | total load 10 N, total load 20 N |" in md
    # the record rebuilds every solve: scene + the body's influence + the load
    for body, b in expected.items():
        for load in b["loads"]:
            rebuilt = dict(
                summary["scene"], influence=b["influence"], load=dict(summary["scene"]["load"], total=load["total"])
            )
            run = json.loads((out / "runs" / f"{body}_{load['label']}" / "result.json").read_text())
            assert scene_from_dict(rebuilt) == scene_from_dict(run["scene"]), (body, load)
