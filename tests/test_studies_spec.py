"""Study files: validation (one line naming the bad value, exit 2, nothing written),
expansion into cases, footprints and case keys."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from helpers import paraboloid_scene
from twoscale.cli.main import main
from twoscale.studies.cases import case_scene, expand, kept_tips
from twoscale.studies.keys import case_key
from twoscale.studies.spec import StudyError, read_study

SCENE = paraboloid_scene([-10.0, 0.0, 10.0], [0.0, 0.0, 0.02])

STUDY = """
[[scene]]
file = "scene.toml"
[[body]]
name = "hs"
kind = "halfspace"
window = [22.0, 10.0]
[load]
penetration = [0.05, 0.1]
[positions]
start = [0.0, 0.0]
end = [5.0, 0.0]
step = 2.5
"""


@pytest.fixture
def study_file(tmp_path):
    (tmp_path / "scene.toml").write_text(SCENE, encoding="utf-8")

    def write(text: str = STUDY) -> str:
        path = tmp_path / "study.toml"
        path.write_text(text, encoding="utf-8")
        return str(path)

    return write


def test_expansion_counts_and_order(study_file):
    study = read_study(study_file())
    cases = expand(study)
    assert study.n_cases == len(cases) == 1 * 1 * 2 * 3
    assert [c.shift for c in cases[:3]] == [(0.0, 0.0), (2.5, 0.0), (5.0, 0.0)]
    assert [c.load for c in cases[::3]] == [("penetration", 0.05), ("penetration", 0.1)]


def test_footprint_keeps_the_tips_inside_the_window(study_file):
    # window |x| <= 11: tips at -10, 0, 10 shifted by 0, 2.5, 5 mm
    cases = expand(read_study(study_file()))
    assert [kept_tips(c).tolist() for c in cases[:3]] == [[0, 1, 2], [0, 1], [0, 1]]
    scene = case_scene(cases[1], read_study(study_file()))
    assert [(a.x, a.y) for a in scene.asperities] == [(-7.5, 0.0), (2.5, 0.0)]
    assert scene.penetration == 0.05 and scene.influence == {"kind": "halfspace"}


def test_block_footprint_defaults_to_the_top_face_less_the_edge(study_file):
    study = read_study(
        study_file(
            STUDY.replace(
                'kind = "halfspace"\nwindow = [22.0, 10.0]',
                'kind = "block"\nsize = [40.0, 40.0, 10.0]\norigin = [-5.0, 0.0]',
            )
        )
    )
    fp = study.bodies[0].footprint
    assert fp.size == (20.0, 20.0) and fp.centre == (5.0, 0.0)  # face centre at -origin: x in [-5, 15]
    assert [kept_tips(c).tolist() for c in expand(study)[:3]] == [[1, 2], [1, 2], [0, 1, 2]]


def test_case_keys_follow_inputs_not_names(study_file, tmp_path):
    study = read_study(study_file())
    keys = [case_key(c, study) for c in expand(study)]
    assert len(set(keys)) == len(keys)
    renamed = read_study(study_file(STUDY.replace('name = "hs"', 'name = "other"')))
    assert [case_key(c, renamed) for c in expand(renamed)] == keys
    (tmp_path / "scene.toml").write_text(SCENE.replace("E = 10.0", "E = 11.0"), encoding="utf-8")
    changed = read_study(study_file())
    assert not set(case_key(c, changed) for c in expand(changed)) & set(keys)


def test_a_case_without_tips_under_the_footprint_is_an_error_of_that_case(study_file):
    study = read_study(study_file(STUDY.replace("window = [22.0, 10.0]", "window = [2.0, 2.0]")))
    cases = expand(study)
    assert kept_tips(cases[2]).size == 0  # tip 1 moved 5 mm out of |x| <= 1
    with pytest.raises(ValueError, match="no tip lies in the footprint"):
        case_scene(cases[2], study)


BAD = [
    ("[study]\nmethod = 'fast'\n", "study.method", "'fast'"),
    ("[[body]]\nname = 'b'\nkind = 'block'\nbase = 'glued'\n", "body 2: base", "'glued'"),
    ("[[body]]\nname = 'hs'\nkind = 'halfspace'\n", "body 2: name", "'hs'"),
    ("[[body]]\nname = 'b'\nkind = 'halfspace'\nsize = [1, 2, 3]\n", "body 2: size", "[1, 2, 3]"),
    ("[solver]\ntol = -1\n", "solver.tol", "-1"),
    ("[solver]\niteration = 'newton'\n", "solver.iteration", "'newton'"),
    ("[sensor]\nnx = 0\n", "sensor.nx", "0"),
    ("[extra]\nx = 1\n", "extra", "{'x': 1}"),
]


@pytest.mark.parametrize("extra, where, value", BAD, ids=[b[1] for b in BAD])
def test_bad_study_exits_2_naming_the_value(study_file, tmp_path, capsys, extra, where, value):
    out = tmp_path / "out"
    assert main(["study", study_file(STUDY + extra), "--out", str(out), "--workers", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("error: ") and where in err and value in err, err
    assert not out.exists()


@pytest.mark.parametrize(
    "old, new, where",
    [
        ("penetration = [0.05, 0.1]", "penetration = [0.05, 0.05]", "load.penetration"),
        ("penetration = [0.05, 0.1]", "total = [0.0]", "load.total[0]"),
        ("step = 2.5", "step = 50.0", "positions.step"),
        ("end = [5.0, 0.0]", "", "positions.end"),
        ('file = "scene.toml"', 'file = "missing.toml"', "missing.toml"),
        ('kind = "halfspace"', 'kind = "rubber"', "body 1: kind"),
        ("window = [22.0, 10.0]", "window = [22.0, -1.0]", "body 1: window[1]"),
    ],
)
def test_bad_values_are_named(study_file, capsys, tmp_path, old, new, where):
    assert old in STUDY
    out = tmp_path / "out"
    assert main(["study", study_file(STUDY.replace(old, new)), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert where in err and len(err.strip().splitlines()) == 1, err
    assert not out.exists()


@pytest.mark.parametrize(
    "table, what",
    [
        ("[load]\ntotal = [[0.0, 0.0], [1.0, 5.0]]\n", "a load history"),
        (
            "[load]\ntotal = 5.0\n[rolling]\nstart = -1.0\nend = 1.0\nstep = 1.0\nspeed = 10.0\nfootprint = [40.0, 20.0]\n",
            "a [rolling] table",
        ),
    ],
)
def test_a_scene_with_a_history_or_rolling_is_refused_before_any_case(study_file, tmp_path, capsys, table, what):
    # a history's case failed with an AttributeError traceback in the warning line
    head, _, tips = SCENE.partition("[[asperity]]")
    head = head.split("[load]")[0]
    (tmp_path / "scene.toml").write_text(head + table + "[[asperity]]" + tips, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["study", study_file(STUDY.split("[load]")[0]), "--out", str(out), "--workers", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "scene 1: scene.toml" in err[0] and what in err[0] and "twoscale solve" in err[0]
    assert not out.exists()


def test_reference_method_refuses_twoscale_options(study_file):
    with pytest.raises(StudyError, match="solver.far_tol"):
        read_study(study_file("[study]\nmethod = 'reference'\n[solver]\nfar_tol = 0.1\n" + STUDY))


def test_bad_workers_and_missing_dependencies_exit_2(study_file, capsys, monkeypatch, tmp_path):
    out = tmp_path / "out"
    assert main(["study", study_file(), "--out", str(out), "--workers", "-1"]) == 2
    assert "--workers must be an integer >= 0, got '-1'" in capsys.readouterr().err
    assert main(["study", study_file(), "--out", str(out), "--batch", "0"]) == 2
    assert "--batch must be an integer >= 1, got '0'" in capsys.readouterr().err
    from twoscale.cli import study as cli_study

    monkeypatch.setattr(cli_study, "missing_dependencies", lambda: ["dask[distributed]"])
    assert main(["study", study_file(), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "pip install" in err and "dask[distributed]" in err
    assert not out.exists()


def test_core_imports_without_dask():
    # the study package reaches distributed only when a study runs on Dask
    import subprocess
    import sys

    code = (
        "import sys; sys.modules['distributed'] = None; sys.modules['pyarrow'] = None\n"
        "import twoscale.studies, twoscale.studies.execute, twoscale.scene, twoscale.cli.main\n"
        "print('ok')"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.stdout.strip() == "ok", proc.stderr


def test_track_positions_are_evenly_spaced_on_the_line(study_file):
    study = read_study(
        study_file(STUDY.replace("end = [5.0, 0.0]", "end = [3.0, 4.0]").replace("step = 2.5", "step = 2.0"))
    )
    P = np.array(study.positions)
    assert study.track and len(P) == 3
    np.testing.assert_allclose(np.hypot(*np.diff(P, axis=0).T), 2.0)
    np.testing.assert_allclose(P[-1], [2.4, 3.2])  # 4 mm along the 5 mm line
    assert dataclasses.is_dataclass(study)


def test_without_load_each_scene_runs_its_own_cases(tmp_path, examples_dir):
    # S2.toml lists load cases 200, 250 and 300 N under a tilting joint
    text = (
        f'[[scene]]\nfile = "{(examples_dir / "S2.toml").as_posix()}"\n'
        '[[body]]\nname = "hs"\nkind = "halfspace"\n[load]\ntilt = false\n'
    )
    (tmp_path / "s.toml").write_text(text, encoding="utf-8")
    study = read_study(tmp_path / "s.toml")
    cases = expand(study)
    assert [c.load for c in cases] == [("total", 200.0), ("total", 250.0), ("total", 300.0)]
    scene = case_scene(cases[1], study)
    assert (scene.total_load, scene.tilt, scene.load_cases, len(scene.asperities)) == (250.0, False, (), 25)
    assert scene.h == 0.1  # the scene's own cell size


def test_the_example_study_is_valid(examples_dir):
    study = read_study(examples_dir / "study.toml")
    assert study.n_cases == 12 >= 8
    assert [b.influence["kind"] for b in study.bodies] == ["halfspace", "block"]
    assert all(kept_tips(c).size == 25 for c in expand(study))  # every tip stays under both footprints
