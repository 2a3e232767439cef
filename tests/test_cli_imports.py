"""The command line imports only what the command it runs needs: ``twoscale --help`` lists
every subcommand from a table, without importing their modules (``solve``'s pulls in scipy,
0.6 s of CPU), a subcommand's line in that list is its module's own summary, and a command's own
``--help`` needs neither scipy nor matplotlib."""

from __future__ import annotations

import importlib
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from twoscale.cli.main import SUBCOMMANDS, build_parser, command_in, plain

ROOT = Path(__file__).resolve().parents[1]

CHILD = textwrap.dedent(
    """
    import contextlib, io, sys
    sys.path.insert(0, {root!r})
    from twoscale.cli.main import main
    with contextlib.redirect_stdout(io.StringIO()):
        code = main({argv!r})
    loaded = sorted(m for m in sys.modules if m.split(".")[0] in ("scipy", "matplotlib", "skfem")
                    or m.startswith("twoscale.cli.") and m not in ("twoscale.cli.main", "twoscale.cli.staging"))
    print(code, ",".join(loaded))
    """
)


def _loaded_by(argv: list[str]) -> tuple[int, list[str]]:
    code = CHILD.format(root=str(ROOT), argv=argv)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    status, _, names = out.stdout.strip().splitlines()[-1].partition(" ")
    return int(status), [n for n in names.split(",") if n]


@pytest.mark.parametrize("argv", [["--help"], ["--version"], []])
def test_top_level_help_imports_no_subcommand(argv):
    status, loaded = _loaded_by(argv)
    assert status == (2 if not argv else 0)
    assert loaded == [], loaded


@pytest.mark.parametrize("command", ["solve", "surface", "indicators", "paper", "study"])
def test_a_commands_help_imports_no_scipy_nor_matplotlib(command):
    # solve's took 0.8 s of CPU: --iteration's choices from micro.policy (the driver, scipy),
    # the memory check and the summary's route text at the top of the module
    status, loaded = _loaded_by([command, "--help"])
    assert status == 0
    assert not [m for m in loaded if not m.startswith("twoscale.")], loaded


def test_a_subcommand_imports_its_own_module_only():
    status, loaded = _loaded_by(["cache", "--help"])
    assert status == 0
    assert loaded == ["twoscale.cli.cache"], loaded


@pytest.mark.parametrize("name, module, required, summary", SUBCOMMANDS)
def test_listed_summary_is_the_modules_own(name, module, required, summary):
    if not required and importlib.util.find_spec(module) is None:
        pytest.skip(f"{module} absent")
    doc = importlib.import_module(module).__doc__
    assert summary == plain(doc.strip().splitlines()[0])


def test_command_is_the_first_word_that_is_not_an_option():
    assert command_in(["--version"]) is None
    assert command_in(["solve", "--out", "x"]) == "solve"
    assert command_in(["-h", "cache", "list"]) == "cache"


def test_the_full_parser_still_knows_every_option():
    """``build_parser()`` (the documentation's and the tests' parser) has every command's options."""
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    solve = sub.choices["solve"]
    assert any("--method" in a.option_strings for a in solve._actions)
    bare = next(a for a in build_parser(None)._actions if a.dest == "command").choices["solve"]
    assert not any("--method" in a.option_strings for a in bare._actions)
