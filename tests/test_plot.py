"""Figures: PNG files of the requested pixel size, non-blank, with version metadata."""

import json

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from helpers import png_info
from twoscale import __version__
from twoscale.grid import Grid
from twoscale.indenters import Asperity
from twoscale.plot import Caption, FigureStyle, compare_forces, compare_maps, force_bars, pressure_map
from twoscale.results import ContactResult, PressureField, summarise
from twoscale.sensor import Sensor


def _hertz_patch(cx, cy, a, p0, h, owner):
    g = Grid.covering(cx - 1.5 * a, cx + 1.5 * a, cy - 1.5 * a, cy + 1.5 * a, h)
    X, Y = g.centres()
    r2 = ((X - cx) ** 2 + (Y - cy) ** 2) / a**2
    p = p0 * np.sqrt(np.clip(1 - r2, 0, None))
    return PressureField(g, p, np.full(g.shape, owner), np.where(p > 0, 0.0, 0.1))


def _result(scale=1.0):
    fields = (_hertz_patch(-3, 0, 1.0, 1.0 * scale, 0.1, 0), _hertz_patch(3, 1, 1.5, 0.8 * scale, 0.1, 1))
    s = summarise(fields, 2)
    return ContactResult("twoscale", fields, 0.2, None, float(s.forces.sum()), s, True)


def _not_blank(path):
    from matplotlib.image import imread

    img = imread(path)
    # a figure with content has many distinct colours, a blank one has one
    assert len(np.unique(img.reshape(-1, img.shape[-1]), axis=0)) > 50


def test_pressure_map_size_metadata_and_content(tmp_path):
    asp = [Asperity(-3, 0, 0, 5.0), Asperity(3, 1, 0, 5.0)]
    path = pressure_map(
        _result(),
        tmp_path / "p.png",
        tips=asp,
        caption=Caption(scene={"name": "demo"}),
        style=FigureStyle(size=(5.0, 4.0), dpi=80),
    )
    size, text = png_info(path)
    assert size == (400, 320)
    assert text["Software"] == f"twoscale {__version__}"
    assert json.loads(text["Description"])["scene"] == {"name": "demo"}
    assert "total load" in text["Title"]
    _not_blank(path)
    assert [p.name for p in tmp_path.iterdir()] == ["p.png"]  # no temporary file left


def test_pressure_map_on_sensor_cells_and_plain_tips(tmp_path):
    path = pressure_map(
        _result(), tmp_path / "s.png", tips=np.array([[-3, 0], [3, 1]]), sensor=Sensor(nx=10, ny=10, cell=1.9)
    )
    size, _ = png_info(path)
    assert size == (640, 520)
    _not_blank(path)


def test_force_bars_with_macro_forces(tmp_path):
    r = _result()
    path = force_bars(r, tmp_path / "f.png", macro_forces=[1.0, 2.0], style=FigureStyle(dpi=50))
    size, text = png_info(path)
    assert size == (320, 200)
    assert text["Software"].endswith(__version__)
    _not_blank(path)
    with pytest.raises(ValueError, match="expected 2"):
        force_bars(r, tmp_path / "g.png", macro_forces=[1.0, 2.0, 3.0])


def test_compare_forces_and_maps(tmp_path):
    results = {"half-space": _result(), "block": _result(0.8)}
    p1 = compare_forces(results, tmp_path / "cf.png", measured=[1.0, 2.0])
    assert png_info(p1)[0] == (720, 400)
    _not_blank(p1)
    p2 = compare_maps(
        results, tmp_path / "cm.png", tips=np.array([[-3, 0], [3, 1]]), style=FigureStyle(panel_size=3.0, dpi=50)
    )
    assert png_info(p2)[0] == (int((2 * 3.0 + 1.5) * 50), int((3.0 + 0.8) * 50))
    _not_blank(p2)


def test_bad_arguments(tmp_path):
    with pytest.raises(ValueError, match=".png"):
        pressure_map(_result(), tmp_path / "p.jpg")
    with pytest.raises(ValueError, match="at least one"):
        compare_maps({}, tmp_path / "m.png")
    with pytest.raises(ValueError, match="at least one"):
        compare_forces({}, tmp_path / "c.png")
    with pytest.raises(ValueError, match="size"):
        pressure_map(_result(), tmp_path / "p.png", style=FigureStyle(size=(0, 3)))
    assert list(tmp_path.iterdir()) == []


def test_pressure_map_draws_the_tips(tmp_path):
    # the same map with and without tips differs, and only where the markers go: around
    # the tips' pixel positions (axes from the result's patches)
    import matplotlib.image as mpimg

    with_tips = pressure_map(
        _result(), tmp_path / "a.png", tips=np.array([[-3.0, 0.0], [3.0, 1.0]]), style=FigureStyle(dpi=60)
    )
    without = pressure_map(_result(), tmp_path / "b.png", style=FigureStyle(dpi=60))
    a, b = mpimg.imread(with_tips), mpimg.imread(without)
    assert a.shape == b.shape
    diff = np.any(np.abs(a - b) > 1e-3, axis=-1)
    assert diff.sum() > 20  # markers were drawn
    assert diff.sum() < 0.05 * diff.size  # and nothing else changed much


def _many(n, scale=1.0, seed=0):
    """n Hertz patches on a jittered square lattice (3 mm pitch), tips as Asperity."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    xy = np.array([(3.0 * i, 3.0 * j) for j in range(side) for i in range(side)][:n]) + rng.normal(0, 0.3, (n, 2))
    a = rng.uniform(0.3, 1.0, n)
    fields = tuple(_hertz_patch(x, y, ak, ak * scale, 0.2, k) for k, ((x, y), ak) in enumerate(zip(xy, a)))
    s = summarise(fields, n)
    tips = [Asperity(float(x), float(y), 0.0, 1.2) for x, y in xy]
    return ContactResult("twoscale", fields, 0.1, None, float(s.forces.sum()), s, True), tips


@pytest.fixture
def figures(monkeypatch):
    """The matplotlib figures saved by the plotting functions, in order."""
    import twoscale.plot._figure as fig_mod
    import twoscale.plot.difference
    import twoscale.plot.forces
    import twoscale.plot.maps

    saved = []

    def keep(fig, path, **kw):
        saved.append(fig)
        return fig_mod.save_png(fig, path, **kw)

    for mod in (twoscale.plot.forces, twoscale.plot.maps, twoscale.plot.difference):
        monkeypatch.setattr(mod, "save_png", keep)
    return saved


def _bars(fig):
    from matplotlib.patches import Rectangle

    return sum(isinstance(p, Rectangle) for ax in fig.axes for p in ax.patches)


def _numbers(fig):
    """Tip numbers written on a figure: {number: (x, y) of the point they label}."""
    return {int(t.get_text()): tuple(t.xy) for ax in fig.axes for t in ax.texts if t.get_text().isdigit()}


def test_five_tips_numbered_with_one_bar_each(tmp_path, figures):
    from twoscale.plot import difference_map

    res, tips = _many(5)
    pressure_map(res, tmp_path / "p.png", tips=tips)
    force_bars(res, tmp_path / "f.png", tips=tips, macro_forces=res.asperities.forces * 1.1)
    difference_map({"a": res, "b": _many(5, scale=1.2)[0]}, tmp_path / "d.png", tips=tips)
    pmap, bars, diff = figures
    # the numbers on the map are the CSV's: tip k (from 1) at the position of asperity k
    assert _numbers(pmap) == {k + 1: (a.x, a.y) for k, a in enumerate(tips)}
    assert _bars(bars) == 10  # 5 final + 5 macro-step bars
    assert _numbers(diff) == _numbers(pmap)
    for name in ("p.png", "f.png", "d.png"):
        _not_blank(tmp_path / name)


def test_two_thousand_tips_histogram_and_map_instead_of_bars(tmp_path, figures):
    from twoscale.plot import difference_map

    res, tips = _many(2000)
    other = _many(2000, scale=1.1)[0]
    pressure_map(res, tmp_path / "p.png", tips=tips)
    force_bars(res, tmp_path / "f.png", tips=tips)
    compare_forces({"a": res, "b": other}, tmp_path / "c.png")
    difference_map({"a": res, "b": other}, tmp_path / "d.png", tips=tips)
    pmap, forces, comp, diff = figures
    for fig in figures:
        assert _bars(fig) == 0  # no bar chart
    # numbers only on the ten most loaded tips (the CSV's numbers, at their tips), or the
    # ten largest changes; none on the parity plot
    top = np.argsort(-res.asperities.forces)[:10]
    assert _numbers(pmap) == _numbers(forces) == {k + 1: (tips[k].x, tips[k].y) for k in top}
    change = np.argsort(-np.abs(other.asperities.forces - res.asperities.forces))[:10]
    assert set(_numbers(diff)) == {k + 1 for k in change}
    assert _numbers(comp) == {}
    # forces.png: a histogram whose counts add up to the tips, and the tips coloured by force
    (steps,) = [p for ax in forces.axes for p in ax.patches]
    assert steps.get_data().values.sum() == 2000
    from matplotlib.collections import PathCollection

    (dots,) = [c for ax in forces.axes for c in ax.collections if isinstance(c, PathCollection)]
    np.testing.assert_array_equal(dots.get_array(), res.asperities.forces)
    np.testing.assert_array_equal(dots.get_offsets(), [[a.x, a.y] for a in tips])
    # the difference map colours each tip by F_b - F_a
    (ddots,) = [c for ax in diff.axes for c in ax.collections if isinstance(c, PathCollection)]
    np.testing.assert_allclose(ddots.get_array(), other.asperities.forces - res.asperities.forces, rtol=0, atol=0)
    for name in ("p.png", "f.png", "c.png", "d.png"):
        _not_blank(tmp_path / name)


def test_many_patches_drawn_as_one_raster_of_their_cells():
    # below RASTER_PX cells a side the raster is the cells themselves: each pixel the
    # largest pressure of the (overlapping, aligned) patches at that cell
    from twoscale.plot.maps import _raster

    res, _ = _many(60)
    image, (x0, x1, y0, y1) = _raster(res.fields)
    h = res.fields[0].grid.h
    g = Grid(x0 + h / 2, y0 + h / 2, h, image.shape[1], image.shape[0])
    assert (x1 - x0, y1 - y0) == pytest.approx((g.nx * h, g.ny * h))
    expected = np.zeros(g.shape)
    for f in res.fields:
        one = ContactResult("x", (f,), 0.0, None, 0.0, summarise((f,), 60), True)
        expected = np.maximum(expected, one.pressure_on(g))
    np.testing.assert_array_equal(image, expected)
