"""A height map is one route: the same scene from Python as from a scene file, the size
checked before the resampled map exists, and the map's report (missing samples, units,
contacts at its edge) in the result, result.json and the summary of ``twoscale solve``."""

import json
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import RegularGridInterpolator

import twoscale
from twoscale.cli.main import main
from twoscale.io.scene_file import read_scene
from twoscale.scene import SceneError
from twoscale.surface import (
    RawMap,
    SurfaceError,
    SurfaceOptions,
    build_surface,
    condition,
)
from twoscale.surface.texture import road

ROAD = Path(__file__).resolve().parents[1] / "examples" / "road"
MAT = twoscale.Material(10.0, 0.5)

SCENE = """[material]
E = 10.0
nu = 0.5
[load]
total = {load}
[surface]
file = "{file}"
law_cache = false
{extra}
"""


def _scene(tmp_path, file, *, load=40.0, extra="", name="scene.toml"):
    path = tmp_path / name
    path.write_text(SCENE.format(load=load, file=file, extra=extra), encoding="utf-8")
    return path


def _road_um(tmp_path):
    """A 12 mm road texture, heights in um as the file says, and the heights."""
    z = np.round(road(12.0, 0.1, seed=7) * 1e3)
    np.savez(tmp_path / "map.npz", heights=z, spacing=0.1, units="um")
    return z


@pytest.mark.filterwarnings("ignore:the contact of asperit")  # stones cut by the map's edge
@pytest.mark.parametrize("h", [None, 0.05])
def test_python_map_gives_the_scene_files_answer(tmp_path, h):
    z = _road_um(tmp_path)
    extra = "" if h is None else f"[grid]\nh = {h}\n"
    from_file = twoscale.solve(read_scene(_scene(tmp_path, "map.npz", extra=extra)))
    surface = build_surface(RawMap(z, spacing=0.1, units="um"), SurfaceOptions())
    from_python = twoscale.solve(surface, material=MAT, total_load=40.0, h=h)
    # the same conditioning, resampling and default h (the map's spacing): the same problem
    assert from_python.fields[0].grid.h == (0.1 if h is None else h)
    assert from_python.converged and from_file.converged
    np.testing.assert_array_equal(from_python.forces, from_file.forces)
    np.testing.assert_array_equal(from_python.asperities.contact_areas, from_file.asperities.contact_areas)
    assert from_python.penetration == from_file.penetration
    if h is None:  # the raw map alone: the default options
        alone = twoscale.solve(RawMap(z, spacing=0.1, units="um"), material=MAT, total_load=40.0)
        np.testing.assert_array_equal(alone.forces, from_file.forces)


def test_the_basins_alone_are_refused_naming_the_route():
    surface = build_surface(RawMap(road(12.0, 0.1, seed=7), spacing=0.1, units="mm"))
    with pytest.raises(SceneError, match=r"basin of a height map: give the surface itself, twoscale.solve\(surface"):
        twoscale.solve(surface.asperities, material=MAT, total_load=40.0)
    with pytest.raises(SceneError, match="surface must be a MeasuredSurface"):
        twoscale.Scene(material=MAT, surface=np.zeros((5, 5)), total_load=1.0)


def test_bilinear_resampling_matches_scipy():
    # the axis-by-axis resampling against scipy's bilinear interpolator, on random heights
    z = np.random.default_rng(3).normal(size=(23, 31))
    hm = condition(RawMap(z, spacing=0.1, units="mm"), h=0.037)
    my, mx = hm.shape
    y, x = np.arange(23) * 0.1, np.arange(31) * 0.1
    Y, X = np.meshgrid(
        np.minimum(np.arange(my) * 0.037, y[-1]), np.minimum(np.arange(mx) * 0.037, x[-1]), indexing="ij"
    )
    expected = RegularGridInterpolator((y, x), z)(np.column_stack([Y.ravel(), X.ravel()])).reshape(my, mx)
    assert hm.shape == (60, 82) and hm.measured_spacing == 0.1
    np.testing.assert_allclose(hm.heights, expected, rtol=0, atol=1e-13)


def _cli_exit_2(argv, capsys):
    """Run ``twoscale`` in-process, measuring the largest allocation (numpy's included)."""
    tracemalloc.start()
    try:
        code = main(argv)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    err = capsys.readouterr().err.strip()
    return code, err, peak


def test_a_fine_h_is_refused_before_the_map_is_resampled(tmp_path, capsys):
    out = tmp_path / "out"
    # the example road (500 x 500 samples) at --h 1e-4 would be 2.5e11 samples (1.2 TiB to resample)
    code, err, peak = _cli_exit_2(["solve", str(ROAD / "road.toml"), "--h", "1e-4", "--out", str(out)], capsys)
    assert code == 2 and "\n" not in err and not out.exists()
    assert "--h = 0.0001 mm gives 499,001 x 499,001" in err and "give --h >= 0.01 mm" in err
    assert peak < 100e6  # nothing of the resampled size (the map as read: 2 MB)
    scene = tmp_path / "fine.toml"
    scene.write_text(
        (ROAD / "road.toml").read_text().replace('file = "road.npz"', f'file = "{ROAD / "road.npz"}"')
        + "\n[grid]\nh = 0.001\n",
        encoding="utf-8",
    )
    code, err, peak = _cli_exit_2(["solve", str(scene), "--out", str(out)], capsys)
    assert code == 2 and "grid.h = 0.001 mm gives 49,901 x 49,901" in err and peak < 100e6
    with pytest.raises(SurfaceError, match=r"h = 0.0001 mm gives"):  # from Python, the keyword
        twoscale.solve(RawMap(np.zeros((500, 500)), spacing=0.1, units="mm"), material=MAT, total_load=1.0, h=1e-4)


def test_the_map_size_is_checked_against_the_memory_available(monkeypatch):
    import twoscale.resources

    raw = RawMap(road(12.0, 0.1, seed=7), spacing=0.1, units="mm")  # 120 x 120 samples
    monkeypatch.setattr(twoscale.resources, "available_memory", lambda: 2.5e6 / 0.8)
    # 200 bytes a sample: 2.5 MB hold 12,500 samples, not the 57,121 of h = 0.05
    with pytest.raises(SurfaceError, match=r"over 80 % of the memory available now .* give h >= 0.11 mm") as err:
        build_surface(raw, h=0.05)
    assert "\n" not in str(err.value)
    with pytest.raises(SurfaceError, match=r"the map's own spacing \(0.1 mm; no h given\) gives 120 x 120"):
        build_surface(raw)  # 14,400 samples as measured
    assert build_surface(raw, h=0.11).hmap.shape == (109, 109)  # the suggested h fits


def _bumps_with_a_hole():
    """12 x 12 mm: a bump in the middle, one on the lower edge, a 2 x 2 mm hole in between."""
    y, x = np.mgrid[0:121, 0:121] * 0.1
    z = sum(0.5 * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / 2.0) for cx, cy in ((6.0, 6.0), (6.0, 0.0)))
    z[25:45, 70:90] = np.nan  # 400 samples, in the floor between the bumps: never in contact
    return z


@pytest.mark.parametrize("fill", ["nearest", "mask"])
def test_missing_samples_units_and_edge_contacts_are_reported(tmp_path, capsys, fill):
    z = _bumps_with_a_hole()
    np.save(tmp_path / "m.npy", z)
    path = _scene(tmp_path, "m.npy", load=2.0, extra=f'spacing = 0.1\nunits = "mm"\nfill = "{fill}"\nlaw = "sphere"')
    out = tmp_path / "out"
    assert main(["solve", str(path), "--out", str(out)]) == 0
    captured = capsys.readouterr()
    text = captured.out
    edge = int(np.argmin([abs(a.y + 6.0) for a in read_scene(path).asperities]))  # the bump on the edge
    record = json.loads((out / "result.json").read_text())["height_map"]
    assert record["missing_samples"] == 400 and record["missing_treated_as"] == fill
    assert record["units"] == "mm" and record["units_from"] == "option"
    assert record["edge_contacts"] == 1 and record["edge_asperities"] == [edge + 1]
    assert "missing samples: 400 (2.73 %)" in text and "heights in mm (surface.units)" in text
    assert f"edge contacts: 1 asperity ({edge + 1}) touches the map's edge" in text
    assert f"warning: the contact of asperity {edge + 1} reaches the edge" in captured.err
    # from Python: the same report on the result's details, for both methods
    surface = build_surface(RawMap(z, spacing=0.1), SurfaceOptions(fill=fill, law="sphere"))
    for method in ("twoscale", "reference"):
        with pytest.warns(UserWarning, match="reaches the edge"):
            res = twoscale.solve(surface, material=MAT, total_load=2.0, method=method)
        report = res.details.surface
        assert (report.missing, report.fill, report.edge_contacts) == (400, fill, (edge,))
        assert (report.units, report.units_from, report.source) == ("mm", "default", "array")


def test_heights_in_um_read_as_mm_are_refused_unless_units_are_given(tmp_path, capsys):
    np.save(tmp_path / "m.npy", np.round(road(12.0, 0.1, seed=7) * 1e3))  # um, the file says nothing
    path = _scene(tmp_path, "m.npy", extra="spacing = 0.1")
    assert main(["solve", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert (
        "\n" not in err
        and "surface.units is not given" in err
        and "run from" in err
        and not (tmp_path / "out").exists()
    )
    um = read_scene(_scene(tmp_path, "m.npy", extra='spacing = 0.1\nunits = "um"', name="um.toml"))
    assert um.surface.hmap.units == "um" and um.surface.hmap.units_from == "option"
    # given explicitly, the same heights are taken as mm (the user's word)
    assert read_scene(_scene(tmp_path, "m.npy", extra='spacing = 0.1\nunits = "mm"', name="mm.toml")).surface
    # a hemisphere in mm (relief half its width) is plausible without units
    y, x = (np.mgrid[0:101, 0:101] - 50) * 0.1
    cap = np.sqrt(np.maximum(25.0 - x**2 - y**2, 0.0))
    assert condition(RawMap(cap, spacing=0.1)).units_from == "default"
    with pytest.raises(SurfaceError, match=r"run from 0 to 5000 \(5000 mm of relief on a map 10 mm wide\)"):
        condition(RawMap(cap * 1e3, spacing=0.1))


def test_a_scene_takes_a_surface_or_asperities_not_both():
    surface = build_surface(RawMap(road(12.0, 0.1, seed=7), spacing=0.1, units="mm"))
    with pytest.raises(SceneError, match="exactly one of asperities and a surface"):
        twoscale.Scene(material=MAT, asperities=twoscale.asperities([0.0], [0.0], 5.0), surface=surface, total_load=1.0)
    scene = twoscale.Scene(material=MAT, surface=surface, total_load=1.0)
    assert scene.h == 0.1 and scene.asperities == surface.asperities
