"""Height maps in: reading (plain formats, instrument formats through SurfaceTopography),
conditioning (units, missing samples, detrend, crop, resampling, invert, centring) and
segmentation (summits, prominence, one basin per sample)."""

import numpy as np
import pytest
from scipy import ndimage

from twoscale.surface import HeightMap, RawMap, SurfaceError, condition, read_heightmap, segment
from twoscale.surface.texture import road


def _grid(ny=7, nx=9, seed=0):
    return np.random.default_rng(seed).normal(size=(ny, nx))


def test_plain_formats_round_trip(tmp_path):
    z = _grid()
    np.save(tmp_path / "a.npy", z)
    np.savez(tmp_path / "b.npz", heights=z, spacing=0.25, units="um")
    np.savetxt(tmp_path / "c.txt", z)
    np.savetxt(tmp_path / "d.csv", z, delimiter=",")
    for name in ("a.npy", "c.txt", "d.csv"):
        raw = read_heightmap(tmp_path / name)
        assert raw.heights.shape == (7, 9)  # rows y, columns x
        np.testing.assert_allclose(raw.heights, z, rtol=1e-15)
        assert raw.spacing is None
    raw = read_heightmap(tmp_path / "b.npz")
    assert raw.spacing == 0.25 and raw.units == "um"
    hm = condition(raw)
    np.testing.assert_allclose(hm.heights, z * 1e-3)
    assert hm.h == 0.25


def test_point_list_with_a_missing_point(tmp_path):
    z = _grid(5, 6)
    J, I = np.indices(z.shape)
    pts = np.column_stack([I.ravel() * 0.5 + 3.0, J.ravel() * 0.5 - 1.0, z.ravel()])
    np.savetxt(tmp_path / "p.xyz", np.delete(pts, 7, axis=0)[::-1])  # any order, one point gone
    raw = read_heightmap(tmp_path / "p.xyz")
    assert raw.spacing == 0.5 and raw.heights.shape == (5, 6)
    assert np.isnan(raw.heights.ravel()[7])
    hm = condition(raw, units="mm")  # random heights: implausible as mm unless said so
    assert hm.filled == 1 and np.all(np.isfinite(hm.heights))


def test_instrument_format_through_surfacetopography(tmp_path):
    st = pytest.importorskip("SurfaceTopography")
    z = _grid(6, 8)
    z[2, 3] = np.nan
    # SurfaceTopography indexes [x, y]: its array is the transpose of ours
    topo = st.Topography(np.ma.masked_invalid(z.T), physical_sizes=(8 * 2e-6, 6 * 2e-6), unit="m")
    topo.to_netcdf(str(tmp_path / "scan.nc"))
    raw = read_heightmap(tmp_path / "scan.nc")
    assert raw.heights.shape == (6, 8)
    hm = condition(raw)
    assert hm.h == pytest.approx(2e-3, rel=1e-6)  # 2 um in mm
    assert hm.filled == 1
    ok = ~np.isnan(z)
    np.testing.assert_allclose(hm.heights[ok], z[ok] * 1e3, rtol=1e-6)


@pytest.mark.parametrize(
    "content, name, message",
    [
        (b"\x00\x01garbage", "scan.qqq", "unknown height map format"),
        (None, "missing.npy", "not found"),
    ],
)
def test_bad_files_name_the_file(tmp_path, content, name, message):
    path = tmp_path / name
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(SurfaceError, match=message) as err:
        read_heightmap(path)
    assert name in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("name, keep", [("road.npz", 0.5), ("road.npy", 0.0), ("road.npz", 0.0)])
def test_damaged_files_are_one_line_errors(tmp_path, name, keep):
    """A half-copied .npz (no zip directory) or an empty .npy is a SurfaceError naming the
    file, as any other unreadable map, not numpy's own exception."""
    whole = tmp_path / ("whole" + name[-4:])
    z = np.arange(100.0).reshape(10, 10)
    np.savez(whole, heights=z, spacing=0.1) if name.endswith(".npz") else np.save(whole, z)
    data = whole.read_bytes()
    (tmp_path / name).write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(SurfaceError, match="cannot read the height map") as err:
        read_heightmap(tmp_path / name)
    assert name in str(err.value) and "\n" not in str(err.value)


def test_a_map_from_python_is_told_where_its_spacing_and_its_class_go():
    """Heights given in Python without a spacing are told the Python spelling (RawMap or
    SurfaceOptions), not the scene file's; a height map passed where tips are expected is
    told its class."""
    import twoscale

    z = np.random.default_rng(3).random((20, 30))
    with pytest.raises(SurfaceError, match=r"RawMap\(heights, spacing=\.\.\.\)") as err:
        twoscale.build_surface(RawMap(z, units="mm"))
    assert "[surface]" not in str(err.value)
    with pytest.raises(ValueError, match=r"twoscale\.RawMap\(heights, spacing="):
        twoscale.solve(z, material=twoscale.Material(10.0, 0.5), total_load=10.0)


def test_all_nan_too_small_and_no_spacing(tmp_path):
    np.save(tmp_path / "nan.npy", np.full((5, 5), np.nan))
    with pytest.raises(SurfaceError, match="all NaN"):
        read_heightmap(tmp_path / "nan.npy")
    np.save(tmp_path / "small.npy", np.zeros((2, 40)))
    with pytest.raises(SurfaceError, match="too small"):
        read_heightmap(tmp_path / "small.npy")
    np.save(tmp_path / "ok.npy", np.zeros((5, 5)))
    with pytest.raises(SurfaceError, match="no spacing"):
        condition(read_heightmap(tmp_path / "ok.npy"))
    with pytest.raises(SurfaceError, match="units"):
        condition(read_heightmap(tmp_path / "ok.npy"), spacing=0.1, units="inch")


def _raw(z, spacing=0.1, units="mm"):
    return RawMap(np.asarray(z, float), spacing, units, None, "map")


def test_detrend_crop_resample_invert_centre():
    J, I = np.indices((21, 31)).astype(float)
    plane = 0.3 + 0.02 * I - 0.01 * J
    bump = np.exp(-((I - 15) ** 2 + (J - 10) ** 2) / 8.0)
    hm = condition(_raw(plane + bump), detrend=True)
    # the plane is gone up to the bump's own least-squares plane (small, symmetric bump)
    assert abs(np.polyfit(I[0], (hm.heights - bump)[0], 1)[0]) < 1e-3
    assert hm.grid.x0 == pytest.approx(-15 * 0.1) and hm.grid.y0 == pytest.approx(-10 * 0.1)  # a sample at (0, 0)
    assert np.unravel_index(np.argmax(hm.heights), hm.shape) == (10, 15)
    crop = condition(_raw(plane), crop=(0.5, 1.5, 0.2, 0.8))
    assert crop.shape == (7, 11)
    fine = condition(_raw(plane), h=0.05)  # bilinear: exact on a plane
    assert fine.shape == (41, 61)
    np.testing.assert_allclose(fine.heights[::2, ::2], plane, atol=1e-12)
    flipped = condition(_raw(plane), invert=True)
    np.testing.assert_allclose(flipped.heights, -plane)


def test_missing_samples_filled_or_masked():
    z = np.arange(25.0).reshape(5, 5)
    z[2, 2] = np.nan
    near = condition(_raw(z), fill="nearest")
    assert near.filled == 1 and near.heights[2, 2] in (7.0, 11.0, 13.0, 17.0)
    masked = condition(_raw(z), fill="mask")
    assert masked.filled == 1 and np.isnan(masked.heights[2, 2])


def _two_bumps(low_peak):
    x = np.arange(-40, 41) * 0.1
    X, Y = np.meshgrid(x, x)
    return X, Y, np.exp(-((X + 1.5) ** 2 + Y**2)) + low_peak * np.exp(-((X - 1.5) ** 2 + Y**2))


def test_prominence_keeps_or_drops_the_lower_summit():
    X, Y, z = _two_bumps(0.6)
    hm = HeightMap(z, 0.1, x0=-4.0, y0=-4.0)
    # the lower summit's prominence: its height less the pass on the line between the two
    saddle = z[40, 20:61].min()
    seg = segment(hm, min_distance=0.5, prominence=0.0)
    assert len(seg) == 2
    assert seg.prominence[1] == pytest.approx(seg.heights[1] - saddle, abs=1e-12)
    assert len(segment(hm, min_distance=0.5, prominence=seg.prominence[1] + 1e-3)) == 1
    assert len(segment(hm, min_distance=3.5, prominence=0.0)) == 1  # too close for the distance


def test_every_sample_in_one_connected_basin():
    z = road(20.0, 0.1, seed=4)
    seg = segment(HeightMap(z, 0.1))
    assert seg.labels.min() == 0 and seg.labels.max() == len(seg) - 1
    assert seg.areas.sum() == pytest.approx(z.size * 0.01)
    for k in range(len(seg)):
        assert ndimage.label(seg.labels == k, structure=np.ones((3, 3)))[1] == 1
        j, i = seg.summits[k]
        assert seg.labels[j, i] == k and z[j, i] == z[seg.labels == k].max()  # the basin's top


def test_a_map_too_large_is_refused_before_segmentation(monkeypatch):
    import twoscale.surface.conditioning as conditioning

    monkeypatch.setattr(conditioning, "MAX_SAMPLES", 100)
    with pytest.raises(SurfaceError, match="crop the map or give h >= 0.2 mm"):
        condition(_raw(np.zeros((20, 20))))
    assert condition(_raw(np.zeros((20, 20))), h=0.2).shape == (10, 10)  # resampled: fits


@pytest.mark.parametrize("seed", range(6))
def test_missing_samples_take_the_nearest_measured_height_of_the_whole_map(seed):
    """The fill runs the feature transform on a window around the holes: every filled
    height is the one the transform of the whole map picks, ties (square holes, heights
    repeated) and holes deeper than the first margin or at the map's edge included."""
    from twoscale.surface.conditioning import _fill_nearest

    rng = np.random.default_rng(seed)
    z = np.round(rng.random((90, 130)), 1)
    missing = np.zeros(z.shape, dtype=bool)
    for _ in range(3):
        (j, i), (h, w) = rng.integers(0, 90, 2), rng.integers(1, 45, 2)
        missing[j : j + h, i : i + w] = True
    index = ndimage.distance_transform_edt(missing, return_distances=False, return_indices=True)
    assert np.array_equal(_fill_nearest(z, missing), z[tuple(index)])
