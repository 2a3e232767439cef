"""Ctrl-C (KeyboardInterrupt) in ``twoscale solve / compare / paper``: one line
``interrupted`` on stderr, exit code 130, and no output folder, whether the interrupt
comes during the solve or while the files are written."""

from __future__ import annotations

import os
import pathlib
import signal
import subprocess
import sys
import textwrap

import pytest

from twoscale.cli import compare as compare_cli
from twoscale.cli import compare_outputs
from twoscale.cli import solve as solve_cli
from twoscale.cli.main import EXIT_INTERRUPTED, main
from twoscale.cli.staging import held_interrupts, staged_directory


def _interrupt(*args, **kwargs):
    raise KeyboardInterrupt


def _only_interrupted(capsys) -> None:
    err = capsys.readouterr().err
    assert err.strip().splitlines() == ["interrupted"], err


def _nothing_but(tmp_path, *names) -> None:
    """Only ``names`` in tmp_path: no output folder, no hidden temporary folder."""
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(names)


def test_solve_interrupted_during_the_solve(scene, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(solve_cli, "solve_scene", _interrupt)
    code = main(["solve", str(scene), "--out", str(tmp_path / "out"), "--quiet"])
    assert code == EXIT_INTERRUPTED == 130
    _only_interrupted(capsys)
    _nothing_but(tmp_path, "scene.toml")


def test_solve_interrupted_while_writing(scene, tmp_path, monkeypatch, capsys):
    # result.json is already written (in the temporary folder) when the interrupt comes
    monkeypatch.setattr(solve_cli, "write_fields_and_figures", _interrupt)
    code = main(["solve", str(scene), "--out", str(tmp_path / "deep" / "out"), "--quiet"])
    assert code == 130
    _only_interrupted(capsys)
    _nothing_but(tmp_path, "scene.toml")  # nor the parent folder made for it


def test_solve_writes_whole_folder_when_not_interrupted(scene, tmp_path):
    out = tmp_path / "out"
    assert main(["solve", str(scene), "--out", str(out), "--quiet"]) == 0
    assert {"result.json", "fields.vtm", "pressure.png", "forces.png"} <= {p.name for p in out.iterdir()}
    _nothing_but(tmp_path, "scene.toml", "out")
    # a second run replaces the first one's files with --overwrite (tests/test_cli_output_folder.py)
    assert main(["solve", str(scene), "--out", str(out), "--quiet", "--overwrite"]) == 0
    _nothing_but(tmp_path, "scene.toml", "out")


def test_solve_out_naming_a_file_is_refused_before_solving(scene, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(solve_cli, "solve_scene", _interrupt)  # must not be reached
    (tmp_path / "taken").write_text("", encoding="utf-8")
    assert main(["solve", str(scene), "--out", str(tmp_path / "taken")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --out")


def test_compare_interrupted_during_the_solves(scene, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(compare_cli, "_solve_all", _interrupt)
    code = main(["compare", str(scene), "--out", str(tmp_path / "cmp"), "--quiet"])
    assert code == 130
    _only_interrupted(capsys)
    _nothing_but(tmp_path, "scene.toml")


def test_compare_interrupted_while_writing(scene, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(
        compare_cli, "_providers", lambda scene, quiet, base="both": ({"halfspace": scene.provider()}, [])
    )
    monkeypatch.setattr(compare_outputs, "write_result", _interrupt)  # after forces.csv, forces.md, figures
    code = main(["compare", str(scene), "--out", str(tmp_path / "cmp"), "--quiet"])
    assert code == 130
    _only_interrupted(capsys)
    _nothing_but(tmp_path, "scene.toml")


def test_paper_interrupted(tmp_path, monkeypatch, capsys):
    import twoscale.paper

    monkeypatch.setattr(twoscale.paper, "run_study", _interrupt)
    assert main(["paper", "--out", str(tmp_path / "paper"), "--quick", "--quiet"]) == 130
    _only_interrupted(capsys)
    _nothing_but(tmp_path)


def test_staged_directory_leaves_nothing_on_error(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        with staged_directory(tmp_path / "a" / "b") as tmp:
            (tmp / "x.txt").write_text("x", encoding="utf-8")
            (tmp / "sub").mkdir()
            raise KeyboardInterrupt
    _nothing_but(tmp_path)


def test_held_interrupts_raises_after_the_block():
    done = []
    with pytest.raises(KeyboardInterrupt):
        with held_interrupts():
            os.kill(os.getpid(), signal.SIGINT)
            done.append(True)  # reached: the interrupt waited for the block to end
    assert done == [True]


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_real_sigint_to_the_command(scene, tmp_path):
    # a real SIGINT to a running `twoscale solve` (its solve replaced by a long sleep)
    code = textwrap.dedent(f"""
        import sys, time
        import twoscale.cli.solve as s
        def slow(*args, **kwargs):
            print("solving", flush=True)
            time.sleep(60)
        s.solve_scene = slow
        from twoscale.cli.main import main
        sys.exit(main(["solve", {str(scene)!r}, "--out", {str(tmp_path / "out")!r}, "--quiet"]))
    """)
    # SIGINT at its default in the child, as in a terminal: a test run started in the
    # background (`pytest &` in a script) ignores SIGINT, its children inherit that, and
    # Python then installs no KeyboardInterrupt handler, so the signal would do nothing
    proc = subprocess.Popen(
        [sys.executable, "-c", code],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        assert proc.stdout.readline().strip() == "solving"
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130
    assert err.strip().splitlines() == ["interrupted"], err
    _nothing_but(tmp_path, "scene.toml")


_KICK_AT_IMPORT = """
import importlib.abc, os, signal, sys
sys.path.insert(0, {root!r})

class Kick(importlib.abc.MetaPathFinder):
    # a Ctrl-C while the package imports: SIGINT to this process when {module!r} is looked up
    def find_spec(self, name, path=None, target=None):
        if name == {module!r}:
            os.kill(os.getpid(), signal.SIGINT)
        return None

sys.meta_path.insert(0, Kick())
sys.argv = ["twoscale", "solve", {scene!r}, "--out", {out!r}]
from twoscale_command import main
sys.exit(main())
"""


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.parametrize("module", ["twoscale", "twoscale.cli.main", "twoscale.cli.solve"])
def test_ctrl_c_while_the_script_imports_is_one_line(scene, tmp_path, module):
    # the `twoscale` script's launcher holds SIGINT from its first line: before it, a Ctrl-C
    # while `import twoscale` ran gave a KeyboardInterrupt traceback, or was swallowed
    root = str(pathlib.Path(__file__).resolve().parents[1])
    code = _KICK_AT_IMPORT.format(root=root, module=module, scene=str(scene), out=str(tmp_path / "out"))
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # as in a terminal
    )
    assert proc.returncode == 130, proc.stderr
    assert proc.stderr.strip().splitlines() == ["interrupted"], proc.stderr
    _nothing_but(tmp_path, "scene.toml")


def test_the_script_is_the_launcher():
    # the console script must go through the launcher, or the guard above never runs
    pyproject = pathlib.Path(__file__).resolve().parents[1] / "pyproject.toml"
    assert 'twoscale = "twoscale_command:main"' in pyproject.read_text(encoding="utf-8")
