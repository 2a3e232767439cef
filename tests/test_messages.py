"""What the user reads: messages that name the bad thing and say what to change, and docs
that stay inside the repository."""

from __future__ import annotations

import pathlib

import pytest

from twoscale import Material
from twoscale.cli.main import main

ROOT = pathlib.Path(__file__).resolve().parents[1]

EDGE_SCENE = """
[material]
E = 6.0
nu = 0.5
[load]
total = 10.0
[influence]
kind = "block"
{extra}
[[asperity]]
x = 30.0
y = 0.0
R = 5.0
[[asperity]]
x = {x}
y = 0.0
R = 5.0
"""


def test_tip_near_the_block_side_is_named_with_the_option_to_change(write_scene, tmp_path, capsys):
    out = tmp_path / "out"
    path = write_scene(EDGE_SCENE.format(x=66.0, extra=""))
    assert main(["solve", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("error: ")
    assert "asperity 2 at (66, 0) mm" in err  # numbered from 1, the second tip
    assert "influence.source_spacing" in err  # an option the scene file accepts
    assert not out.exists()


def test_the_suggested_option_is_accepted_by_the_scene_and_widens_the_region(write_scene):
    pytest.importorskip("skfem")
    from fem_influence import BlockProvider
    from twoscale.io.scene_file import read_scene
    from twoscale.api import check_domain

    scene = read_scene(write_scene(EDGE_SCENE.format(x=64.0, extra="source_spacing = 2.0")))
    provider = scene.provider(progress=False)
    assert provider.source_spacing == 2.0
    # lattice nodes at multiples of 2 mm, one spacing inside the 70 mm half-width: 68 mm
    assert provider.domain() == pytest.approx((-68.0, 68.0, -68.0, 68.0))
    check_domain(scene, provider, 0.1)  # the tip at 64 mm and its patch now fit
    default = BlockProvider(Material(6.0, 0.5), progress=False)
    assert default.domain() == pytest.approx((-65.0, 65.0, -65.0, 65.0))


def test_bad_source_spacing_is_one_line(write_scene, tmp_path, capsys):
    path = write_scene(EDGE_SCENE.format(x=20.0, extra="source_spacing = -1"))
    assert main(["solve", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "influence.source_spacing" in err and "-1" in err and "\n" not in err


def test_the_half_space_answers_everywhere():
    from twoscale.influence import HalfSpace

    assert HalfSpace(Material(6.0, 0.5)).domain() is None


def test_cell_size_from_the_command_line_is_said_to_be(examples_dir, capsys):
    assert main(["solve", str(examples_dir / "hertz_sphere.toml"), "--h", "0.1"]) == 0
    line = [ln for ln in capsys.readouterr().out.splitlines() if "cell size" in ln][0]
    assert "h = 0.1 mm (--h)" in line


def test_docs_and_code_cite_only_files_of_the_repository():
    # the method is described in docs/method.md; nothing may send a reader outside the project
    offenders = []
    for path in [p for ext in ("py", "md", "toml", "txt", "cfg") for p in ROOT.glob(f"**/*.{ext}")]:
        if any(part in {".venv", "node_modules", ".git"} or part.endswith(".egg-info") for part in path.parts):
            continue
        text = path.read_text(encoding="utf-8", errors="replace")
        if "METHOD" + ".md" in text or "../" + "shared" in text:
            offenders.append(str(path.relative_to(ROOT)))
    assert offenders == []


def test_method_page_has_the_sections_the_code_cites():
    import re

    text = (ROOT / "docs" / "method.md").read_text(encoding="utf-8")
    sections = {int(m) for m in re.findall(r"^## (\d+)\.", text, flags=re.M)}
    cited = set()
    for path in (
        list(ROOT.glob("twoscale/**/*.py")) + list(ROOT.glob("fem_influence/*.py")) + list(ROOT.glob("tests/*.py"))
    ):
        for m in re.findall(r"docs/method\.md sections? (\d+)(?:-(\d+))?", path.read_text(encoding="utf-8")):
            cited |= {int(v) for v in m if v}
    assert cited and cited <= sections


def test_tip_outside_the_block_is_said_to_lie_outside(write_scene, tmp_path, capsys):
    path = write_scene(EDGE_SCENE.format(x=75.0, extra=""))
    assert main(["solve", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "asperity 2 at (75, 0) mm lies outside" in err and err.count("\n") == 1


def test_a_cell_coarser_than_every_contact_is_refused(examples_dir, capsys):
    # S1: seven 6 mm spheres at 50 N, contacts about 3 mm across; h = 20 mm resolves none
    assert main(["solve", str(examples_dir / "S1.toml"), "--h", "20"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "h = 20 mm is coarser than every expected contact" in err
    assert "default rule gives" in err


def test_a_coarse_cell_is_warned_about_in_one_line(examples_dir, capsys):
    # h = 1 mm: about 3 cells across each ~3 mm contact (a Hertz force off by ~10 %)
    assert main(["solve", str(examples_dir / "S1.toml"), "--h", "1", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert err.startswith("warning: cell size h = 1 mm gives asperity ") and err.count("\n") == 1


def test_python_solve_warns_and_refuses_the_same_way():
    import warnings

    import twoscale
    from twoscale.api import ResolutionWarning
    from twoscale.scene import SceneError

    mat = Material(6.0, 0.5)
    with pytest.raises(SceneError, match="coarser than every expected contact"):
        twoscale.solve([[0.0, 0.0, 5.0]], material=mat, penetration=0.1, h=2.0)  # contact ~1.4 mm
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        twoscale.solve([[0.0, 0.0, 5.0]], material=mat, penetration=0.1, h=0.5)
    assert [type(w.message) for w in caught] == [ResolutionWarning]
    assert caught[0].filename == __file__  # the caller's line, not a line of the package
    with warnings.catch_warnings(record=True) as caught:  # through the solver object too
        warnings.simplefilter("always")
        twoscale.ContactSolver(options=twoscale.SolverOptions.from_mapping({"resolution": {"h": 0.5}})).solve(
            [[0.0, 0.0, 5.0]], material=mat, penetration=0.1
        )
    assert [(type(w.message), w.filename) for w in caught] == [(ResolutionWarning, __file__)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        twoscale.solve([[0.0, 0.0, 5.0]], material=mat, penetration=0.1)  # the default h: silent


def test_heights_in_um_taken_as_mm_are_refused(tmp_path, capsys):
    import numpy as np

    y, x = np.mgrid[0:120, 0:120] * 0.1
    z = 800.0 * np.exp(-((x - 6.0) ** 2 + (y - 6.0) ** 2) / 4.0)  # an 0.8 mm bump, in um
    np.save(tmp_path / "bump.npy", z)
    scene = tmp_path / "bump.toml"
    scene.write_text(
        '[material]\nE = 6.0\nnu = 0.5\n[load]\ntotal = 5.0\n[surface]\nfile = "bump.npy"\nspacing = 0.1\n',
        encoding="utf-8",
    )
    assert main(["surface", str(scene), "--out", str(tmp_path / "seg"), "--no-laws"]) == 2
    out, err = capsys.readouterr()
    assert err.startswith("error: ") and err.count("\n") == 1 and not (tmp_path / "seg").exists()
    assert "surface.units is not given" in err and " to 800 (800 mm of relief on a map 11.9 mm wide)" in err
    scene.write_text(scene.read_text().replace("spacing = 0.1", 'spacing = 0.1\nunits = "um"'), encoding="utf-8")
    assert main(["surface", str(scene), "--out", str(tmp_path / "seg2"), "--no-laws"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and " to 0.8 mm" in out


def test_indicators_between_different_scenes_warn(write_scene, tmp_path, capsys):
    text = (
        "[material]\nE = 6.0\nnu = 0.5\n[load]\npenetration = 0.05\n[grid]\nh = 0.05\n"
        "[[asperity]]\nx = 0.0\ny = 0.0\nR = 5.0\n[[asperity]]\nx = {x}\ny = 0.0\nR = 5.0\n"
    )
    for name, x in (("a", 4.0), ("b", 4.0), ("c", 5.0)):
        assert (
            main(
                ["solve", str(write_scene(text.format(x=x), f"{name}.toml")), "--out", str(tmp_path / name), "--quiet"]
            )
            == 0
        )
    capsys.readouterr()
    assert main(["indicators", str(tmp_path / "a"), str(tmp_path / "b")]) == 0
    assert "warning" not in capsys.readouterr().err  # the same scene twice: silent
    assert main(["indicators", str(tmp_path / "a"), str(tmp_path / "c")]) == 0
    err = capsys.readouterr().err
    assert err.startswith("warning: ") and "asperity 2: (4, 0) against (5, 0) mm" in err


def test_height_map_mistakes_are_one_line(tmp_path):
    import numpy as np

    from twoscale.surface.conditioning import condition
    from twoscale.surface import RawMap, SurfaceError
    from twoscale.surface.reading import read_heightmap

    ragged = tmp_path / "ragged.txt"
    ragged.write_text("0 1 2\n3 4 5\n6 7\n", encoding="utf-8")
    with pytest.raises(SurfaceError, match="data row 3 has 2, the first has 3"):
        read_heightmap(ragged)
    inf = tmp_path / "inf.npy"
    np.save(inf, np.full((20, 20), np.inf))
    with pytest.raises(SurfaceError, match="all NaN or infinite"):
        read_heightmap(inf)
    raw = RawMap(np.zeros((31, 31)), 1.0, "mm", None, "flat")
    with pytest.raises(SurfaceError, match=r"crop \[0, 40, 0, 40\] mm must lie within the map"):
        condition(raw, crop=(0, 40, 0, 40))
    with pytest.raises(SurfaceError, match=r"^array: RawMap spacing must be a number > 0 \(mm\), got -1$"):
        RawMap(np.zeros((31, 31)), spacing=-1)  # heights given in Python: no file to blame


def test_contacts_reaching_the_map_edge_are_named(tmp_path):
    import warnings

    import numpy as np

    import twoscale
    from twoscale.io.scene_file import read_scene
    from twoscale.surface.conditioning import SurfaceWarning

    y, x = np.mgrid[0:121, 0:121] * 0.1  # 12 x 12 mm at 0.1 mm
    bump = lambda cx, cy: 0.5 * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / 2.0)  # noqa: E731
    scene = tmp_path / "s.toml"
    scene.write_text(
        '[material]\nE = 6.0\nnu = 0.5\n[load]\ntotal = 2.0\n[surface]\nfile = "m.npy"\n'
        'spacing = 0.1\nunits = "mm"\nlaw = "sphere"\n',
        encoding="utf-8",
    )
    for centres, expected in (([(6.0, 6.0)], []), ([(6.0, 6.0), (6.0, 0.0)], [2])):
        np.save(tmp_path / "m.npy", sum(bump(cx, cy) for cx, cy in centres))
        s = read_scene(scene)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = twoscale.solve(s)
        edge = [w for w in caught if issubclass(w.category, SurfaceWarning)]
        assert res.converged
        if not expected:
            assert edge == []
        else:  # the stone centred on the map's lower edge, numbered from 1 in scene order
            k = int(np.argmin([abs(a.y - (-6.0)) for a in s.asperities]))
            assert len(edge) == 1 and f"asperity {k + 1} reaches the edge" in str(edge[0].message)
            assert edge[0].filename == __file__  # points at the caller's line, not into the package


SOFT_SCENE = """
[material]
E = 1e-12
nu = 0.5
[load]
total = 5.0
[grid]
h = 0.1
[[asperity]]
x = -3.0
y = 0.0
R = 10.0
[[asperity]]
x = 3.0
y = 0.0
z = 0.01
R = 10.0
shape = "paraboloid"
[influence]
kind = "block"
size = [60.0, 60.0, 10.0]
"""


def test_a_memory_refusal_under_load_names_the_modulus_that_makes_the_contact_large(write_scene, tmp_path, capsys):
    """Under load control a contact grows as (F R / E)^(1/3): at E = 1e-12 MPa the expected
    contact is kilometres wide (R 10 mm, 5 N: 2 (3 F R / (4 E*))^(1/3) ~ 5e4 mm), and the
    refusal names the modulus beside the load, the two fields that make it."""
    out = tmp_path / "out"
    path = write_scene(SOFT_SCENE)
    assert main(["solve", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and err.startswith("error: ")
    assert "load.total = 5 N" in err and "material.E = 1e-12 MPa" in err
    assert not out.exists()


def test_a_load_history_on_too_coarse_a_grid_is_warned_of():
    """A step load's first answer is the glassy body's, whose contacts are the history's
    smallest: a cell size that leaves them under 4 cells across is warned of as for one
    load (at the glassy modulus a 10 N sphere of R 10 mm touches over about 1 mm: Hertz),
    one coarser than them all too (a warning: the relaxed answers may be resolved), and a
    history's default cell size is silent."""
    import warnings

    import twoscale
    from twoscale.api import ResolutionWarning
    from twoscale.scene import Scene
    from twoscale.indenters import Asperity
    from twoscale.viscoelastic import LoadHistory

    tip = (Asperity(0.0, 0.0, 0.0, 10.0),)
    mat = Material(5.0, 0.5, prony=((45.0, 1e-2),))  # glassy 50 MPa
    hist = LoadHistory("total", ((0.0, 10.0), (0.05, 10.0)), output=(0.0, 0.05))
    a_glassy = (3 * 10.0 * 10.0 * (1 - 0.25) / (4 * 50.0)) ** (1 / 3)  # mm, Hertz radius
    for h, says in ((0.5 * a_glassy, "cells across"), (3.0 * a_glassy, "coarser than every")):
        scene = Scene(material=mat, history=hist, asperities=tip, h=h)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            twoscale.solve(scene)
        messages = [str(w.message) for w in caught if issubclass(w.category, ResolutionWarning)]
        assert len(messages) == 1 and "glassy" in messages[0] and says in messages[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", ResolutionWarning)
        twoscale.solve(Scene(material=mat, history=hist, asperities=tip))
