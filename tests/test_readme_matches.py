"""What the README shows matches what the program does.

The Python example is run as written (its first ``python`` block) and its output compared, line
by line, with the ``text`` block after it; wall times (a number before `` s``) differ from
run to run and machine to machine, and the force and the relative difference to the
reference differ in the last digits, so those are compared loosely.
"""

import contextlib
import io
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_SECONDS = re.compile(r"\d+(\.\d+)?(?= s\b)")
_SMALL = re.compile(r"\b\d\.\d+e-\d+\b")
_LONG = re.compile(r"\b\d+\.\d{7,}\b")


def _blocks(text: str, language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", text, flags=re.S)


def _loose(line: str) -> str:
    line = _SECONDS.sub("<t>", line)
    line = _SMALL.sub(lambda m: "<1e-6>" if float(m.group()) < 1e-6 else m.group(), line)
    return _LONG.sub(lambda m: f"{float(m.group()):.6g}", line)


def test_the_readme_python_example_prints_what_the_readme_shows():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    api = readme[readme.index("## Python API") :]
    code, shown = _blocks(api, "python")[0], _blocks(api, "text")[0]
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "README.md", "exec"), {"__name__": "readme"})
    printed = out.getvalue().strip().splitlines()
    assert [_loose(s) for s in printed] == [_loose(s) for s in shown.strip().splitlines()]


def test_the_readme_names_the_macro_steps_dense_limit_of_the_options():
    from twoscale.options import MacroOptions

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    row = next(line for line in readme.splitlines() if line.startswith("| `macro` |"))
    limit = int(re.search(r"up to ([\d,]+) asperities", row).group(1).replace(",", ""))
    assert limit == MacroOptions().dense_max


def test_the_set_up_lines_run_where_only_python3_is_on_the_path():
    """The README's set-up lines make the virtual environment with ``python3`` (many
    systems have no ``python`` outside one), and the CI script runs the second verbatim."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    setup = readme[readme.index("## Set-up") : readme.index("## Five-minute tour")]
    lines = [block.strip() for block in re.findall(r"```\n(.*?)```", setup, flags=re.S)]
    assert len(lines) == 2 and all(line.startswith("python3 -m venv .venv && ") for line in lines)
    assert lines[1] in (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
