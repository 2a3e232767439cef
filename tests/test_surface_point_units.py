"""A point list (``.xyz``) whose x, y and heights are in different units.

The three columns of a point list share one unit (``surface.units``). A scan exported with
x, y in mm and heights in um, read with ``units = "um"``, became a map 0.012 mm wide: the
segmentation then asked for a disc of min_distance / h = 20,000 cells (a 23.8 GiB array)
and the command ended in a traceback. Now the conditioning refuses it in one line (the
relief over the width does not depend on the shared unit), the same scan written in one
unit solves, and a min_distance wider than any map is capped at the map's diagonal
(the same summits as at the diagonal itself, without the huge disc).
"""

from __future__ import annotations

import numpy as np

from twoscale.cli.main import main
from twoscale.surface import RawMap, SurfaceOptions, build_surface

H = 0.1  # mm


def _bumps() -> np.ndarray:
    """Heights in um: two round stones 1.5 and 1.2 mm high on a 6 x 6 mm patch."""
    y, x = np.mgrid[0:61, 0:61] * H
    return 1000.0 * (1.5 * np.exp(-((x - 2) ** 2 + (y - 3) ** 2)) + 1.2 * np.exp(-((x - 4.5) ** 2 + (y - 3) ** 2)))


def _write(tmp_path, name: str, xy_factor: float) -> str:
    z = _bumps()
    y, x = np.mgrid[0 : z.shape[0], 0 : z.shape[1]] * H * xy_factor
    np.savetxt(tmp_path / f"{name}.xyz", np.column_stack([x.ravel(), y.ravel(), z.ravel()]))
    scene = tmp_path / f"{name}.toml"
    scene.write_text(
        "[material]\nE = 10.0\nnu = 0.5\n[load]\ntotal = 5.0\n[surface]\n"
        f'file = "{name}.xyz"\nunits = "um"\nlaw_cache = false\nmin_distance = 1.0\n'
    )
    return str(scene)


def test_xy_in_mm_with_heights_in_um_is_refused_in_one_line(tmp_path, capsys):
    scene = _write(tmp_path, "mixed", 1.0)  # x, y in mm, heights in um
    assert main(["solve", scene, "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "share one unit" in err[0] and "Traceback" not in err[0]
    assert not (tmp_path / "out").exists()


def test_the_same_scan_in_one_unit_solves(tmp_path):
    scene = _write(tmp_path, "um", 1000.0)  # x, y in um too
    assert main(["solve", scene, "--out", str(tmp_path / "out"), "--quiet"]) == 0


def test_a_min_distance_wider_than_the_map_gives_the_diagonal_s_summits():
    raw = RawMap(_bumps(), spacing=H, units="um")
    diagonal = np.hypot(61, 61) * H  # mm: the disc then covers the map from any sample
    wide = build_surface(raw, SurfaceOptions(min_distance=1e6)).segmentation
    at_diagonal = build_surface(raw, SurfaceOptions(min_distance=diagonal)).segmentation
    assert np.array_equal(wide.summits, at_diagonal.summits)
    assert np.array_equal(wide.labels, at_diagonal.labels)
