"""Height-map scenes: the [surface] table, ``twoscale surface``, ``twoscale solve`` and
``compare`` on them, and the shipped example road."""

import json
import sys
from pathlib import Path

import numpy as np
import pytest
from tidy_tables import assert_tidy

from twoscale.cli.main import main
from twoscale.io.scene_file import read_scene
from twoscale.api import solve_scene
from twoscale.scene import SceneError
from twoscale.surface.texture import road

ROOT = Path(__file__).resolve().parents[1]
ROAD = ROOT / "examples" / "road"

SCENE = """# Units: mm, N, MPa.
[material]
E = 10.0
nu = 0.5

[load]
total = {load}

[surface]
file = "map.npy"
spacing = 0.1
units = "{units}"
law_cache = "cache"
{extra}
"""


@pytest.fixture
def map_scene(tmp_path):
    """``map_scene(load=..., units="mm", extra="")``: a 12 mm road texture and its scene."""

    def make(load=40.0, units="mm", extra="", scale=1.0):
        np.save(tmp_path / "map.npy", road(12.0, 0.1, seed=7) * scale)
        path = tmp_path / "scene.toml"
        path.write_text(SCENE.format(load=load, units=units, extra=extra), encoding="utf-8")
        return path

    return make


def test_surface_scene_reads_the_map(map_scene):
    scene = read_scene(map_scene())
    assert scene.surface is not None and scene.h == 0.1
    assert scene.asperities == scene.surface.asperities and len(scene.asperities) >= 3
    assert min(a.z for a in scene.asperities) == 0.0  # the highest summit sets z = 0
    um = read_scene(map_scene(units="um", scale=1e3))  # the same heights in um
    assert [a.z for a in um.asperities] == pytest.approx([a.z for a in scene.asperities])
    coarse = scene.surface.at(0.2)  # conditioned again from the file as read
    assert coarse.h == 0.2 and coarse.hmap.shape == (60, 60)


def test_grid_h_resamples_the_map(map_scene, tmp_path):
    path = map_scene()
    path.write_text(path.read_text() + "\n[grid]\nh = 0.2\n", encoding="utf-8")
    scene = read_scene(path)
    assert scene.h == 0.2 and scene.surface.hmap.shape == (60, 60)


@pytest.mark.parametrize(
    "extra, message",
    [
        ("colour = 1", "unknown key surface.colour"),
        ('units = "inch"', "units must be one of"),
        ("prominence = -1", "prominence"),
        ('law = "magic"', "surface.law must be one of"),
    ],
)
def test_bad_surface_keys(map_scene, extra, message):
    path = map_scene()
    text = path.read_text().replace('units = "mm"\n', "") if extra.startswith("units") else path.read_text()
    path.write_text(text + extra + "\n", encoding="utf-8")
    with pytest.raises(SceneError, match=message):
        read_scene(path)


def test_asperity_or_surface_not_both(map_scene):
    path = map_scene()
    path.write_text(path.read_text() + "\n[[asperity]]\nx = 0\ny = 0\nR = 1\n", encoding="utf-8")
    with pytest.raises(SceneError, match="exactly one of"):
        read_scene(path)


def test_bad_map_file_is_exit_2_naming_it(map_scene, tmp_path, capsys):
    path = map_scene()
    (tmp_path / "map.npy").write_bytes(b"not an array")
    out = tmp_path / "out"
    assert main(["surface", str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "map.npy" in err and "\n" not in err and not out.exists()
    path.write_text(path.read_text().replace("spacing = 0.1\n", ""), encoding="utf-8")
    np.save(tmp_path / "map.npy", np.zeros((20, 20)))
    assert main(["solve", str(path), "--out", str(out), "--quiet"]) == 2
    assert "no spacing" in capsys.readouterr().err and not out.exists()


def test_surface_command_writes_the_segmentation(map_scene, tmp_path):
    path = map_scene()
    out = tmp_path / "seg"
    assert main(["surface", str(path), "--out", str(out), "--quiet"]) == 0
    rows = assert_tidy(out / "segmentation.csv")  # pandas and csv read it without options
    assert not (out / "asperities.csv").exists()  # named apart from a solve's table
    scene = read_scene(path)
    assert len(rows) == len(scene.asperities)
    assert [int(r["asperity"]) for r in rows] == list(range(1, len(rows) + 1))  # numbered from 1
    assert float(rows[0]["recess_z_mm"]) == 0.0 and 1.0 < float(rows[0]["law_exponent"]) < 2.0
    summary = json.loads((out / "surface.json").read_text())
    assert summary["segmentation"]["asperities"] == len(rows)
    assert summary["laws"]["all_solves_converged"] is True
    assert (out / "segmentation.png").stat().st_size > 0
    assert any((tmp_path / "cache").glob("*.npz"))  # the laws went to the cache


def test_solve_and_reference_on_a_map_scene(map_scene, tmp_path):
    path = map_scene()
    assert main(["solve", str(path), "--out", str(tmp_path / "two"), "--quiet"]) == 0
    assert main(["solve", str(path), "--method", "reference", "--out", str(tmp_path / "ref"), "--quiet"]) == 0
    two = json.loads((tmp_path / "two" / "result.json").read_text())
    ref = json.loads((tmp_path / "ref" / "result.json").read_text())
    assert two["scene"]["surface"]["file"].endswith("map.npy")
    assert two["total_load"] == pytest.approx(40.0) and ref["total_load"] == pytest.approx(40.0)
    assert two["penetration"] == pytest.approx(ref["penetration"], rel=1e-3)
    f = np.array([a["force"] for a in two["asperities"]])
    g = np.array([a["force"] for a in ref["asperities"]])
    assert np.allclose(f, g, rtol=0.01, atol=0.01 * g.max())


def test_h_option_resamples_the_map(map_scene, tmp_path):
    out = tmp_path / "coarse"
    assert main(["solve", str(map_scene()), "--h", "0.2", "--out", str(out), "--quiet"]) == 0
    res = json.loads((out / "result.json").read_text())
    assert res["h"] == 0.2 and res["total_load"] == pytest.approx(40.0)


def test_h_option_reads_a_map_too_large_at_its_own_spacing(map_scene, tmp_path, monkeypatch, capsys):
    # the map (120 x 120 samples at 0.1 mm) over the size limit, but not once resampled to
    # the --h the refusal suggests: the map used to be conditioned at its own spacing when
    # the scene was read, before --h applied, and was refused again naming grid.h
    import twoscale.surface.conditioning as conditioning

    monkeypatch.setattr(conditioning, "MAX_SAMPLES", 10_000)
    scene = map_scene()
    assert main(["solve", str(scene), "--out", str(tmp_path / "fine"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "crop the map or give grid.h >= 0.12 mm" in err[0], err
    out = tmp_path / "coarse"
    assert main(["solve", str(scene), "--h", "0.12", "--out", str(out), "--quiet"]) == 0
    res = json.loads((out / "result.json").read_text())
    assert res["h"] == 0.12 and res["h_source"] == "--h" and res["total_load"] == pytest.approx(40.0)
    assert not (tmp_path / "fine").exists()
    capsys.readouterr()  # the coarse solve's warnings (edge contacts)
    # too large at --h itself: refused naming --h
    assert main(["solve", str(scene), "--h", "0.11", "--out", str(tmp_path / "x"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--h = 0.11 mm gives" in err[0] and "give --h >= 0.12 mm" in err[0], err


def test_sphere_law_option_gives_the_same_answer(map_scene):
    # the law only guides the macro step; the micro step solves on the true heights
    tab = solve_scene(read_scene(map_scene()))
    sph = solve_scene(read_scene(map_scene(extra='law = "sphere"')))
    assert sph.converged and tab.converged
    assert sph.penetration == pytest.approx(tab.penetration, rel=1e-4)
    assert np.allclose(sph.asperities.forces, tab.asperities.forces, rtol=1e-3, atol=1e-6)


def test_example_road_is_its_script_output(tmp_path):
    sys.path.insert(0, str(ROAD))
    try:
        import make_road
    finally:
        sys.path.remove(str(ROAD))
    made = make_road.make(tmp_path / "road.npz")
    with np.load(made) as a, np.load(ROAD / "road.npz") as b:
        assert np.array_equal(a["heights"], b["heights"]) and float(b["spacing"]) == 0.1
        assert a["heights"].shape == (500, 500)
    scene = read_scene(ROAD / "road.toml")
    assert scene.surface.hmap.h == 0.1 and len(scene.asperities) >= 50
    assert scene.total_load == pytest.approx(0.2 * 50.0 * 50.0)  # 0.2 MPa nominal


@pytest.mark.slow
def test_example_road_solves_like_the_reference(tmp_path, monkeypatch):
    # 100 stones: the policy couples far patches through their resultants (far_tol 0.1):
    # per-stone errors within 1 % of the largest force (the project's per-tip measure),
    # not of each stone's own force on the lightly loaded ones; far_tol 0.02 meets that too
    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path))
    scene = read_scene(ROAD / "road.toml")
    ref = solve_scene(scene, method="reference")
    g = ref.asperities.forces
    big = g > 0.01 * g.max()
    for options, scale in (({}, g.max()), ({"far_tol": 0.02}, g[big])):
        two = solve_scene(scene, **options)
        assert two.converged and ref.converged
        assert two.total_load == pytest.approx(ref.total_load, rel=0.005)
        f = two.asperities.forces
        assert np.all(np.abs(f - g)[big] <= 0.01 * scale)


@pytest.mark.slow
def test_compare_runs_a_map_scene(map_scene, tmp_path):
    assert main(["compare", str(map_scene()), "--out", str(tmp_path / "cmp"), "--quiet"]) == 0


@pytest.mark.parametrize("shape, wide", [((100, 100), False), ((40, 280), True)])
def test_segmentation_figure_follows_the_maps_shape(tmp_path, shape, wide):
    # a road strip 7 times as long as wide was drawn as a thin band in the middle of a
    # 7 x 6 inch square; its figure is now wide and low, the map filling its width
    import twoscale
    from helpers import png_info
    from twoscale.surface.figure import segmentation_figure

    ny, nx = shape
    z = road(max(nx, ny) * 0.25, 0.25, seed=3)[:ny, :nx]
    surface = twoscale.build_surface(
        twoscale.RawMap(z, spacing=0.25, units="mm"), twoscale.SurfaceOptions(law="sphere")
    )
    (w, h), _ = png_info(segmentation_figure(surface, tmp_path / "seg.png", dpi=50))
    assert (w / h > 2.5) == wide, (w, h)
    if wide:
        ax = _figure_axes(surface)
        box = ax.get_window_extent()
        assert box.width / ax.figure.bbox.width > 0.6  # the strip spans most of the figure


def _figure_axes(surface):
    from twoscale.surface.figure import plot_segmentation

    fig = plot_segmentation(surface, dpi=50)
    fig.canvas.draw()
    return fig.axes[0]
