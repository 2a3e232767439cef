"""Figures a reader understands at a glance, from one tip to thousands.

Built on synthetic results (Hertz-like patches on coarse grids, Agg canvas) so each
figure takes well under a second: tips numbered with the CSV's numbers (all when few,
the ten most loaded when many), markers on loaded tips only, titles naming the scene and
the body, a colour scale that one huge corner peak does not flatten, ``ax=`` honoured,
distinct colours and legends beside the lines in the study figures.
"""

import dataclasses
import json

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from twoscale.grid import Grid
from twoscale.indenters import Asperity
from twoscale.plot import (
    Caption,
    FigureStyle,
    body_text,
    compare_forces,
    compare_maps,
    difference_map,
    force_bars,
    plot_forces,
    plot_pressure_map,
    plot_tip_values,
    pressure_map,
    robust_scale,
)
from twoscale.results import ContactResult, PressureField, summarise

BLOCK = {"influence": {"kind": "block", "size": [60.0, 60.0, 10.0], "base": "bonded"}}


def _patch(cx, cy, a, p0, h, owner):
    g = Grid.covering(cx - 1.2 * a, cx + 1.2 * a, cy - 1.2 * a, cy + 1.2 * a, h)
    X, Y = g.centres()
    p = p0 * np.sqrt(np.clip(1 - ((X - cx) ** 2 + (Y - cy) ** 2) / a**2, 0, None))
    return PressureField(g, p, np.full(g.shape, owner), np.where(p > 0, 0.0, 0.1))


def _scene(n, seed=0, unloaded_every=4):
    """n tips on a jittered lattice; every ``unloaded_every``-th tip (from the 2nd) carries
    nothing (no patch). Returns (result, tips, loaded mask)."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    xy = np.array([(3.0 * i, 3.0 * j) for j in range(side) for i in range(side)][:n]) + rng.normal(0, 0.3, (n, 2))
    loaded = np.ones(n, bool)
    if n > 1:
        loaded[1::unloaded_every] = False
    a = rng.uniform(0.4, 1.0, n)
    fields = tuple(_patch(x, y, ak, ak, 0.25, k) for k, ((x, y), ak) in enumerate(zip(xy, a)) if loaded[k])
    s = summarise(fields, n)
    tips = [Asperity(float(x), float(y), 0.0, 1.2) for x, y in xy]
    return ContactResult("twoscale", fields, 0.1, None, float(s.forces.sum()), s, True), tips, loaded


def _numbers(fig):
    return {int(t.get_text()): tuple(np.round(t.xy, 9)) for ax in fig.axes for t in ax.texts if t.get_text().isdigit()}


def _expected_numbers(tips, values, among):
    """Tip numbers (from 1) expected: all of ``among`` when at most 30, else the 10 largest."""
    idx = np.flatnonzero(among)
    if idx.size > 30:
        idx = idx[np.argsort(-values[idx], kind="stable")[:10]]
    return {int(k) + 1: (round(tips[k].x, 9), round(tips[k].y, 9)) for k in idx}


@pytest.fixture
def saved(monkeypatch):
    import twoscale.plot._figure as fig_mod
    import twoscale.plot.difference
    import twoscale.plot.forces
    import twoscale.plot.maps

    figs = []

    def keep(fig, path, **kw):
        figs.append(fig)
        return fig_mod.save_png(fig, path, **kw)

    for mod in (twoscale.plot.forces, twoscale.plot.maps, twoscale.plot.difference):
        monkeypatch.setattr(mod, "save_png", keep)
    return figs


@pytest.mark.parametrize("n", [1, 30, 300, 3000])
def test_every_figure_at_any_number_of_tips(n, tmp_path, saved):
    res, tips, loaded = _scene(n)
    # the "block": the same contacts, tip forces changed by -20 % to +20 % along the scene
    other = ContactResult(
        "twoscale",
        res.fields,
        0.1,
        None,
        res.total_load,
        dataclasses.replace(res.asperities, forces=res.forces * np.linspace(0.8, 1.2, n)),
        True,
    )
    road = Caption(scene=BLOCK, name="road")
    pmap = pressure_map(res, tmp_path / "p.png", tips=tips, caption=road)
    force_bars(res, tmp_path / "f.png", tips=tips, macro_forces=res.forces, caption=road)
    compare_forces({"half-space": res, "block": other}, tmp_path / "c.png", caption=Caption(name="road"))
    compare_maps({"half-space": res, "block": other}, tmp_path / "m.png", tips=tips, caption=Caption(name="road"))
    if n > 1:
        difference_map({"half-space": res, "block": other}, tmp_path / "d.png", tips=tips, caption=Caption(name="road"))
    assert pmap.stat().st_size > 5000
    fig_p, fig_f = saved[0], saved[1]
    forces = res.forces
    # markers only on the loaded tips (crosses of the map)
    (crosses,) = [c for c in fig_p.axes[0].collections if c.get_label() == "loaded tips"]
    np.testing.assert_allclose(crosses.get_offsets(), [[t.x, t.y] for t, on in zip(tips, loaded) if on])
    # the numbers are the CSV's (from 1) at their tips: every loaded tip, or the 10 most loaded
    assert _numbers(fig_p) == _expected_numbers(tips, forces, loaded)
    if n > 30:
        assert _numbers(fig_f) == _expected_numbers(tips, forces, loaded)
    if n > 1:  # the difference map numbers the largest changes among the loaded tips
        change = np.abs(other.forces - forces)
        assert _numbers(saved[-1]) == _expected_numbers(tips, change, loaded)
    for fig in saved:
        assert len(fig.axes) >= 1 and all(len(ax.texts) <= 30 for ax in fig.axes)


def test_titles_name_the_scene_and_the_body(tmp_path):
    from helpers import png_info

    res, tips, _ = _scene(5)
    p = pressure_map(res, tmp_path / "p.png", tips=tips, caption=Caption(scene=BLOCK, name="road"))
    f = force_bars(
        res, tmp_path / "f.png", tips=tips, caption=Caption(scene={"influence": {"kind": "halfspace"}}, name="S1")
    )
    assert "road on a 60 x 60 x 10 mm block, bonded base" in png_info(p)[1]["Title"]
    assert "S1 on the half-space" in png_info(f)[1]["Title"]
    assert body_text(None) == "half-space"
    # compare's record names each panel's body
    meta = {"bodies": {"block-bonded": {"influence": BLOCK["influence"]}}}
    from twoscale.plot.maps import _panel_body

    assert _panel_body(meta, "block-bonded") == "60 x 60 x 10 mm block, bonded base"
    m = compare_maps({"block-bonded": res}, tmp_path / "m.png", tips=tips, caption=Caption(meta=meta, name="road"))
    assert json.loads(png_info(m)[1]["Description"])["bodies"] == meta["bodies"]


def test_one_huge_corner_peak_does_not_flatten_the_scale(tmp_path):
    res, tips, _ = _scene(30)
    # a punch corner: one cell of the first patch at 1000 MPa, the others at most ~1 MPa
    f0 = res.fields[0]
    p = f0.pressure.copy()
    j = np.unravel_index(np.argmax(p), p.shape)
    p[j] = 1000.0
    fields = (PressureField(f0.grid, p, f0.owner, f0.gap),) + res.fields[1:]
    s = summarise(fields, 30)
    peaky = ContactResult("twoscale", fields, 0.1, None, float(s.forces.sum()), s, True)
    fig = plot_pressure_map(peaky, tips=tips, caption=Caption(scene=BLOCK, name="road"))
    ax, cax = fig.axes[0], fig.axes[1]
    top = ax.images[0].norm.vmax
    assert top <= 1.0 + 1e-9  # the scale ends among the ordinary cells
    assert "peak 1e+03 MPa at tip 1" in ax.get_title()  # the true peak and its tip, reported
    assert "peak 1e+03" in cax.get_ylabel()
    # a smooth map is not clipped: the scale ends at its peak
    smooth = robust_scale(np.concatenate([f.pressure.ravel() for f in res.fields]))
    assert not smooth.clipped and smooth.top == pytest.approx(max(f.pressure.max() for f in res.fields))
    assert robust_scale(np.zeros(4)).top == 1.0


def test_plot_functions_draw_into_a_given_axes_and_return_its_figure():
    from matplotlib.figure import Figure

    res, tips, _ = _scene(40)
    fig = Figure()
    sub = fig.subfigures(1, 2)
    ax1, ax2 = sub[0].subplots(), sub[1].subplots()
    assert plot_pressure_map(res, ax=ax1, tips=tips) is fig
    assert plot_forces({"a": res}, ax=ax2) is fig
    assert plot_tip_values(tips, res.forces, ax=ax2, style=FigureStyle(colourbar=False)) is fig
    assert ax1.images and ax2.patches
    alone = plot_pressure_map(res, tips=tips)
    assert isinstance(alone, Figure) and alone is not fig


def _study_rows(n_tips=40, loads=(100.0, 200.0), positions=(0, 1, 2)):
    cases, tips = [], []
    for li, W in enumerate(loads):
        for pos in positions:
            key = f"k{li}{pos}"
            f = np.linspace(1.0, 2.0, n_tips) * W / n_tips * (1 + 0.1 * pos)
            cases.append(
                {
                    "scene": "S2",
                    "body": "block",
                    "position": pos,
                    "load_kind": "total",
                    "load": W,
                    "distance_mm": 5.0 * pos,
                    "total_load_N": float(f.sum()),
                    "approach_mm": 0.1 * (li + 1),
                    "contact_area_mm2": 10.0 * (li + 1),
                    "key": key,
                }
            )
            tips += [
                {"scene": "S2", "body": "block", "position": pos, "asperity": k + 1, "force_N": float(f[k]), "key": key}
                for k in range(n_tips)
            ]
    return cases, tips


def test_a_study_title_names_a_body_once_when_its_name_is_its_kind():
    from twoscale.studies.figures import _on

    assert _on("halfspace", {"halfspace": {"kind": "halfspace"}}) == "half-space"  # not "halfspace (half-space)"
    assert _on("hs", {"hs": {"kind": "halfspace"}}) == "hs (half-space)"
    assert _on("soft", None) == "soft"


def test_study_figures_distinct_colours_and_legend_beside_the_lines(tmp_path):
    from twoscale.studies.figures import asperity_forces, track

    cases, tips = _study_rows()
    bodies = {"block": {"kind": "block", "size": [140.0, 140.0, 20.0], "base": "bonded"}}
    for draw in (asperity_forces, track):
        path = draw(cases, tips, "S2", "block", tmp_path / f"{draw.__name__}.png", {}, bodies)
        from helpers import png_info

        assert "S2 on block (140 x 140 x 20 mm block, bonded base)" in png_info(path)[1]["Title"]
    from twoscale.studies.figures import plot_tip_forces

    fig = plot_tip_forces(cases, tips, "S2", "block")
    ax = fig.axes[0]
    colours = [ln.get_color() for ln in ax.lines]
    assert len(colours) == 10 and len(set(colours)) == 10  # the 10 most loaded, no colour twice
    assert [ln.get_label() for ln in ax.lines][:3] == ["tip 40", "tip 39", "tip 38"]
    fig.canvas.draw()
    legend, axes_box = ax.get_legend().get_window_extent(), ax.get_window_extent()
    assert legend.x0 >= axes_box.x1  # beside the plot, over no line
