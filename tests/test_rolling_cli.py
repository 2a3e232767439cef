"""A [rolling] scene through ``twoscale solve SCENE --out DIR``: the files with exactly
their columns, and bad input refused with one line naming the field, exit 2, nothing
written."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from twoscale.cli.main import main
from twoscale.io.scene_file import read_scene, scene_from_dict, scene_to_dict
from twoscale.rolling import road_strip

SCENE = """
[material]
E = 10.0
nu = 0.5
{prony}
[load]
{load}
[surface]
file = "strip.npy"
spacing = 0.25
[rolling]
{rolling}
"""
ROLLING = {
    "start": "-4.0",
    "end": "-2.0",
    "step": "1.0",
    "speed": "50.0",
    "tyre_radius": "150.0",
    "footprint": "[30.0, 12.0]",
}


@pytest.fixture(scope="module")
def strip_file(tmp_path_factory):
    folder = tmp_path_factory.mktemp("strip")
    np.save(folder / "strip.npy", road_strip(50.0, 16.0, 0.25, seed=5))
    return folder


def _scene(folder, *, load="total = 40.0", prony="", **rolling) -> str:
    table = {**ROLLING, **rolling}
    lines = "\n".join(f"{k} = {v}" for k, v in table.items() if v is not None)
    path = folder / "scene.toml"
    path.write_text(SCENE.format(load=load, prony=prony, rolling=lines), encoding="utf-8")
    return str(path)


def test_outputs_have_exactly_their_columns(strip_file, tmp_path):
    out = tmp_path / "run"
    assert main(["solve", _scene(strip_file), "--out", str(out), "--quiet"]) == 0
    with open(out / "signals.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["time_s", "shift_mm", "total_load_N", "penetration_mm", "contact_area_mm2", "drag_N"]
    assert len(rows) == 1 + 3
    shifts = [float(r[1]) for r in rows[1:]]
    assert shifts == [-4.0, -3.0, -2.0]
    # time = distance / speed: 1 mm at 50 km/h
    assert float(rows[2][0]) == pytest.approx(1.0 / (50.0 * 1e6 / 3600.0), rel=1e-9)
    assert all(float(r[2]) == pytest.approx(40.0, rel=1e-6) for r in rows[1:])
    with open(out / "asperity_signals.csv", newline="") as fh:
        stones = list(csv.reader(fh))
    assert stones[0] == ["time_s", "shift_mm", "asperity", "force_N", "contact_area_mm2"]
    by_shift: dict = {}
    for r in stones[1:]:
        assert int(r[2]) >= 1 and float(r[4]) > 0
        by_shift[float(r[1])] = by_shift.get(float(r[1]), 0.0) + float(r[3])
    assert by_shift[-3.0] == pytest.approx(40.0, rel=1e-6)  # the stones' forces add up to the load
    meta = json.loads((out / "rolling.json").read_text())
    assert meta["speed_kmh"] == 50.0 and meta["steps"]["positions"] == 3
    assert meta["scene"]["rolling"]["tyre_radius"] == 150.0
    assert [p["converged"] for p in meta["positions"]] == [True] * 3
    assert (out / "fields.pvd").is_file() and len(list((out / "fields").glob("s_*.vti"))) == 3
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    table = pd.read_parquet(out / "asperity_signals.parquet")
    assert list(table.columns) == stones[0] and len(table) == len(stones) - 1


@pytest.mark.parametrize(
    "change, field",
    [
        ({"end": "-6.0"}, "rolling.end"),
        ({"step": "0.0"}, "rolling.step"),
        ({"step": "-1.0"}, "rolling.step"),
        ({"speed": "0.0"}, "rolling.speed"),
        ({"speed": "-5.0"}, "rolling.speed"),
        ({"start": "-20.0"}, "rolling.start"),  # the strip is shorter than footprint + run
        ({"tyre_radius": None, "footprint": "[49.0, 12.0]"}, "rolling.start"),  # a flat 49 mm tread, 2 mm run
        ({"tyre_radius": "1e-5"}, "rolling.tyre_radius"),
        ({"unknown": "1"}, "rolling.unknown"),
    ],
)
def test_bad_input_exit_2_nothing_written(strip_file, tmp_path, capsys, change, field):
    out = tmp_path / "run"
    scene = _scene(strip_file, **change)
    code = main(["solve", scene, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    # the file first, whether the reader or the rolling's own checks refused it
    assert len(err.strip().splitlines()) == 1 and err.startswith(f"error: {scene}: ")
    assert field in err
    assert not out.exists()


def test_tyre_that_leaves_no_contact_under_penetration_control(strip_file, tmp_path, capsys):
    # held 0.01 mm below the strip's highest point on a small tyre: no stone reaches it at the start
    out = tmp_path / "run"
    scene = _scene(strip_file, load="penetration = 0.001", tyre_radius="5.0")
    code = main(["solve", scene, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "rolling.tyre_radius" in err and len(err.strip().splitlines()) == 1
    assert err.startswith(f"error: {scene}: rolling.tyre_radius")
    assert not out.exists()


@pytest.mark.parametrize(
    "option, named",
    [
        (["--method", "reference"], "--method reference"),
        (["--far-tol", "0.3"], "--far-tol 0.3"),
        (["--block-field"], "--block-field"),
    ],
)
def test_a_static_solves_option_is_refused_naming_its_value(strip_file, tmp_path, capsys, option, named):
    out = tmp_path / "run"
    code = main(["solve", _scene(strip_file), "--out", str(out), *option])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert err.startswith(f"error: {named} does not apply to a [rolling] scene")
    assert not out.exists()


def test_viscoelastic_rolling_through_the_cli(strip_file, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["solve", _scene(strip_file, prony="prony = [[20.0, 0.01]]"), "--out", str(out)]) == 0
    assert "  start        from rest:" in capsys.readouterr().out
    meta = json.loads((out / "rolling.json").read_text())
    assert meta["body"].endswith("viscoelastic") and meta["material"]["prony"] == [[20.0, 0.01]]
    with open(out / "signals.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0][-1] == "drag_N" and len(rows) == 4
    if __import__("importlib").util.find_spec("matplotlib"):  # the elastic run's figures, all three
        assert all((out / f"{name}.png").is_file() for name in ("signals", "bands", "space_time"))
        # titled with the held load and the speed: two runs of one scene are told apart
        from helpers import png_info

        assert png_info(out / "signals.png")[1]["Title"].startswith("scene W=40N 50km/h on the half-space")


def test_the_summary_of_a_viscoelastic_run_names_its_start_from_rest():
    # one branch: the creep's retardation time is tau (E + E_1) / E = 1 ms x 40 / 10 = 4 ms,
    # 4 mm of road at 1,000 mm/s
    from types import SimpleNamespace

    from twoscale.cli.rolling import start_line
    from twoscale.material import Material

    run = SimpleNamespace(spec=SimpleNamespace(speed_mm_s=1000.0), shifts=np.array([-10.0, 0.0, 10.0]))
    line = start_line(run, Material(10.0, 0.5, prony=((30.0, 1e-3),)))
    assert "v lambda = 4 mm" in line and "0.004 s" in line and "the first 12 mm of this 20 mm run" in line


def test_the_bands_line_names_the_bands_the_drift_leaks_into():
    # the periodogram sees the run as periodic: a signal that ends where it started has no
    # leak; the same noise on a straight drift of 0.05 mm has every band at its leak's level
    from types import SimpleNamespace

    from twoscale.cli.rolling import _bands_line

    rng = np.random.default_rng(3)
    noise = 1e-3 * rng.standard_normal(400)
    noise[-1] = noise[0]

    def line(signal):
        spec = SimpleNamespace(step=0.5, speed_mm_s=50.0 / 3.6 * 1e3)
        return _bands_line(SimpleNamespace(control="load", penetration=signal, total_load=signal, spec=spec))

    assert "drift" not in line(1.0 + noise)
    said = line(1.0 + noise + np.linspace(0.0, 0.05, 400))
    resolved = int(said.split("bands")[1].split()[0])
    assert f"; {resolved} of them less than 10 dB above what the drift" in said and "(+0.05 mm)" in said


@pytest.mark.parametrize(
    "option, words",
    [((), "one CG over the kept window"), (("--iteration", "block-gs"), "each position a two-scale solve")],
)
def test_the_summary_says_how_the_positions_were_solved(strip_file, capsys, option, words):
    """--iteration other than auto runs every position as a two-scale solve (far slower on a
    tyre): the first line says which path ran, as rolling.json's method."""
    assert main(["solve", _scene(strip_file), *option]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert first.endswith(words)


def test_rolling_json_lists_the_runs_warnings(strip_file, tmp_path, capsys):
    """A step of 1 mm over samples 0.25 mm apart on a viscoelastic body is coarse: the
    StepWarning printed on stderr is listed in rolling.json too; an elastic run lists none."""
    out = tmp_path / "coarse"  # the branch is 1.4 mm long at 50 km/h: active on the 50 mm strip
    assert main(["solve", _scene(strip_file, prony="prony = [[20.0, 1e-4]]"), "--out", str(out), "--quiet"]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]
    (entry,) = json.loads((out / "rolling.json").read_text())["warnings"]
    assert entry["category"] == "StepWarning" and entry["count"] == 1
    assert entry["message"].startswith("rolling.step = 1 mm") and err == [f"warning: {entry['message']}"]
    assert main(["solve", _scene(strip_file), "--out", str(tmp_path / "elastic"), "--quiet"]) == 0
    assert json.loads((tmp_path / "elastic" / "rolling.json").read_text())["warnings"] == []


def test_viscoelastic_rolling_of_tips_refused(tmp_path, capsys):
    scene = tmp_path / "tips.toml"
    scene.write_text(
        """
[material]
E = 10.0
nu = 0.5
prony = [[20.0, 0.01]]
[load]
total = 5.0
[[asperity]]
x = 0.0
y = 0.0
R = 5.0
[rolling]
start = -2.0
end = 2.0
step = 1.0
speed = 10.0
footprint = [30.0, 30.0]
""",
        encoding="utf-8",
    )
    out = tmp_path / "run"
    assert main(["solve", str(scene), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "material.prony" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_rolling_table_round_trip(strip_file):
    scene = read_scene(_scene(strip_file))
    again = scene_from_dict(scene_to_dict(scene))
    assert again.rolling == scene.rolling
    assert scene.rolling.footprint == (30.0, 12.0)


def test_coarse_viscoelastic_step_warns_and_records_the_balance(strip_file, tmp_path, capsys):
    """A branch of 0.1 ms at 50 km/h (1.4 mm of road) on a 0.25 mm strip rolled in 1 mm steps:
    one warning line naming rolling.step, ``step_check`` in rolling.json, and the energy
    balance there equal to the one recomputed from the files (drag and load over the shifts
    and approaches, the branches' energy per position)."""
    out = tmp_path / "run"
    assert main(["solve", _scene(strip_file, prony="prony = [[20.0, 1e-4]]"), "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("warning: rolling.step = 1 mm is coarser than 0.25 mm")
    meta = json.loads((out / "rolling.json").read_text())
    check = meta["step_check"]
    assert check["coarse"] and check["limit_mm"] == 0.25 and check["branch_tau_s"] == 1e-4
    with open(out / "signals.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    s, W, d, g = (
        np.array([float(r[k]) for r in rows]) for k in ("shift_mm", "total_load_N", "penetration_mm", "drag_N")
    )
    work = np.trapezoid(g, s) + np.trapezoid(W, d)
    energy = meta["energy_Nmm"]
    spent = energy["stored"][-1] - energy["stored"][0] + sum(energy["dissipated"][1:])
    balance = meta["energy_balance"]
    assert balance["mismatch"] == pytest.approx(work / spent - 1.0, rel=1e-6, abs=1e-9)
    assert "second order in the step" in balance["meaning"]


def test_footprint_wider_than_the_strip_warns_naming_it(strip_file, tmp_path, capsys):
    # the strip is 16 mm wide: a 24 mm footprint's outer 4 mm on each side meet no road
    out = tmp_path / "run"
    assert main(["solve", _scene(strip_file, footprint="[30.0, 24.0]"), "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("warning: rolling.footprint = [30, 24] mm is wider than the strip")


def test_block_face_wider_than_the_strip_warns_naming_it(strip_file, tmp_path, capsys, monkeypatch):
    # a flat tread block without a footprint: its face, 60 mm across less its margins, is
    # wider than the 16 mm strip, and the rubber beyond the strip meets no road
    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path / "cache"))
    path = _scene(strip_file, tyre_radius=None, footprint=None)
    with open(path, "a", encoding="utf-8") as fh:
        fh.write('[influence]\nkind = "block"\nsize = [44.0, 60.0, 8.0]\nbase = "bonded"\nsource_spacing = 4.0\n')
    assert main(["solve", path, "--out", str(tmp_path / "run"), "--quiet"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        "warning: influence.size = [44, 60, ...] mm (the part of the block's face"
    )
    assert "mm across y) is wider than the strip (15.75 mm across y" in err[0]
    # a run longer than the strip leaves beyond the face: refused, naming what sets the length
    text = open(path, encoding="utf-8").read().replace("end = -2.0", "end = 30.0")
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(text)
    assert main(["solve", path, "--out", str(tmp_path / "long")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "rolling.end = 30.0" in err[0] and "block's face" in err[0] and "influence.size" in err[0]
    assert not (tmp_path / "long").exists()


def test_fine_step_does_not_warn(strip_file, tmp_path, capsys):
    # the same branch, 0.25 mm steps (one sample): no warning, step_check says so
    out = tmp_path / "run"
    scene = _scene(strip_file, prony="prony = [[20.0, 1e-4]]", step="0.25", end="-3.5")
    assert main(["solve", scene, "--out", str(out), "--quiet"]) == 0
    assert "warning" not in capsys.readouterr().err
    assert json.loads((out / "rolling.json").read_text())["step_check"]["coarse"] is False


def test_step_error_warns_of_the_road_once(strip_file, tmp_path, capsys):
    """The run at twice the step rolls the same road under the same face: a footprint wider
    than the strip is warned of once, on stderr and in ``rolling.json``, not once per run."""
    out = tmp_path / "run"
    scene = _scene(strip_file, prony="prony = [[20.0, 1e-4]]", footprint="[30.0, 24.0]")
    assert main(["solve", scene, "--out", str(out), "--quiet", "--step-error"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert sum("rolling.footprint" in line for line in err) == 1
    listed = json.loads((out / "rolling.json").read_text())["warnings"]
    assert [w["count"] for w in listed if w["category"] == "SurfaceWarning"] == [1]


def test_step_error_from_a_run_at_twice_the_step(strip_file, tmp_path, capsys):
    """``--step-error``: the friction over the run (from signals.csv: the drag's trapezoid
    mean over the shifts) against the run at twice the step; the extrapolation adds their
    difference (first order). Refused, exit 2, for an elastic material."""
    out = tmp_path / "run"
    scene = _scene(strip_file, prony="prony = [[20.0, 1e-4]]")
    assert main(["solve", scene, "--out", str(out), "--quiet", "--step-error"]) == 0
    assert len(capsys.readouterr().err.strip().splitlines()) == 1  # the coarse step's warning, once
    e = json.loads((out / "rolling.json").read_text())["step_error"]
    with open(out / "signals.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    s, g = (np.array([float(r[k]) for r in rows]) for k in ("shift_mm", "drag_N"))
    assert e["distance_mm"] == pytest.approx(2.0)
    assert e["friction_N"] == pytest.approx(np.trapezoid(g, s) / 2.0, rel=1e-9)
    assert e["extrapolated_friction_N"] == pytest.approx(2 * e["friction_N"] - e["friction_at_twice_the_step_N"])
    assert e["friction_at_twice_the_step_N"] != e["friction_N"]
    elastic = tmp_path / "elastic"
    assert main(["solve", _scene(strip_file), "--out", str(elastic), "--step-error"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "--step-error" in err and not elastic.exists()


def test_step_error_refused_without_rolling(tmp_path, capsys):
    scene = tmp_path / "static.toml"
    scene.write_text("[material]\nE = 10.0\nnu = 0.5\n[load]\ntotal = 5.0\n[[asperity]]\nx = 0.0\ny = 0.0\nR = 5.0\n")
    out = tmp_path / "run"
    assert main(["solve", str(scene), "--out", str(out), "--step-error"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "--step-error" in err and not out.exists()


def test_a_single_position_writes_the_bands_header_only(strip_file, tmp_path):
    """start = end: one position, no spectrum; bands.csv is still there, header only, as a run
    too short for any band writes it."""
    out = tmp_path / "run"
    assert main(["solve", _scene(strip_file, end="-4.0"), "--out", str(out), "--quiet"]) == 0
    with open(out / "bands.csv", newline="") as fh:
        assert list(csv.reader(fh)) == [["band_Hz", "level_dB"]]
    with open(out / "signals.csv", newline="") as fh:
        assert len(list(csv.reader(fh))) == 2


def test_rolling_json_times_the_strips_segmentation(strip_file, tmp_path, monkeypatch):
    """The strip is segmented when the scene is read, before the run's clock: its seconds are
    ``rolling.json`` ``timings_s.segment`` (a segmentation made to last 0.3 s more is
    there)."""
    import time

    import twoscale.surface.measured as measured

    real = measured.segment

    def slow(*args, **kwargs):
        time.sleep(0.3)
        return real(*args, **kwargs)

    monkeypatch.setattr(measured, "segment", slow)
    out = tmp_path / "run"
    assert main(["solve", _scene(strip_file), "--out", str(out), "--quiet"]) == 0
    t = json.loads((out / "rolling.json").read_text())["timings_s"]
    assert t["segment"] >= 0.3
    assert t["total"] == pytest.approx(t["prepare"] + t["positions"])
