"""Scene files: every malformed input gets one message naming the field and the value;
valid scenes round-trip through dicts (and JSON); the default cell size follows its rule."""

from __future__ import annotations

import copy
import json
import math
import sys

import numpy as np
import pytest

from twoscale import Material
from twoscale.analytic import hertz
from twoscale.indenters import Asperity
from twoscale.io.scene_file import SceneError, read_scene, scene_from_dict, scene_to_dict
from twoscale.reference.on_scene import approach_bound, reference_grid
from twoscale.scene import Scene, default_h

BASE = {
    "material": {"E": 10.0, "nu": 0.5},
    "load": {"penetration": 0.5},
    "asperity": [
        {"x": 0.0, "y": 0.0, "z": 0.0, "R": 10.0, "shape": "sphere"},
        {"x": 30.0, "y": 0.0, "z": 0.1, "R": 5.0, "shape": "paraboloid"},
        {"x": 0.0, "y": 30.0, "R": 8.0},
        {"x": -30.0, "y": 0.0, "z": 0.2, "R": 6.0},
    ],
}


def mutated(change) -> dict:
    data = copy.deepcopy(BASE)
    change(data)
    return data


def _set(path, value):
    """A mutator setting ``data[k1][k2]... = value`` (integers index lists)."""

    def change(data):
        d = data
        for k in path[:-1]:
            d = d[k]
        d[path[-1]] = value

    return change


def _del(path):
    def change(data):
        d = data
        for k in path[:-1]:
            d = d[k]
        del d[path[-1]]

    return change


def _both(*changes):
    def change(data):
        for c in changes:
            c(data)

    return change


def _cases(value):
    """Load control (total 200 N) with ``load.cases = value``."""
    return _both(_del(("load", "penetration")), _set(("load", "total"), 200.0), _set(("load", "cases"), value))


# (mutation, field path the message must name, value text the message must show)
MALFORMED = {
    "unknown top-level key": (_set(("mesh",), 1), "mesh", "1"),
    "unknown material key": (_set(("material", "G"), 3.0), "material.G", "3.0"),
    "unknown load key": (_set(("load", "force"), 7.0), "load.force", "7.0"),
    "unknown asperity key": (_set(("asperity", 1, "radius"), 5.0), "asperity 2: radius", "5.0"),
    "unknown grid key": (_set(("grid",), {"size": 0.1}), "grid.size", "0.1"),
    "missing material": (_del(("material",)), "material", "missing"),
    "missing load": (_del(("load",)), "load", "missing"),
    "missing asperity list": (_del(("asperity",)), "asperity", "missing"),
    "missing E": (_del(("material", "E")), "material.E", "missing"),
    "missing nu": (_del(("material", "nu")), "material.nu", "missing"),
    "missing R": (_del(("asperity", 2, "R")), "asperity 3: R", "missing"),
    "missing x": (_del(("asperity", 0, "x")), "asperity 1: x", "missing"),
    "E is a string": (_set(("material", "E"), "10"), "material.E", "'10'"),
    "E is a bool": (_set(("material", "E"), True), "material.E", "True"),
    "x is a bool": (_set(("asperity", 3, "x"), True), "asperity 4: x", "True"),
    "R is a list": (_set(("asperity", 1, "R"), [5.0]), "asperity 2: R", "[5.0]"),
    "negative radius": (_set(("asperity", 3, "R"), -1.0), "asperity 4: R", "-1.0"),
    "zero radius": (_set(("asperity", 2, "R"), 0.0), "asperity 3: R", "0.0"),
    "E zero": (_set(("material", "E"), 0.0), "material.E", "0.0"),
    "E negative": (_set(("material", "E"), -6.0), "material.E", "-6.0"),
    "nu above 0.5": (_set(("material", "nu"), 0.6), "material.nu", "0.6"),
    "nu at -1": (_set(("material", "nu"), -1.0), "material.nu", "-1.0"),
    "nu below -1": (_set(("material", "nu"), -1.5), "material.nu", "-1.5"),
    "both penetration and total": (_set(("load", "total"), 60.0), "load.total", "60.0"),
    "neither penetration nor total": (_del(("load", "penetration")), "load.penetration", "None"),
    "tilt without total": (_set(("load", "tilt"), True), "load.tilt", "penetration = 0.5"),
    "tilt not a bool": (
        _both(_del(("load", "penetration")), _set(("load", "total"), 10.0), _set(("load", "tilt"), 1)),
        "load.tilt",
        "1",
    ),
    "pivot without tilt": (_set(("load", "pivot"), [1.0, 2.0]), "load.pivot", "[1.0, 2.0]"),
    "pivot of three numbers": (
        _both(
            _del(("load", "penetration")),
            _set(("load", "total"), 10.0),
            _set(("load", "tilt"), True),
            _set(("load", "pivot"), [0.0, 0.0, 1.0]),
        ),
        "load.pivot",
        "[0.0, 0.0, 1.0]",
    ),
    "total zero": (_both(_del(("load", "penetration")), _set(("load", "total"), 0.0)), "load.total", "0.0"),
    "total negative": (_both(_del(("load", "penetration")), _set(("load", "total"), -5.0)), "load.total", "-5.0"),
    "penetration reaches nothing": (_set(("load", "penetration"), -0.25), "load.penetration", "-0.25"),
    "empty asperity list": (_set(("asperity",), []), "asperity", "[]"),
    "asperity not a list": (_set(("asperity",), 5), "asperity", "5"),
    "asperity entry not a table": (_set(("asperity", 1), 5), "asperity 2", "5"),
    "material not a table": (_set(("material",), 5), "material", "5"),
    "two tips at one place": (
        _both(_set(("asperity", 3, "x"), 30.0), _set(("asperity", 3, "y"), 0.0)),
        "asperity 4",
        "(30.0, 0.0)",
    ),
    "R infinite": (_set(("asperity", 0, "R"), math.inf), "asperity 1: R", "inf"),
    "x nan": (_set(("asperity", 1, "x"), math.nan), "asperity 2: x", "nan"),
    "z -inf": (_set(("asperity", 2, "z"), -math.inf), "asperity 3: z", "-inf"),
    "E nan": (_set(("material", "E"), math.nan), "material.E", "nan"),
    "penetration inf": (_set(("load", "penetration"), math.inf), "load.penetration", "inf"),
    "total nan": (_both(_del(("load", "penetration")), _set(("load", "total"), math.nan)), "load.total", "nan"),
    "h negative": (_set(("grid",), {"h": -0.1}), "grid.h", "-0.1"),
    "h infinite": (_set(("grid",), {"h": math.inf}), "grid.h", "inf"),
    "h a string": (_set(("grid",), {"h": "fine"}), "grid.h", "'fine'"),
    "unknown shape": (_set(("asperity", 2, "shape"), "cube"), "asperity 3: shape", "'cube'"),
    "unknown influence kind": (_set(("influence",), {"kind": "layer"}), "influence.kind", "'layer'"),
    "block option on halfspace": (
        _set(("influence",), {"kind": "halfspace", "base": "bonded"}),
        "influence.base",
        "'bonded'",
    ),
    "unknown block base": (_set(("influence",), {"kind": "block", "base": "glued"}), "influence.base", "'glued'"),
    "negative block size": (
        _set(("influence",), {"kind": "block", "size": [140.0, 140.0, -20.0]}),
        "influence.size[2]",
        "-20.0",
    ),
    "block size of two numbers": (
        _set(("influence",), {"kind": "block", "size": [140.0, 20.0]}),
        "influence.size",
        "[140.0, 20.0]",
    ),
    "unknown block key": (_set(("influence",), {"kind": "block", "thickness": 20.0}), "influence.thickness", "20.0"),
    "load cases with penetration": (_set(("load", "cases"), [1.0, 2.0]), "load.cases", "[1.0, 2.0]"),
    "load cases empty": (_cases([]), "load.cases", "[]"),
    "load cases not a list": (_cases(200.0), "load.cases", "200.0"),
    "load cases a string": (_cases("200, 250"), "load.cases", "'200, 250'"),
    "load case zero": (_cases([200.0, 0.0]), "load.cases[1]", "0.0"),
    "load case negative": (_cases([-5.0]), "load.cases[0]", "-5.0"),
    "load case infinite": (_cases([200.0, math.inf]), "load.cases[1]", "inf"),
    "load case nan": (_cases([math.nan]), "load.cases[0]", "nan"),
    "load case a string": (_cases([200.0, "250"]), "load.cases[1]", "'250'"),
    "load case a bool": (_cases([True]), "load.cases[0]", "True"),
    "load cases repeated": (_cases([200.0, 250.0, 200.0]), "load.cases", "[200.0, 250.0, 200.0]"),
}


def test_base_scene_is_valid():
    scene = scene_from_dict(BASE)
    assert len(scene.asperities) == 4
    assert scene.asperities[2].z == 0.0 and scene.asperities[2].shape == "sphere"  # defaults
    assert scene.influence == {"kind": "halfspace"}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_scene_names_field_and_value(case):
    change, path, value = MALFORMED[case]
    with pytest.raises(SceneError) as info:
        scene_from_dict(mutated(change))
    msg = str(info.value)
    assert "\n" not in msg
    assert path in msg, msg
    assert value in msg, msg
    assert isinstance(info.value, ValueError)


def _toml(data: dict) -> str:
    """A small TOML writer for these tests' dicts (floats via repr keep nan/inf)."""

    def val(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(val(x) for x in v) + "]"
        return repr(float(v)) if isinstance(v, float) else repr(v)

    lines = []
    for key, section in data.items():
        if key == "asperity":
            for t in section:
                lines.append("[[asperity]]")
                lines += [f"{k} = {val(v)}" for k, v in t.items()]
        else:
            lines.append(f"[{key}]")
            lines += [f"{k} = {val(v)}" for k, v in section.items()]
    return "\n".join(lines) + "\n"


def test_read_scene_from_file_and_toml_nonfinite(write_scene):
    assert read_scene(write_scene(_toml(BASE))) == scene_from_dict(BASE)
    text = _toml(BASE).replace("R = 5.0", "R = inf")  # TOML's own spelling of infinity
    path = write_scene(text, "inf.toml")
    with pytest.raises(SceneError, match=r"inf\.toml: asperity 2: R must be a finite number .*got inf"):
        read_scene(path)


def test_read_scene_bad_toml_names_file_and_line(write_scene):
    path = write_scene("[material]\nE = 10.0\nnu = \n", "broken.toml")
    with pytest.raises(SceneError, match=r"broken\.toml: invalid TOML.*line 3"):
        read_scene(path)


def test_read_scene_missing_file(tmp_path):
    with pytest.raises(SceneError, match="not found.*nowhere.toml"):
        read_scene(tmp_path / "nowhere.toml")


@pytest.mark.parametrize(
    "table, message",
    [
        ({"rolling": {"start": 10.0, "end": -10.0, "step": 1.0, "speed": 50.0}}, "rolling.end must not be before"),
        ({"rolling": {"start": -10.0, "end": 10.0, "step": 0.0, "speed": 50.0}}, r"rolling.step must be > 0"),
        ({"grid": {"hh": 0.1}}, "unknown key grid.hh"),
    ],
)
def test_the_other_tables_are_checked_before_the_height_map_is_read(table, message):
    # the map is never opened (it does not exist): a mistake in [rolling] or [grid] was named
    # only after a map had been read and segmented (2.9 s on a 280 x 40 mm strip)
    data = {
        "material": {"E": 10.0, "nu": 0.5},
        "load": {"total": 10.0},
        "surface": {"file": "no_such_map.npy", "spacing": 0.25},
        **table,
    }
    with pytest.raises(SceneError, match=message):
        scene_from_dict(data)


def test_shipped_examples_are_valid(examples_dir):
    hertz_scene = read_scene(examples_dir / "hertz_sphere.toml")
    assert hertz_scene.penetration == 0.5 and hertz_scene.asperities[0].R == 10.0
    paper = read_scene(examples_dir / "paper_seven_spheres.toml")
    tips = paper.tips
    assert len(tips) == 7 and paper.h == 0.25 and paper.penetration == 1.0
    # six tips on a hexagon of radius d_c = 2R * 0.5 = 10 mm around the centre, 60 degrees apart
    r = np.hypot(tips[1:, 0], tips[1:, 1])
    np.testing.assert_allclose(r, 10.0, rtol=1e-15)
    ang = np.sort(np.degrees(np.arctan2(tips[1:, 1], tips[1:, 0])) % 360)
    np.testing.assert_allclose(ang, np.arange(0, 360, 60), atol=1e-12)


# ---------------------------------------------------------------- round trips
ROUND_TRIP = {
    "penetration": BASE,
    "load with tilt and pivot": mutated(
        _both(
            _del(("load", "penetration")),
            _set(("load", "total"), 60.0),
            _set(("load", "tilt"), True),
            _set(("load", "pivot"), [1.5, -2.0]),
        )
    ),
    "block with options and h": mutated(
        _both(
            _set(("grid",), {"h": 0.05}),
            _set(
                ("influence",),
                {"kind": "block", "size": [100.0, 120.0, 20.0], "base": "sliding", "origin": [3.0, -4.0]},
            ),
        )
    ),
    "block defaults": mutated(_set(("influence",), {"kind": "block"})),
    "load cases": mutated(_cases([200.0, 250, 300.0])),
}


@pytest.mark.parametrize("case", sorted(ROUND_TRIP))
def test_round_trip_scene_dict_scene(case):
    scene = scene_from_dict(ROUND_TRIP[case])
    again = scene_from_dict(scene_to_dict(scene))
    assert again == scene
    # the dict is what result.json records: it must survive JSON too
    assert scene_from_dict(json.loads(json.dumps(scene_to_dict(scene)))) == scene


def test_load_cases_are_kept_in_order_as_floats():
    scene = scene_from_dict(ROUND_TRIP["load cases"])
    assert scene.load_cases == (200.0, 250.0, 300.0) and all(type(w) is float for w in scene.load_cases)
    assert scene_to_dict(scene)["load"]["cases"] == [200.0, 250.0, 300.0]
    # no key, no list; and none is written back
    assert scene_from_dict(BASE).load_cases == ()
    assert "cases" not in scene_to_dict(scene_from_dict(BASE))["load"]


def test_load_cases_from_a_toml_file(write_scene):
    text = _toml(mutated(_both(_del(("load", "penetration")), _set(("load", "total"), 50.0))))
    path = write_scene(text.replace("total = 50.0", "total = 50.0\ncases = [50.0, 100, 150.0]"))
    assert read_scene(path).load_cases == (50.0, 100.0, 150.0)
    with pytest.raises(SceneError, match=r"load\.cases\[1\] must be > 0 \(N\), got 0"):
        read_scene(write_scene(text.replace("total = 50.0", "total = 50.0\ncases = [50.0, 0]"), "zero.toml"))


def test_block_defaults_are_the_paper_block():
    scene = scene_from_dict(ROUND_TRIP["block defaults"])
    assert scene.influence == {
        "kind": "block",
        "size": (140.0, 140.0, 20.0),
        "base": "bonded",
        "origin": (0.0, 0.0),
        "source_spacing": 5.0,
    }


def test_block_without_fem_influence_names_kind(monkeypatch):
    monkeypatch.setitem(sys.modules, "fem_influence", None)  # makes `import fem_influence` fail
    scene = scene_from_dict(ROUND_TRIP["block defaults"])
    with pytest.raises(SceneError, match='kind = "block"'):
        scene.provider()


# ---------------------------------------------------------------- Python API
def test_python_api_same_checks():
    mat = Material(10.0, 0.5)
    a = Asperity(0.0, 0.0, 0.0, 10.0)
    scene = Scene(material=mat, asperities=[a], penetration=0.5)
    assert scene.asperities == (a,)
    assert scene == scene_from_dict(
        {
            "material": {"E": 10.0, "nu": 0.5},
            "load": {"penetration": 0.5},
            "asperity": [{"x": 0.0, "y": 0.0, "z": 0.0, "R": 10.0}],
        }
    )
    with pytest.raises(SceneError, match="asperity 2 .*-0.0"):
        Scene(material=mat, asperities=[a, Asperity(-0.0, 0.0, 1.0, 5.0)], penetration=0.5)
    with pytest.raises(SceneError, match="exactly one"):
        Scene(material=mat, asperities=[a], penetration=0.5, total_load=3.0)
    with pytest.raises(SceneError, match="asperity list is empty"):
        Scene(material=mat, asperities=[], penetration=0.5)


# ---------------------------------------------------------------- default cell size
def _one(R=10.0, shape="sphere", **load):
    return Scene(material=Material(10.0, 0.5), asperities=[Asperity(0.0, 0.0, 0.0, R, shape)], **load)


@pytest.mark.parametrize("shape", ["sphere", "paraboloid"])
def test_default_h_gives_32_cells_across_the_contact(shape):
    scene = _one(shape=shape, penetration=0.5)
    a = hertz.sphere_contact_radius(10.0, 0.5) if shape == "sphere" else math.sqrt(10.0 * 0.5)
    cells = 2 * a / default_h(scene)
    # 32 cells, plus at most 10 % from rounding h down to two significant digits
    assert 32.0 <= cells <= 32.0 / 0.9


def test_default_h_load_control_matches_penetration_control():
    # a paraboloid carrying its Hertz load at d = 0.5 has the contact of d = 0.5
    E_star = Material(10.0, 0.5).E_star
    W = float(hertz.load(10.0, 0.5, E_star))
    assert default_h(_one(shape="paraboloid", total_load=W)) == default_h(_one(shape="paraboloid", penetration=0.5))


def test_default_h_ignores_asperities_carrying_under_one_percent():
    mat = Material(10.0, 0.5)
    main = Asperity(0.0, 0.0, 0.0, 10.0, "paraboloid")
    barely = Asperity(20.0, 0.0, 0.49, 10.0, "paraboloid")  # approach 0.01: (0.01/0.5)^1.5 = 0.3 % of the force
    fair = Asperity(20.0, 0.0, 0.3, 10.0, "paraboloid")  # approach 0.2: 25 % of the force
    alone = default_h(Scene(material=mat, asperities=[main], penetration=0.5))
    assert default_h(Scene(material=mat, asperities=[main, barely], penetration=0.5)) == alone
    h_fair = default_h(Scene(material=mat, asperities=[main, fair], penetration=0.5))
    assert 32.0 <= 2 * math.sqrt(10.0 * 0.2) / h_fair <= 32.0 / 0.9


def test_scene_h_wins_over_default():
    assert (
        default_h(Scene(material=Material(10.0, 0.5), asperities=[Asperity(0, 0, 0, 10.0)], penetration=0.5, h=0.37))
        == 0.37
    )


# ---------------------------------------------------------------- reference grid
def test_approach_bound_single_paraboloid_under_load_is_hertz():
    E_star = Material(10.0, 0.5).E_star
    scene = _one(shape="paraboloid", total_load=20.0)
    assert approach_bound(scene) == pytest.approx(float(hertz.penetration(10.0, 20.0, E_star)), rel=1e-14)


def test_reference_grid_covers_every_reachable_point():
    scene = scene_from_dict(BASE)
    h = 0.2
    grid = reference_grid(scene, h)
    xmin, xmax, ymin, ymax = grid.bounds
    for a in scene.asperities:
        r = a.reach(scene.penetration - a.z)
        assert r > 0
        assert xmin <= a.x - r - 3 * h and a.x + r + 3 * h <= xmax
        assert ymin <= a.y - r - 3 * h and a.y + r + 3 * h <= ymax
    # aligned with the lattice h Z^2: the tip at the origin sits on a cell centre
    assert grid.x0 / h == pytest.approx(round(grid.x0 / h), abs=1e-9)


def test_an_unknown_influence_key_with_a_line_break_is_named_on_one_line():
    from twoscale.io.scene_file import scene_from_dict
    from twoscale.scene import SceneError

    table = {
        "material": {"E": 10.0, "nu": 0.5},
        "load": {"total": 5.0},
        "asperity": [{"x": 0.0, "y": 0.0, "R": 10.0}],
        "influence": {"kind": "block", "size": [60.0, 60.0, 10.0], "base": "bonded", "\x85": 0},
    }
    with pytest.raises(SceneError) as err:
        scene_from_dict(table)
    message = str(err.value)
    assert len(message.splitlines()) == 1 and "'\\x85'" in message
