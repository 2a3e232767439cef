"""The repository speaks for itself, and its README says what the command line does.

* No tracked text file (code, tests, benchmarks, docs, README, examples, pyproject)
  points to an issue tracker by number: a reader has only the repository, so the text
  says what a figure or scene is, not which request asked for it.
* The README's synopses under "## Command line" (the code block for ``twoscale solve``
  and the ``twoscale COMMAND ...`` line opening each bullet) list exactly the options
  that ``twoscale COMMAND --help`` prints.
"""

from __future__ import annotations

import pathlib
import re
import subprocess

import pytest

from twoscale.cli.main import build_parser, main

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: A numbered reference to a tracker: the word issue (or issues) followed by a number,
#: with or without a hash, a hyphen or a slash between them, or GH- and a number (see
#: test_the_pattern_finds_tracker_references; examples there are built from parts so
#: that this file does not match itself).
TRACKER = re.compile(r"\bissues?\s*[-#]?\s*\d+|\bissues/\d+|\bGH-\d+", re.IGNORECASE)
#: Binary or generated files: not read.
BINARY = {
    ".png",
    ".jpg",
    ".npz",
    ".npy",
    ".vti",
    ".vtu",
    ".vtm",
    ".msh",
    ".x3p",
    ".parquet",
    ".pdf",
    ".gz",
    ".zip",
    ".pkl",
    ".sur",
    ".datx",
    ".opd",
    ".plu",
}


def tracked_text_files() -> list[pathlib.Path]:
    """The repository's tracked files (``git ls-files``; every file when git is absent)."""
    try:
        out = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
        names = [n for n in out.decode().split("\0") if n]
    except (OSError, subprocess.CalledProcessError):
        skip = {".git", ".venv", "_build", "__pycache__", ".pytest_cache", ".mypy_cache", ".ruff_cache"}
        names = [
            str(p.relative_to(ROOT))
            for p in ROOT.rglob("*")
            if p.is_file() and not skip & set(p.relative_to(ROOT).parts)
        ]
    return [ROOT / n for n in names if pathlib.Path(n).suffix.lower() not in BINARY and (ROOT / n).is_file()]


def test_the_pattern_finds_tracker_references():
    hits = [
        "see issue " + "12",
        "Issue #" + "4's target",
        "(issues " + "6, 14, 16)",
        "the issue-" + "6 layout",
        "github.com/x/y/issues/" + "3",
        "GH-" + "7",
    ]
    misses = ["a known issue with the mesh", "tissue 12", "issued 3 times"]
    assert all(TRACKER.search(s) for s in hits)
    assert not any(TRACKER.search(s) for s in misses)


def test_no_reference_to_an_issue_tracker():
    files = tracked_text_files()
    assert any(f.name == "README.md" for f in files) and any(f.suffix == ".py" for f in files)
    found = []
    for path in files:
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        for number, line in enumerate(text.splitlines(), start=1):
            if TRACKER.search(line):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()[:100]}")
    assert not found, "references to an issue tracker:\n" + "\n".join(found)


# ---------------------------------------------------------------- README synopses
def readme_synopses() -> dict[str, str]:
    """Subcommand -> its synopsis text from README.md's "## Command line" section."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("\n## Command line", 1)[1].split("\n## ", 1)[0]
    synopses: dict[str, str] = {}
    for block in re.findall(r"```\w*\n(.*?)```", section, re.S):  # the code block(s)
        for m in re.finditer(r"^twoscale (\w+)(.*?)(?=^twoscale |\Z)", block, re.S | re.M):
            synopses[m.group(1)] = m.group(2)
    for m in re.finditer(r"^- `twoscale (\w+)([^`]*)`", section, re.M):  # "- `twoscale CMD ...`: ..."
        synopses.setdefault(m.group(1), m.group(2))
    return synopses


def options_in(text: str) -> set[str]:
    return set(re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", text))


def help_options(command: str, capsys) -> set[str]:
    """The long options ``twoscale COMMAND --help`` prints in its option list."""
    assert main([command, "--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: twoscale {command}"), out[:200]
    listed = set(re.findall(r"^ {2}(?:-\w(?: \S+)?, )?(--[a-z][a-z0-9-]*)", out, re.M))
    return listed - {"--help"}


def subcommands() -> list[str]:
    parser = build_parser()
    return sorted(next(a for a in parser._actions if a.dest == "command").choices)


def test_options_are_read_from_help(capsys):
    """The reader of ``--help`` is not blind: it finds the options ``solve`` is known to have."""
    assert {"--method", "--out", "--h", "--overwrite", "--quiet"} <= help_options("solve", capsys)


def test_readme_has_a_synopsis_for_every_subcommand():
    assert set(readme_synopses()) == set(subcommands())


@pytest.mark.parametrize("command", subcommands())
def test_readme_synopsis_matches_help(command, capsys):
    documented = options_in(readme_synopses()[command])
    actual = help_options(command, capsys)
    assert not documented - actual, (
        f"README lists options `twoscale {command}` does not have: {sorted(documented - actual)}"
    )
    assert not actual - documented, (
        f"README's synopsis of `twoscale {command}` leaves out {sorted(actual - documented)}"
    )
