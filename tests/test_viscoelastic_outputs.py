"""``twoscale solve`` on a scene with a load history: the files (history.csv columns
exactly as specified, fields.pvd time series, result.json record, history.png) and the
bad-input exits."""

import csv
import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from twoscale.cli.main import main
from twoscale.io.vti import read_image

SCENE = """
[material]
E = 2.0
nu = 0.5
prony = [[8.0, 1.0]]

[load]
total = [[0, 2.0], [2, 2.0], [3, 0.5]]
{tilt}

[time]
output = [0, 0.5, 2, 2.5, 3]

[grid]
h = 0.15

[[asperity]]
x = 0.0
y = 0.0
R = 10.0
shape = "paraboloid"

[[asperity]]
x = 4.0
y = 1.0
z = 0.01
R = 8.0

[[asperity]]
x = 1.0
y = 4.0
z = 0.02
R = 8.0
"""


def _write(tmp_path, text):
    path = tmp_path / "creep.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("tilt", [False, True])
def test_solve_writes_the_history_files(tmp_path, tilt):
    scene = _write(tmp_path, SCENE.format(tilt="tilt = true\npivot = [1.5, 1.5]" if tilt else ""))
    out = tmp_path / "out"
    assert main(["solve", str(scene), "--out", str(out), "--quiet"]) == 0
    with open(out / "history.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    head = ["time_s", "penetration_mm", "total_load_N", "contact_area_mm2"]
    head += ["tilt_x_rad", "tilt_y_rad"] if tilt else []
    assert rows[0] == head + ["force_1", "force_2", "force_3"]
    data = np.array(rows[1:], dtype=float)
    np.testing.assert_allclose(data[:, 0], [0, 0.5, 2, 2.5, 3])
    np.testing.assert_allclose(data[:, 2], [2.0, 2.0, 2.0, 1.25, 0.5], rtol=1e-6)
    np.testing.assert_allclose(data[:, -3:].sum(axis=1), data[:, 2], rtol=1e-6)
    assert data[2, 1] > data[1, 1] > data[0, 1]  # creep under the held load
    record = json.loads((out / "result.json").read_text())
    assert record["material"]["prony"] == [[8.0, 1.0]] and record["history"]["control"] == "total"
    assert record["steps"]["count"] == len(record["steps"]["dt"]) and record["steps"]["error_estimate"] >= 0
    assert record["memory"]["bytes_per_cell"] == 8 * 3
    pvd = ET.parse(out / "fields.pvd").getroot()
    sets = pvd.findall("./Collection/DataSet")
    assert [float(s.get("timestep")) for s in sets] == [0, 0.5, 2, 2.5, 3]
    image = read_image(out / sets[2].get("file"))
    h = 0.15
    assert image.cell_data["pressure_MPa"].sum() * h * h == pytest.approx(2.0, rel=1e-6)
    assert (out / "history.png").stat().st_size > 0


def test_the_summary_names_the_files_written(tmp_path, capsys):
    """As a static solve's summary: the folder and every file in it, by name."""
    out = tmp_path / "out"
    assert main(["solve", str(_write(tmp_path, SCENE.format(tilt=""))), "--out", str(out)]) == 0
    wrote = [line for line in capsys.readouterr().out.splitlines() if line.strip().startswith("wrote")]
    names = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    assert "history.csv" in names and wrote == [f"  wrote        {out}/: {', '.join(names)}"]


@pytest.mark.parametrize(
    "change, text",
    [
        ("prony = [[8.0, 1.0]]", "prony = [[8.0, -1.0]]"),
        ("total = [[0, 2.0], [2, 2.0], [3, 0.5]]", "total = [[0, 2.0], [2, 2.0], [1, 0.5]]"),
        ("total = [[0, 2.0], [2, 2.0], [3, 0.5]]", "total = [[0, 2.0], [3, 0.5]]\npenetration = [[0, 0.1]]"),
        ("output = [0, 0.5, 2, 2.5, 3]", "output = [0, 4]"),
    ],
)
def test_bad_input_exits_2_and_writes_nothing(tmp_path, capsys, change, text):
    scene = _write(tmp_path, SCENE.format(tilt="").replace(change, text))
    out = tmp_path / "out"
    assert main(["solve", str(scene), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ")
    assert not out.exists()


def test_the_history_table_has_its_metadata_as_every_table(tmp_path):
    """history.csv opens in pandas with the documented columns, and its metadata JSON
    (version, units, scene, a description per column) lies beside it as for every table."""
    import pandas as pd

    out = tmp_path / "out"
    assert main(["solve", str(_write(tmp_path, SCENE.format(tilt=""))), "--out", str(out), "--quiet"]) == 0
    table = pd.read_csv(out / "history.csv")
    columns = ["time_s", "penetration_mm", "total_load_N", "contact_area_mm2", "force_1", "force_2", "force_3"]
    assert list(table.columns) == columns
    np.testing.assert_allclose(table[columns[4:]].sum(axis=1), table.total_load_N, rtol=1e-6)
    meta = json.loads((out / "history.csv-metadata.json").read_text())
    assert [c["name"] for c in meta["tableSchema"]["columns"]] == columns
    assert all(c.get("dc:description") for c in meta["tableSchema"]["columns"])
    assert meta["twoscale"]["units"]["force"] == "N" and meta["twoscale"]["scene"]["material"]["prony"] == [[8.0, 1.0]]


def test_a_penetration_history_from_zero_writes_every_file(tmp_path):
    """The README's ``penetration = [[0, 0.0], [1, 0.3]]``: at t = 0 nothing touches (no
    pressure field), which the time series must take as a frame of zero pressure, not fail on."""
    text = SCENE.format(tilt="").replace("total = [[0, 2.0], [2, 2.0], [3, 0.5]]", "penetration = [[0, 0.0], [3, 0.1]]")
    out = tmp_path / "out"
    assert main(["solve", str(_write(tmp_path, text)), "--out", str(out), "--quiet"]) == 0
    sets = ET.parse(out / "fields.pvd").getroot().findall("./Collection/DataSet")
    assert [float(s.get("timestep")) for s in sets] == [0, 0.5, 2, 2.5, 3]
    first, last = (read_image(out / sets[k].get("file")).cell_data["pressure_MPa"] for k in (0, -1))
    assert not first.any() and last.max() > 0
    with open(out / "history.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert float(rows[0]["total_load_N"]) == 0.0 and float(rows[-1]["total_load_N"]) > 0.0


@pytest.mark.parametrize(
    "load, given",
    [("cases = [0.5, 2.0]", "got load cases [0.5, 2.0]"), ("total = 2.0", "got a single value 2.0")],
)
def test_prony_without_a_history_names_what_was_given(tmp_path, capsys, load, given):
    """Load cases or one load on a Prony material: the one line says which it got."""
    text = SCENE.format(tilt="").replace("total = [[0, 2.0], [2, 2.0], [3, 0.5]]", load)
    text = text.replace("[time]\noutput = [0, 0.5, 2, 2.5, 3]\n", "")
    assert main(["solve", str(_write(tmp_path, text)), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "material.prony needs a load history" in err[0] and err[0].endswith(given)
