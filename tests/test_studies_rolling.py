"""Rolling studies: road sections x bodies x materials x loads x speeds, each case the
rolling run's own files in its folder; the numbers equal direct rolling runs; a study
stopped part-way resumes with only the unfinished cases; bad input is one line, exit 2.

The study: a seeded chip-seal strip (50 x 14 mm at 0.25 mm) under a slick tyre's face
(R 150 mm, a 24 x 12 mm footprint) at a held approach of 0.9 mm, three positions 1 mm
apart, an elastic and a viscoelastic tread (one branch, tau 2 ms), two speeds.
"""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np
import pytest

from twoscale import Material
from twoscale.cli.main import main
from twoscale.rolling import RollingSpec, road_strip, roll
from twoscale.scene import Scene
from twoscale.studies import rolling_run
from twoscale.studies.rolling_cases import case_key, expand
from twoscale.studies.rolling_run import run_rolling_study
from twoscale.studies.rolling_tables import write_rolling_outputs
from twoscale.studies.spec import read_study
from twoscale.studies.store import CaseStore
from twoscale.surface import RawMap, SurfaceOptions, build_surface

STUDY = """
[study]
name = "tiny road"
figures = false

[[section]]
name = "chip"
generate = { length = 50.0, width = 14.0, h = 0.25, seed = 7 }
surface = { min_distance = 2.0, prominence = 0.1 }

[[body]]
name = "slick"
kind = "halfspace"
tyre_radius = 150.0
footprint = [24.0, 12.0]

[[material]]
name = "rubber"
E = 10.0
nu = 0.5

[[material]]
name = "tread"
E = 10.0
nu = 0.5
prony = [[40.0, 2e-3]]

[rolling]
start = -3.0
end = -1.0
step = 1.0
speeds = [1.8, 50.0]

[load]
penetration = [0.9]
"""


@pytest.fixture
def study_file(tmp_path):
    path = tmp_path / "study.toml"
    path.write_text(STUDY, encoding="utf-8")
    return path


def _direct(material: Material, speed: float):
    """The case rolled by hand: the strip built from its seed, the scene from its parts."""
    strip = build_surface(
        RawMap(road_strip(50.0, 14.0, 0.25, seed=7), spacing=0.25, units="mm"),
        SurfaceOptions(min_distance=2.0, prominence=0.1),
    )
    spec = RollingSpec(start=-3.0, end=-1.0, step=1.0, speed=speed, tyre_radius=150.0, footprint=(24.0, 12.0))
    return roll(Scene(material=material, surface=strip, penetration=0.9, rolling=spec))


def _signals(folder):
    import pandas as pd

    return pd.read_csv(folder / "signals.csv")


def test_cases_equal_direct_rolling_runs_and_resume(study_file, tmp_path, monkeypatch):
    """Stopped after the first solve (Ctrl-C), the study keeps that solve's cases (the elastic
    tread's two speeds: one roll); rerun, it solves only the others; every case's files equal
    a direct rolling run of the case, and the tables open in pandas."""
    import pandas as pd

    study = read_study(study_file)
    out = tmp_path / "out"
    real, calls = rolling_run.solve_group, []

    def stopped(study_, group, strips, providers):
        if calls:
            raise KeyboardInterrupt
        calls.append([key for _, key in group])
        return real(study_, group, strips, providers)

    monkeypatch.setattr(rolling_run, "solve_group", stopped)
    with pytest.raises(KeyboardInterrupt):
        run_rolling_study(study, out, quiet=True)
    store = CaseStore(out)
    keys = [case_key(c, study) for c in expand(study)]
    assert [k for k in keys if store.finished(k)] == calls[0] == keys[:2]  # elastic, both speeds
    stamps = {k: os.stat(store.path(k) / "case.json").st_mtime_ns for k in keys[:2]}
    (store.folder / f".{keys[0]}.tmp-left").mkdir()  # what a killed write leaves
    monkeypatch.setattr(rolling_run, "solve_group", real)
    run = run_rolling_study(study, out, quiet=True)
    assert (run.ran, run.skipped) == (2, 2)
    assert {k: os.stat(store.path(k) / "case.json").st_mtime_ns for k in keys[:2]} == stamps
    assert not any(p.name.startswith(".") for p in store.folder.iterdir())
    assert run_rolling_study(study, out, quiet=True).ran == 0

    summary = write_rolling_outputs(out, study, run)
    assert summary["counts"]["converged"] == 4
    table = pd.read_csv(out / "cases.csv")
    for case, key in zip(expand(study), keys):
        direct = _direct(case.material.material, case.speed)
        got = _signals(store.path(key))
        assert list(got.columns) == [
            "time_s",
            "shift_mm",
            "total_load_N",
            "penetration_mm",
            "contact_area_mm2",
            "drag_N",
        ]
        np.testing.assert_allclose(got["shift_mm"], direct.shifts)
        np.testing.assert_allclose(got["time_s"], direct.times, rtol=1e-12)
        np.testing.assert_allclose(got["total_load_N"], direct.total_load, rtol=1e-9)
        np.testing.assert_allclose(got["drag_N"], direct.drag, rtol=1e-9, atol=1e-12)
        row = table[table.key == key].iloc[0]
        assert row.mean_drag_N == pytest.approx(direct.mean_drag, rel=1e-9)
        assert row.load_rms_N == pytest.approx(float(np.std(direct.total_load)), rel=1e-9)
        assert bool(row.viscoelastic) == case.material.material.viscoelastic
        record = json.loads((store.path(key) / "rolling.json").read_text())
        assert record["speed_kmh"] == case.speed
        for name in ("asperity_signals.csv", "texture.json", "case.json"):
            assert (store.path(key) / name).is_file()
    # the slow tread drags more than the elastic one at the same speed; its energy is there
    visco = table[table.material == "tread"]
    assert np.all(visco.dissipated_per_mm_N > 0) and table.dissipated_per_mm_N.isna().sum() == 2
    assert float(visco[visco.speed_kmh == 1.8].mean_drag_N.iloc[0]) > 2.0 * float(
        table[(table.material == "rubber") & (table.speed_kmh == 1.8)].mean_drag_N.iloc[0]
    )


@pytest.mark.slow
def test_cli_runs_on_two_workers_and_lists_bands(study_file, tmp_path, capsys):
    """``twoscale study`` on a local Dask cluster; a longer run resolves third-octave bands,
    one row per case and band in bands.csv, each case's the levels of its own force signal (one
    roll serves the elastic tread's two speeds: the faster's bands lie higher)."""
    import pandas as pd

    text = (
        STUDY.replace('name = "tread"', 'name = "tread"\n# one material only')
        .replace("end = -1.0", "end = 12.0")
        .replace("step = 1.0", "step = 0.25")
    )  # 61 positions
    text = text[: text.index('[[material]]\nname = "tread"')] + text[text.index("[rolling]") :]
    path = tmp_path / "s.toml"
    path.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["study", str(path), "--out", str(out), "--workers", "2", "--quiet"]) == 0
    bands = pd.read_csv(out / "bands.csv")
    assert set(bands.columns) >= {"section", "speed_kmh", "signal", "band_Hz", "level_dB"}
    assert set(bands.signal) == {"total_load_N"}
    from twoscale.rolling.bands import third_octave_levels

    for speed in (1.8, 50.0):  # each case's levels are those of its own force signal and time step
        mine = bands[bands.speed_kmh == speed].sort_values("band_Hz")
        signals = _signals(out / "cases" / mine.key.iloc[0])
        levels = third_octave_levels(signals.total_load_N.to_numpy(), 0.25 / (speed / 3.6e-3))
        np.testing.assert_allclose(mine.band_Hz, levels.nominal)
        np.testing.assert_allclose(mine.level_dB, levels.columns()["level_dB"], atol=1e-8)  # CSV: 10 digits
    assert bands[bands.speed_kmh == 50.0].band_Hz.min() > bands[bands.speed_kmh == 1.8].band_Hz.max()


@pytest.mark.parametrize(
    "change, words",
    [
        (("speeds = [1.8, 50.0]", "speeds = [0.0]"), "rolling.speeds[0] must be > 0"),
        (("end = -1.0", "end = -4.0"), "rolling.end must not be before"),
        (
            ('kind = "halfspace"\ntyre_radius = 150.0\nfootprint = [24.0, 12.0]', 'kind = "halfspace"'),
            "body 1: a flat face on the half-space needs a footprint",
        ),
        (("seed = 7 }", "seed = 7 }\nseeds = [1, 2]"), "generate.seed or seeds"),
        (("E = 10.0\nnu = 0.5\nprony", "E = -1.0\nnu = 0.5\nprony"), "material 2: material.E must be"),
        (("speeds = [1.8, 50.0]", "speed = [1.8, 50.0]"), "a list goes in rolling.speeds"),
        (("[load]", '[[scene]]\nfile = "S2.toml"\n\n[load]'), "scene is a static study's table"),
        (("[rolling]\nstart = -3.0\nend = -1.0\nstep = 1.0\nspeeds = [1.8, 50.0]\n", ""), "no [rolling] table"),
    ],
)
def test_bad_input_is_one_line_and_nothing_written(study_file, tmp_path, capsys, change, words):
    path = tmp_path / "bad.toml"
    path.write_text(STUDY.replace(*change), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["study", str(path), "--out", str(out), "--workers", "0", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and words in err and not out.exists()


def test_offsets_and_seeds_make_sections(tmp_path):
    text = STUDY.replace(", seed = 7 }", " }\nseeds = [3, 4]\noffsets = [0.0, 5.0]")
    path = tmp_path / "s.toml"
    path.write_text(text, encoding="utf-8")
    study = read_study(path)
    assert [s.name for s in study.sections] == ["chip-s3@0mm", "chip-s3@5mm", "chip-s4@0mm", "chip-s4@5mm"]
    assert study.n_cases == 4 * 2 * 2
    cases = expand(study)
    from twoscale.studies.rolling_cases import rolling_spec, solve_key

    spec = rolling_spec(cases[4], study)  # the second section: 5 mm further along the strip
    assert (spec.start, spec.end) == (-8.0, -6.0)
    elastic = [c for c in cases if not c.viscoelastic]
    assert len({solve_key(c, study) for c in elastic}) == len(elastic) // 2  # the speeds share a roll
    visco = [c for c in cases if c.viscoelastic]
    assert len({solve_key(c, study) for c in visco}) == len(visco)
    assert dataclasses.replace(study, figures=True).figures


def test_strip_file_sections_are_keyed_by_the_files_content(tmp_path):
    """A section read from a strip file: its key follows the file's bytes, not its name; the
    shipped example study reads."""
    from pathlib import Path

    heights = road_strip(50.0, 14.0, 0.25, seed=7)
    np.save(tmp_path / "strip.npy", heights)
    text = STUDY.replace(
        "generate = { length = 50.0, width = 14.0, h = 0.25, seed = 7 }\n"
        "surface = { min_distance = 2.0, prominence = 0.1 }",
        'surface = { file = "strip.npy", spacing = 0.25, min_distance = 2.0 }\noffsets = [0.0, 4.0]',
    )
    path = tmp_path / "s.toml"
    path.write_text(text, encoding="utf-8")
    keys = [case_key(c, read_study(path)) for c in expand(read_study(path))]
    assert len(set(keys)) == len(keys) == 2 * 2 * 2
    np.save(tmp_path / "strip.npy", heights[:, ::-1])
    assert not set(keys) & {case_key(c, read_study(path)) for c in expand(read_study(path))}
    example = read_study(Path(__file__).resolve().parents[1] / "examples" / "rolling" / "study.toml")
    assert example.n_cases == 8 and [s.name for s in example.sections] == ["example@0mm", "example@30mm"]


def test_a_local_workers_warnings_are_one_line_each(study_file, tmp_path):
    """The slow tread's coarse step warns in the worker that rolls it: on the local cluster
    that line reads as the command's own (``warning: ...``), not Python's default with the
    library's source file, line number and code."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": str(root)}
    command = [sys.executable, "-m", "twoscale", "study", str(study_file), "--out", str(tmp_path / "out")]
    proc = subprocess.run(command + ["--workers", "1", "--quiet"], capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.splitlines()
    assert any("coarser than" in line for line in lines), proc.stderr
    assert all(line.startswith("warning: ") for line in lines), proc.stderr


def test_an_empty_bands_table_is_explained(study_file, tmp_path, capsys):
    """Runs of 2 mm resolve no third-octave band (3 bins, 1 / duration apart): bands.csv has
    its header only, and the summary says why rather than leaving an empty table unexplained."""
    import pandas as pd

    text = study_file.read_text().replace("prony = [[40.0, 2e-3]]", "")  # elastic only: one quick roll
    study_file.write_text(text.replace('name = "tread"', 'name = "tread2"'), encoding="utf-8")
    out = tmp_path / "out"
    assert main(["study", str(study_file), "--out", str(out), "--workers", "0"]) == 0
    assert len(pd.read_csv(out / "bands.csv")) == 0
    said = [line for line in capsys.readouterr().out.splitlines() if line.startswith("bands.csv has no rows")]
    assert len(said) == 1 and "longest run 2 mm" in said[0]


def test_case_json_and_rolling_json_list_the_cases_warnings(study_file, tmp_path):
    """A case rolled with a coarse step (its ``step_check`` says so) lists the StepWarning
    with that message, without the case's label the stderr line leads with, in ``case.json``
    and in its ``rolling.json``; a case whose step is fine lists no StepWarning."""
    study = read_study(study_file)
    out = tmp_path / "out"
    run = run_rolling_study(study, out, quiet=True)
    store = CaseStore(out)
    coarse = 0
    for key in run.keys:
        check = json.loads((store.path(key) / "rolling.json").read_text()).get("step_check") or {}
        listed = store.read(key)["warnings"]
        assert json.loads((store.path(key) / "rolling.json").read_text())["warnings"] == listed
        steps = [w for w in listed if w["category"] == "StepWarning"]
        if check.get("coarse"):
            coarse += 1
            assert steps == [{"category": "StepWarning", "message": check["message"], "count": 1}]
        else:
            assert steps == []
    assert coarse >= 1


def test_an_offset_off_the_strip_names_the_offset_and_the_offsets_that_fit(study_file, tmp_path):
    """A section offset that moves the run off the strip fails its case with a reason naming
    the offset and its value (not the moved ``rolling.start``, which the user never wrote),
    and the offsets that fit: one just inside that range rolls, one just beyond fails."""
    import re

    text = study_file.read_text().replace("prony = [[40.0, 2e-3]]", "").replace('name = "tread"', 'name = "tread2"')
    text = text.replace("speeds = [1.8, 50.0]", "speeds = [50.0]")

    def outcome(offset: float) -> tuple:
        path = tmp_path / f"s{offset:g}.toml"
        path.write_text(text.replace(", seed = 7 }", f", seed = 7 }}\noffsets = [{offset!r}]"), encoding="utf-8")
        study = read_study(path)
        out = tmp_path / f"out{offset:g}"
        run = run_rolling_study(study, out, quiet=True)
        record = CaseStore(out).read(run.keys[0])
        return record["status"], record["reason"]

    status, reason = outcome(40.0)
    assert status == "failed" and reason.count("\n") == 0
    assert "section chip@40mm: offsets value 40 mm" in reason and "rolling.start" not in reason
    lo, hi = (float(v) for v in re.search(r"offsets from (\S+) to (\S+) mm fit", reason).groups())
    assert lo < 0.0 < hi < 40.0
    assert outcome(hi - 0.5)[0] == "converged"
    assert outcome(hi + 0.5)[0] == "failed"
