"""The documentation: the gallery covers every figure the program writes, the guides speak
for themselves, and the Sphinx site builds with warnings as errors (slow: it runs the
examples)."""

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _gallery():
    spec = importlib.util.spec_from_file_location("make_gallery", DOCS / "gallery" / "make_gallery.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_gallery_shows_every_figure_the_program_writes():
    from twoscale.cli.surface import NAMES
    from twoscale.io.solve_outputs import FORCES_NAME, PRESSURE_NAME

    shown = {Path(name).name for *_, figures in _gallery().RUNS for name, _ in figures}
    # solve (spheres and a height map), surface, compare, study, paper; a history and a rolling run
    expected = {
        PRESSURE_NAME,
        FORCES_NAME,
        NAMES[0],
        "forces_50N.png",
        "maps_50N.png",
        "sensor_50N.png",
        "difference_50N.png",
        "load_approach_S2.png",
        "asperity_forces_S2_block.png",
        "track_S2_block.png",
        "indicators_S2.png",
        "fig3_two_maps.png",
        "fig4_seven_maps.png",
        "fig5_profiles.png",
        "fig6_errors.png",
        "history.png",
        "signals.png",
        "bands.png",
        "space_time.png",
    }
    assert shown == expected
    index = (DOCS / "gallery" / "index.md").read_text(encoding="utf-8")
    linked = re.findall(r"\]\((img/[^)]+\.png)\)", index)
    assert len(linked) == sum(len(f) for *_, f in _gallery().RUNS)
    for rel in linked:  # every picture the page shows is in the repository
        assert (DOCS / "gallery" / rel).stat().st_size > 10_000
    assert (DOCS / "img" / "tour_pressure.png").exists()


def test_every_guide_is_in_the_site():
    index = (DOCS / "index.md").read_text(encoding="utf-8") + (DOCS / "records" / "index.md").read_text(
        encoding="utf-8"
    )
    for page in DOCS.glob("*.md"):
        if page.stem not in ("index",):
            assert re.search(rf"^{re.escape(page.stem)}$", index, re.MULTILINE), (
                f"{page.name} is in no table of contents"
            )


@pytest.mark.slow
def test_the_site_builds_with_warnings_as_errors(tmp_path):
    pytest.importorskip("sphinx")
    pytest.importorskip("myst_parser")
    pytest.importorskip("sphinx_gallery")
    out = tmp_path / "html"
    done = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "-q", "-b", "html", str(DOCS), str(out)],
        capture_output=True,
        text=True,
        check=False,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    assert done.returncode == 0, done.stderr[-3000:]
    plot = (out / "reference" / "plot.html").read_text(encoding="utf-8")
    assert "plot_pressure_map" in plot and "robust_scale" in plot  # the API reference from docstrings
    example = (out / "auto_examples" / "plot_seven_spheres.html").read_text(encoding="utf-8")
    assert "sphx_glr_plot_seven_spheres_001.png" in example  # the example ran and drew
    assert (out / "_images" / "sphx_glr_plot_seven_spheres_001.png").stat().st_size > 10_000


def test_the_design_layout_names_every_module_and_package():
    """docs/DESIGN.md's layout table names every top-level module and package of twoscale."""
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    text = (root / "docs" / "DESIGN.md").read_text()
    layout = text.split("## Layout", 1)[1].split("\n## ", 1)[0]
    named = set(re.findall(r"`twoscale/([A-Za-z_]+)(?:\.py|/)`", layout))
    package = root / "twoscale"
    have = {p.stem for p in package.glob("*.py") if not p.name.startswith("_")} | {
        p.name for p in package.iterdir() if p.is_dir() and (p / "__init__.py").exists()
    }
    assert have <= named, f"missing from docs/DESIGN.md's layout: {sorted(have - named)}"


# the files a guide tells the reader to write themselves, and placeholders (SCENE.toml)
_OWN_FILES = {"scene.toml"}


def _doc_commands() -> list[tuple[str, str]]:
    """``(file, command)`` for every ``twoscale`` / ``pip install`` line the README and the
    guides show, inline in backticks or on a line of a code block."""
    found = []
    for path in [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]:
        for line in path.read_text().splitlines():
            inline = re.findall(r"`((?:twoscale|pip install) [^`]+)`", line)
            block = [line.strip()] if re.match(r"\s*(twoscale|pip install) ", line) else []
            found += [(path.name, c) for c in inline + block]
    return found


def test_every_command_the_docs_show_names_files_of_the_repository():
    """A command copied from a guide runs from a clone: the scene or study file it names
    exists (relative to the repository), and an extra is installed from the repository
    (``pip install ".[study]"``), not asked of the package index by name."""
    missing, indexed = [], []
    for name, command in _doc_commands():
        words = command.split()
        if words[0] == "pip":
            indexed += [(name, command) for w in words[2:] if w.strip("\"'").startswith("twoscale")]
            continue
        if len(words) < 3 or words[1] not in ("solve", "compare", "surface", "study"):
            continue
        arg = words[2]
        if not arg.endswith(".toml") or arg in _OWN_FILES or re.fullmatch(r"[A-Z_]+", Path(arg).stem):
            continue
        if not (ROOT / arg).is_file():
            missing.append((name, command))
    assert not missing, f"commands naming files the repository does not have: {missing}"
    assert not indexed, f"extras asked of the package index instead of the repository: {indexed}"
