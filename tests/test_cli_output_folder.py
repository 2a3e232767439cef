"""Output folders of ``solve / compare / paper``: a non-empty folder is refused (exit 2, one
line, nothing written, before any solve) unless ``--overwrite``, which removes exactly the
files the earlier run listed in its manifest; a folder holding other files is never cleared."""

from __future__ import annotations

import json

import pytest

from twoscale.cli import compare as compare_cli
from twoscale.cli import solve as solve_cli
from twoscale.cli.main import main
from twoscale.cli.staging import MANIFEST_NAME, OutputFolderError, check_output_folder, staged_directory
from twoscale.influence.halfspace import HalfSpace


def _never(*args, **kwargs):
    raise AssertionError("the solve ran although the output folder was refused")


def _tree(folder):
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*"))


def _one_error_line(capsys, *words):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    for w in words:
        assert w in err[0], err[0]


# ---------------------------------------------------------------- staging itself
def test_manifest_lists_exactly_the_files_written(tmp_path):
    with staged_directory(tmp_path / "run", command="test") as tmp:
        (tmp / "a.txt").write_text("a")
        (tmp / "sub" / "deep").mkdir(parents=True)
        (tmp / "sub" / "deep" / "b.txt").write_text("b")
    m = json.loads((tmp_path / "run" / MANIFEST_NAME).read_text())
    assert m["program"] == "twoscale" and m["command"] == "test"
    assert m["files"] == ["a.txt", "sub/deep/b.txt"]


def test_empty_folder_accepted_and_file_refused(tmp_path):
    (tmp_path / "empty").mkdir()
    check_output_folder(tmp_path / "empty")
    check_output_folder(tmp_path / "missing")
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputFolderError, match="existing file"):
        check_output_folder(tmp_path / "f", overwrite=True)


def test_overwrite_removes_only_the_manifest_files(tmp_path):
    out = tmp_path / "run"
    with staged_directory(out) as tmp:
        (tmp / "old.txt").write_text("old")
        (tmp / "runs" / "x_100N").mkdir(parents=True)
        (tmp / "runs" / "x_100N" / "r.json").write_text("{}")
    with pytest.raises(OutputFolderError, match="--overwrite"):
        check_output_folder(out)
    with staged_directory(out, overwrite=True) as tmp:
        (tmp / "new.txt").write_text("new")
    # the earlier run's files and the folders they alone filled are gone
    assert _tree(out) == [MANIFEST_NAME, "new.txt"]


def test_foreign_files_are_never_removed(tmp_path):
    out = tmp_path / "run"
    with staged_directory(out) as tmp:
        (tmp / "old.txt").write_text("old")
    (out / "notes.txt").write_text("mine")
    (out / "mine").mkdir()
    before = _tree(out)
    with pytest.raises(OutputFolderError, match="did not write"):
        with staged_directory(out, overwrite=True) as tmp:
            (tmp / "new.txt").write_text("new")
    assert _tree(out) == before
    # a non-empty folder without a manifest is refused even with overwrite
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "data.csv").write_text("1")
    with pytest.raises(OutputFolderError, match="not written by twoscale"):
        check_output_folder(tmp_path / "other", overwrite=True)


def test_folder_changed_during_the_run_is_left_alone(tmp_path):
    out = tmp_path / "run"
    with pytest.raises(OutputFolderError):
        with staged_directory(out) as tmp:
            (tmp / "new.txt").write_text("new")
            out.mkdir()
            (out / "appeared.txt").write_text("x")
    assert _tree(out) == ["appeared.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # no temporary folder left


# ---------------------------------------------------------------- the commands
def test_solve_refuses_a_non_empty_folder_before_solving(scene, tmp_path, monkeypatch, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "data.csv").write_text("1")
    monkeypatch.setattr(solve_cli, "solve_scene", _never)
    for extra in ([], ["--overwrite"]):
        assert main(["solve", str(scene), "--out", str(out), *extra]) == 2
        _one_error_line(capsys, "--out", "not written by twoscale")
        assert _tree(out) == ["data.csv"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "scene.toml"]


def test_solve_out_naming_a_file_exits_2_before_solving(scene, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(solve_cli, "solve_scene", _never)
    (tmp_path / "taken").write_text("keep")
    assert main(["solve", str(scene), "--out", str(tmp_path / "taken"), "--overwrite"]) == 2
    _one_error_line(capsys, "--out", "existing file")
    assert (tmp_path / "taken").read_text() == "keep"


def test_solve_twice_needs_overwrite(scene, tmp_path, monkeypatch, capsys):
    out = tmp_path / "out"
    assert main(["solve", str(scene), "--out", str(out), "--quiet"]) == 0
    first = _tree(out)
    assert "result.json" in first and "fields/patch_001.vti" in first
    listed = json.loads((out / MANIFEST_NAME).read_text())["files"]
    assert sorted(listed + [MANIFEST_NAME]) == sorted(p for p in first if (out / p).is_file())
    real_solve = solve_cli.solve_scene
    monkeypatch.setattr(solve_cli, "solve_scene", _never)
    assert main(["solve", str(scene), "--out", str(out), "--quiet"]) == 2
    _one_error_line(capsys, "--overwrite")
    monkeypatch.setattr(solve_cli, "solve_scene", real_solve)
    assert main(["solve", str(scene), "--out", str(out), "--quiet", "--overwrite"]) == 0
    assert _tree(out) == first


def test_compare_overwrite_removes_stale_load_files(scene, tmp_path, monkeypatch, capsys):
    # the reported case: a run at 100 N, then one at 50 N into the same folder left
    # forces_100N.png and runs/*_100N beside a forces.md that no longer listed them
    monkeypatch.setattr(compare_cli, "_block_factory", lambda: ((lambda material, **kw: HalfSpace(material)), ""))
    out = tmp_path / "cmp"
    assert main(["compare", str(scene), "--out", str(out), "--loads", "5", "--quiet"]) == 0
    assert (out / "forces_5N.png").exists() and (out / "runs" / "halfspace_5N").is_dir()
    monkeypatch.setattr(compare_cli, "_solve_all", _never)
    assert main(["compare", str(scene), "--out", str(out), "--loads", "4", "--quiet"]) == 2
    _one_error_line(capsys, "--overwrite")
    monkeypatch.undo()
    monkeypatch.setattr(compare_cli, "_block_factory", lambda: ((lambda material, **kw: HalfSpace(material)), ""))
    assert main(["compare", str(scene), "--out", str(out), "--loads", "4", "--quiet", "--overwrite"]) == 0
    names = _tree(out)
    assert "forces_4N.png" in names and "runs/halfspace_4N/result.json" in names
    assert not any("5N" in n for n in names)


def test_compare_and_paper_refuse_a_file_before_solving(scene, tmp_path, monkeypatch, capsys):
    import twoscale.paper

    (tmp_path / "taken").write_text("keep")
    monkeypatch.setattr(compare_cli, "_solve_all", _never)
    assert main(["compare", str(scene), "--out", str(tmp_path / "taken")]) == 2
    _one_error_line(capsys, "--out", "existing file")
    monkeypatch.setattr(twoscale.paper, "run_study", _never)
    assert main(["paper", "--quick", "--out", str(tmp_path / "taken")]) == 2
    _one_error_line(capsys, "--out", "existing file")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("")
    assert main(["paper", "--quick", "--out", str(tmp_path / "full"), "--overwrite"]) == 2
    _one_error_line(capsys, "--out", "not written by twoscale")
    assert (tmp_path / "taken").read_text() == "keep"
