"""Tables any tool opens, and the numbers a reader looks for first.

Every CSV a command writes is opened with pandas and the csv module without options
(:func:`tidy_tables.assert_tidy`); the contact area and its ratio to the nominal area are
checked against Hertz's closed form; the body is named in the result, result.json and the
summary; compare leads with the per-tip changes; a study keeps one cell size across loads.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pandas")

from twoscale.cli import compare
from twoscale.cli.main import main
from twoscale.influence import HalfSpace
from twoscale.io.tables import cell
from twoscale.setting import Body, nominal_area

from helpers import THREE_SPHERES_TILT, half_space_as_block
from tidy_tables import assert_tidy

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


# ---------------------------------------------------------------- the CSV cells
@pytest.mark.parametrize(
    "value, text",
    [
        (7.490000000000001, "7.49"),
        (0.1 + 0.2, "0.3"),
        (-0.0, "0"),
        (1e-20, "1e-20"),
        (12, "12"),
        (np.int64(3), "3"),
        (None, ""),
        (math.nan, ""),
        (True, "true"),
        (np.float32(0.5), "0.5"),
        ("halfspace", "halfspace"),
    ],
)
def test_cells_carry_the_precision_of_the_number(value, text):
    assert cell(value) == text


def test_parquet_only_beside_long_tables(tmp_path):
    pytest.importorskip("pyarrow")
    import pandas as pd
    from twoscale.io.tables import LONG_TABLE, write_table

    rows = [{"k": k, "force_N": 0.5 * k} for k in range(3)]
    assert len(write_table(tmp_path, "short", rows, ("k", "force_N"), title="t", parquet=LONG_TABLE)) == 2
    assert not (tmp_path / "short.parquet").exists()
    written = write_table(tmp_path, "always", rows, ("k", "force_N"), title="t", parquet=0)
    assert written[-1].name == "always.parquet"
    assert pd.read_parquet(written[-1])["force_N"].tolist() == [0.0, 0.5, 1.0]


# ---------------------------------------------------------------- every command's tables
def test_solve_table_opens_without_options(tmp_path):
    out = tmp_path / "run"
    assert main(["solve", str(EXAMPLES / "S1.toml"), "--out", str(out), "--quiet"]) == 0
    rows = assert_tidy(out / "asperities.csv", rows=7)
    res = json.loads((out / "result.json").read_text())
    assert sum(float(r["contact_area_mm2"]) for r in rows) == pytest.approx(res["contact_area"], rel=1e-9)
    if (out / "asperities.parquet").exists():  # with pyarrow: the same rows, typed
        import pandas as pd

        back = pd.read_parquet(out / "asperities.parquet")
        np.testing.assert_allclose(back["force_N"], [a["force"] for a in res["asperities"]], rtol=1e-15)


def test_compare_tables_open_without_options_and_hold_numbers(tmp_path, monkeypatch):
    monkeypatch.setattr(compare, "_block_factory", lambda: (half_space_as_block, ""))
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT)
    out = tmp_path / "cmp"
    assert main(["compare", str(scene), "--loads", "10", "20", "--out", str(out), "--quiet"]) == 0
    forces = assert_tidy(out / "forces.csv", rows=2 * 3 * 3)
    assert {r["load_N"] for r in forces} == {"10", "20"} and {r["penetration_mm"] for r in forces} == {""}
    changes = assert_tidy(out / "changes.csv", rows=2 * 2 * 3)
    # the stand-in block is the half-space: every change is zero
    assert all(float(r["change_percent"]) == 0.0 and r["reference"] == "halfspace" for r in changes)


def test_study_tables_open_without_options(tmp_path, capsys):
    pytest.importorskip("distributed")
    study = _study(tmp_path, loads="[10.0, 20.0]")
    out = tmp_path / "st"
    assert main(["study", str(study), "--out", str(out), "--workers", "0"]) == 0
    cases = assert_tidy(out / "cases.csv", rows=2)
    assert_tidy(out / "asperities.csv", rows=6)
    assert_tidy(out / "indicators.csv", rows=0)
    # one cell size across the loads: the default rule at the lightest load, 10 N
    from twoscale.io.scene_file import read_scene
    from twoscale.scene import default_h
    import dataclasses

    light = dataclasses.replace(read_scene(tmp_path / "noh.toml"), total_load=10.0, load_cases=())
    assert [float(r["h_mm"]) for r in cases] == [default_h(light)] * 2
    assert {r["h_source"] for r in cases} == {"lightest load"}
    text = capsys.readouterr().out
    assert "W = 10 N" in text and "W = 20 N" in text and "h mm" in text and "cases.csv" in text


def _study(tmp_path, loads):
    (tmp_path / "noh.toml").write_text(THREE_SPHERES_TILT.replace("[grid]\nh = 0.3\n", ""))
    path = tmp_path / "study.toml"
    path.write_text(f"""
[study]
name = "loads"
[[scene]]
file = "noh.toml"
name = "small"
[[body]]
name = "halfspace"
kind = "halfspace"
[load]
total = {loads}
""")
    return path


# ---------------------------------------------------------------- contact area and nominal area
def test_contact_area_is_hertz_and_the_ratio_pi_over_16():
    # one paraboloid alone: contact radius a = sqrt(R d) (Hertz), so the area is pi R d; its
    # base at twice the approach has radius sqrt(2 R 2d) = 2 a, a box of side 4a: ratio pi/16
    import twoscale
    from twoscale.material import Material

    R, d, h = 10.0, 0.2, 0.05
    res = twoscale.solve(
        twoscale.asperities([0.0], [0.0], [R], shape="paraboloid"),
        material=Material(E=10.0, nu=0.5),
        penetration=d,
        h=h,
    )
    a = math.sqrt(R * d)
    # the loaded cells' area differs from the disc by about one cell along the perimeter
    assert res.contact_area == pytest.approx(math.pi * a * a, abs=2 * math.pi * a * h)
    assert res.nominal_area == pytest.approx(16 * a * a, rel=1e-9)
    assert res.contact_ratio == pytest.approx(math.pi / 16, rel=2 * h / a)
    assert res.body.label == "half-space" and res.nominal_area_basis == "tips' bases"


def test_nominal_area_is_cut_to_the_block_top_face():
    from twoscale.api import asperities
    from twoscale.material import Material
    from twoscale.scene import Scene

    tips = asperities([-20.0, 20.0], [0.0, 0.0], [6.0])  # spheres: bases of radius 6
    scene = Scene(material=Material(E=6.0, nu=0.5), asperities=tips, penetration=0.5)
    assert nominal_area(scene, Body())[0] == pytest.approx(52.0 * 12.0)
    block = Body(kind="block", size=(40.0, 60.0, 10.0), base="bonded", origin=(0.0, 0.0))
    area, basis = nominal_area(scene, block)
    assert area == pytest.approx(40.0 * 12.0) and "top face" in basis
    # origin: the scene's (0, 0) sits 5 mm right of the face's centre, so the face spans x in [-25, 15]
    area, _ = nominal_area(scene, Body(kind="block", size=(40.0, 60.0, 10.0), base="bonded", origin=(5.0, 0.0)))
    assert area == pytest.approx((15.0 - (-25.0)) * 12.0)


def test_body_labels():
    assert Body.of(HalfSpace.__new__(HalfSpace)).label == "half-space"
    assert Body(kind="block", size=(60.0, 60.0, 10.0), base="bonded").label == "block 60 x 60 x 10 mm, bonded base"


# ---------------------------------------------------------------- what solve prints and records
def test_solve_summary_leads_with_the_body_and_the_contact_area(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["solve", str(EXAMPLES / "S1.toml"), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "body         half-space" in text and "contact area" in text and "% of the nominal" in text
    assert "macro_krylov" not in text and "sensitivity_sweeps" not in text  # no internal names
    assert "alpha 0 rad, beta 0 rad" in text  # the symmetric scene's round-off tilt shows as 0
    res = json.loads((out / "result.json").read_text())
    assert res["body"] == {"kind": "halfspace", "label": "half-space"} and res["scene_name"] == "S1"
    assert res["contact_area_ratio"] == pytest.approx(res["contact_area"] / res["nominal_area"], rel=1e-12)
    assert abs(res["tilt"][0]) < 1e-8  # the number itself is kept


def test_help_texts_are_plain_text(capsys):
    from twoscale.cli.main import build_parser

    for argv in (["--help"], ["compare", "--help"], ["indicators", "--help"], ["solve", "--help"]):
        with pytest.raises(SystemExit):
            build_parser().parse_args(argv)
        assert "`" not in capsys.readouterr().out, argv


# ---------------------------------------------------------------- compare leads with the difference
def test_tip_changes_in_percent_of_the_tips_own_force():
    from twoscale import comparison
    from twoscale.results import AsperitySummary

    class Res:
        def __init__(self, forces):
            f = np.asarray(forces, float)
            self.asperities = AsperitySummary(f, f, f)

    class Sc:
        total_load, penetration = 50.0, None

    runs = [
        comparison.Run("50N", "halfspace", Sc, Res([1.0, 4.0, 5.0, 1e-4]), 0.0),
        comparison.Run("50N", "block", Sc, Res([1.1, 3.0, 5.0, 1e-3]), 0.0),
    ]
    rows = comparison.tip_changes(runs)
    assert [r["change_percent"] for r in rows] == pytest.approx([10.0, -25.0, 0.0, 900.0])
    # tip 4 barely touches (under 1 % of the largest force): not ranked
    assert [r["asperity"] for r in comparison.largest_changes(rows)] == [2, 1, 3]


def test_compare_terminal_is_compact_and_block_options_reach_the_body(tmp_path, monkeypatch, capsys):
    built = []

    def factory(material, **options):
        built.append(options)
        return HalfSpace(material)

    monkeypatch.setattr(compare, "_block_factory", lambda: (factory, ""))
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT)
    out = tmp_path / "cmp"
    assert (
        main(
            [
                "compare",
                str(scene),
                "--loads",
                "10",
                "20",
                "--block-size",
                "60",
                "50",
                "10",
                "--base",
                "bonded",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert [(o["size"], o["base"]) for o in built] == [((60.0, 50.0, 10.0), "bonded")]
    bodies = json.loads((out / "summary.json").read_text())["bodies"]
    assert list(bodies) == ["halfspace", "block-bonded"] and bodies["block-bonded"]["influence"]["size"] == [60, 50, 10]
    text = capsys.readouterr().out
    assert len(text.splitlines()) < 20 and "|---" not in text  # no Markdown table in the terminal
    assert "largest tip changes" in text and "changes.csv" in text and "e_M, e_m:" in text


@pytest.mark.parametrize(
    "extra, match", [(["--block-size", "60", "0", "10"], "--block-size"), (["--base", "glued"], "--base")]
)
def test_bad_block_options_exit_2(tmp_path, capsys, extra, match):
    scene = tmp_path / "small.toml"
    scene.write_text(THREE_SPHERES_TILT)
    out = tmp_path / "cmp"
    assert main(["compare", str(scene), "--out", str(out), "--quiet", *extra]) == 2
    assert match in capsys.readouterr().err and not out.exists()


# ---------------------------------------------------------------- notebooks
def test_result_table_view_and_full_pressure_map():
    import twoscale
    from twoscale.display import pressure_map_over
    from twoscale.io.scene_file import read_scene

    scene = read_scene(EXAMPLES / "S1.toml")
    res = twoscale.solve(scene)
    df = res.to_dataframe(scene)
    assert list(df.index) == list(range(1, 8)) and df["force_N"].sum() == pytest.approx(res.total_load, rel=1e-12)
    assert df.loc[2, "x_mm"] == 15.0
    html = res._repr_html_()
    assert "half-space" in html and "contact area" in html and html.count("<tr>") < 30
    P, extent = pressure_map_over(res)
    h = res.fields[0].grid.h
    assert P.sum() * h * h == pytest.approx(res.total_load, rel=1e-9)  # every patch once
    assert extent[1] - extent[0] == pytest.approx(P.shape[1] * h)


def test_progress_is_drawn_in_a_notebook(monkeypatch):
    from twoscale import progress

    monkeypatch.setattr(progress, "in_notebook", lambda: True)
    with progress.Progress(3, delay=0.0) as bar:
        assert bar.enabled
    with progress.Progress(3, quiet=True) as bar:
        assert not bar.enabled
    monkeypatch.undo()
    assert progress.in_notebook() is False  # pytest is no Jupyter kernel
