"""``twoscale indicators``: e_M and e_m between two stored solves.

Independent checks: e_M recomputed from the two result.json files and e_m from sensor
maps rebuilt here from the two fields.vtm files, both by the formulas of docs/method.md
section 5 written out; a run against itself gives 0; bad input exits with 2.
"""

import json

import numpy as np
import pytest

from twoscale.cli.main import main
from twoscale.io.vtk import read_vtk
from twoscale.sensor import Sensor

SCENE = """
[material]
E = 6.0
nu = 0.5
[load]
total = {W}
[[asperity]]
x = -4.0
y = 0.0
z = 0.0
R = 5.0
[[asperity]]
x = 4.0
y = 1.0
z = 0.02
R = 4.0
"""


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    root = tmp_path_factory.mktemp("ind")
    out = {}
    for W in (10.0, 12.0):
        scene = root / f"s{W:g}.toml"
        scene.write_text(SCENE.format(W=W), encoding="utf-8")
        out[W] = root / f"o{W:g}"
        assert main(["solve", str(scene), "--out", str(out[W]), "--quiet", "--h", "0.1"]) == 0
    return out


def _forces(folder):
    return np.array([a["force"] for a in json.loads((folder / "result.json").read_text())["asperities"]])


def test_indicators_match_the_formulas(runs, tmp_path, capsys):
    a, b = runs[12.0], runs[10.0]
    target = tmp_path / "ind.json"
    assert main(["indicators", str(a), str(b), "--json", str(target), "--sensor", "20", "20", "1.0"]) == 0
    rec = json.loads(target.read_text())
    P, R = _forces(a), _forces(b)
    assert rec["e_M_percent"] == pytest.approx(100 * np.sum((P - R) ** 2) / np.sum(R**2), rel=1e-12)
    s = Sensor(20, 20, 1.0)
    maps = []
    for folder in (a, b):
        m = np.zeros(s.shape)
        for f in read_vtk(folder / "fields.vtm").fields:
            m += s.average_field(f.grid, f.pressure)
        maps.append(m)
    p, r = maps
    mask = (p != 0) | (r != 0)
    assert rec["e_m_percent"] == pytest.approx(100 * np.sum((p - r)[mask] ** 2) / np.sum(r[mask] ** 2), rel=1e-12)
    assert rec["e_M_percent"] > 1.0 and rec["e_m_percent"] > 0.1  # 20 % more load: not small
    assert rec["sensor"] == {"nx": 20, "ny": 20, "cell": 1.0, "centre": [0.0, 0.0]}
    assert rec["version"] and rec["units"]["force"] == "N"
    assert "e_M = " in capsys.readouterr().out


def test_a_run_against_itself_is_zero(runs, capsys):
    assert main(["indicators", str(runs[10.0]), str(runs[10.0])]) == 0
    out = capsys.readouterr().out
    assert "e_M = 0 %" in out and "e_m = 0 %" in out


def test_sensor_away_from_the_contact_gives_no_e_m(runs, capsys):
    assert main(["indicators", str(runs[12.0]), str(runs[10.0]), "--sensor-centre", "500", "0"]) == 0
    assert "e_m = n/a" in capsys.readouterr().out


@pytest.mark.parametrize("case", ["missing", "not_json", "sensor", "json_dir", "count", "history", "rolling"])
def test_bad_input_exit_2_nothing_written(runs, tmp_path, capsys, case):
    a, b = str(runs[12.0]), str(runs[10.0])
    target = tmp_path / "ind.json"
    if case == "missing":
        argv, needle = [a, str(tmp_path / "nowhere")], "nowhere"
    elif case == "not_json":
        bad = tmp_path / "bad"
        bad.mkdir()
        (bad / "result.json").write_text("{not json", encoding="utf-8")
        argv, needle = [a, str(bad)], "is not a twoscale result.json"
    elif case == "sensor":
        argv, needle = [a, b, "--sensor", "0", "44", "1.9"], "--sensor NX must be an integer >= 1, got '0'"
    elif case == "json_dir":
        argv, needle = [a, b, "--json", str(tmp_path)], "--json must name a file"
    elif case == "history":  # a load history's folder: its forces are per output time
        hist = tmp_path / "hist"
        hist.mkdir()
        (hist / "result.json").write_text(json.dumps({"kind": "history", "outputs": []}), encoding="utf-8")
        argv, needle = [a, str(hist)], "is a load history's"
    elif case == "rolling":  # a rolling run's folder has rolling.json, no result.json
        roll = tmp_path / "roll"
        roll.mkdir()
        (roll / "rolling.json").write_text("{}", encoding="utf-8")
        argv, needle = [str(roll), b], "holds a rolling run"
    else:
        one = tmp_path / "one"
        one.mkdir()
        (one / "result.json").write_text(json.dumps({"asperities": [{"force": 1.0}]}), encoding="utf-8")
        argv, needle = [a, str(one)], "has 2 asperities and"
    code = main(["indicators", *argv] + ([] if case == "json_dir" else ["--json", str(target)]))
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and needle in err[0]
    assert not target.exists()


MAP_SCENE = """
[material]
E = 6.0
nu = 0.5
[load]
total = 10.0
[surface]
file = "{name}"
spacing = 0.1
units = "mm"
"""


def _map_run(root, name: str, caps) -> object:
    """A solve --out of a height map of two paraboloid caps (R 5 mm, 1 mm high) at ``caps``."""
    x = np.linspace(-10.0, 10.0, 201)
    X, Y = np.meshgrid(x, x)
    z = np.max([1.0 - ((X - cx) ** 2 + (Y - cy) ** 2) / 10.0 for cx, cy in caps], axis=0)
    np.save(root / f"{name}.npy", np.maximum(z, 0.0))
    scene = root / f"{name}.toml"
    scene.write_text(MAP_SCENE.format(name=f"{name}.npy"), encoding="utf-8")
    assert main(["solve", str(scene), "--out", str(root / name), "--quiet"]) == 0
    return root / name


def test_height_map_runs_with_summits_elsewhere_are_named(tmp_path, capsys):
    # a height map's scene lists no tips: the summits' places come from asperities.csv
    a = _map_run(tmp_path, "a", [(-4.0, 0.0), (4.0, 1.0)])
    b = _map_run(tmp_path, "b", [(-4.0, 0.0), (5.0, 1.0)])
    capsys.readouterr()
    assert main(["indicators", str(a), str(a)]) == 0
    assert "different places" not in capsys.readouterr().err
    assert main(["indicators", str(a), str(b)]) == 0
    [line] = [x for x in capsys.readouterr().err.splitlines() if "different places" in x]
    assert "(asperity 2: (4, 1) against (5, 1) mm)" in line
