"""Generated input (hypothesis): scene, study and surface files from random TOML values,
types and structures, and random arrays as height maps.

The contract: a file either validates, or is refused with one line naming what is wrong
(``ValueError``, exit 2 through the command line), never a traceback. The scene files go
through the whole ``twoscale solve`` command line up to the solver (which is replaced by a
stub: the solve itself is tested elsewhere), so every check made before solving is
exercised, the memory estimate included. A few hundred examples in the default run;
``-m slow`` runs thousands.
"""

from __future__ import annotations

import copy
import datetime
import math
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from twoscale import resources
from twoscale.cli import solve as solve_cli
from twoscale.cli.main import main

FAST = settings(
    max_examples=150,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
MANY = settings(
    max_examples=3000,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)

# ------------------------------------------------------------------ TOML values
SPECIAL = [
    0,
    -1,
    1,
    2,
    0.0,
    -0.0,
    1e-320,
    1e-12,
    0.5,
    0.4999999,
    0.50001,
    -1.0,
    1e12,
    1e308,
    -1e308,
    math.nan,
    math.inf,
    -math.inf,
    2**63 - 1,
    -(2**63),
    "",
    "mm",
    "sphere",
    "paraboloid",
    "block",
    "halfspace",
    "bonded",
    "sliding",
    True,
    False,
]
scalars = st.one_of(
    st.sampled_from(SPECIAL),
    st.booleans(),
    st.integers(-(2**63), 2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=6),
    st.datetimes(min_value=datetime.datetime(1, 1, 1), max_value=datetime.datetime(9999, 1, 1)),
    st.dates(),
)
keys = st.one_of(
    st.sampled_from(
        [
            "x",
            "y",
            "z",
            "R",
            "E",
            "nu",
            "h",
            "total",
            "penetration",
            "kind",
            "size",
            "base",
            "origin",
            "shape",
            "file",
            "law",
            "crop",
            "tilt",
        ]
    ),
    st.text(min_size=1, max_size=5),
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(keys, inner, max_size=3)),
    max_leaves=6,
)


def toml_string(text: str) -> str:
    """A TOML basic string: quotes, backslashes and control characters escaped, the rest
    as is (JSON's surrogate-pair escapes are not valid TOML)."""
    out = []
    for c in text:
        if c in '"\\':
            out.append("\\" + c)
        elif ord(c) < 0x20 or ord(c) == 0x7F:
            out.append(f"\\u{ord(c):04x}")
        else:
            out.append(c)
    return '"' + "".join(out) + '"'


def toml_value(v) -> str:
    """``v`` as an inline TOML value (tables inline, arrays of tables as arrays)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return toml_string(v)
    if isinstance(v, (datetime.datetime, datetime.date)):
        return v.isoformat()
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{toml_string(str(k))} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def toml_text(data: dict) -> str:
    return "".join(f"{toml_string(str(k))} = {toml_value(v)}\n" for k, v in data.items())


def _paths(data, prefix=()):
    """Every key path of nested dicts and lists (list items by index)."""
    out = []
    items = data.items() if isinstance(data, dict) else enumerate(data)
    for k, v in items:
        out.append(prefix + (k,))
        if isinstance(v, (dict, list)):
            out.extend(_paths(v, prefix + (k,)))
    return out


@st.composite
def mutated(draw, base: dict, n_max: int = 3):
    """``base`` with 1 to ``n_max`` mutations: a value replaced by a random one (any type,
    any structure), a key deleted, or an unknown key added; returns (data, touched paths)."""
    data = copy.deepcopy(base)
    touched = []
    for _ in range(draw(st.integers(1, n_max))):
        paths = _paths(data)
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent = data
        for k in path[:-1]:
            parent = parent[k]
        op = draw(st.sampled_from(["replace", "replace", "delete", "add"]))
        if op == "replace":
            parent[path[-1]] = draw(values)
        elif op == "delete":
            del parent[path[-1]]
        elif isinstance(parent, dict):
            parent[draw(keys)] = draw(values)
        else:
            parent.append(draw(values))
        touched.append(path)
    return data, touched


def _one_line(err: str) -> str:
    lines = [line for line in err.strip().splitlines() if not line.startswith("warning:")]
    assert "Traceback" not in err, err
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    return lines[0]


# ------------------------------------------------------------------ scene files
BASE_SCENE = {
    "material": {"E": 10.0, "nu": 0.5},
    "load": {"penetration": 0.05},
    "grid": {"h": 0.1},
    "asperity": [{"x": -3.0, "y": 0.0, "R": 10.0}, {"x": 3.0, "y": 0.0, "z": 0.01, "R": 10.0, "shape": "paraboloid"}],
}
BLOCK_SCENE = dict(
    copy.deepcopy(BASE_SCENE),
    load={"total": 5.0, "tilt": True, "pivot": [0.0, 0.0]},
    influence={"kind": "block", "size": [60.0, 60.0, 10.0], "base": "bonded"},
)


class _Reached(Exception):
    """The command line validated everything and called the solver."""


@pytest.fixture
def solve_stub(monkeypatch):
    """The solver replaced by :class:`_Reached`, and the memory the checks see fixed at
    16 GB: what a file's checks say must not depend on what else the machine runs (with
    little memory free, a valid scene is refused for its size, which no mutation names)."""

    def stub(*args, **kwargs):
        raise _Reached

    monkeypatch.setattr(solve_cli, "solve_scene", stub)
    monkeypatch.setattr(resources, "available_memory", lambda: 16e9)


def _names(touched) -> set:
    """What an error about the mutated paths may name: their keys, and numbered tables as
    the messages number them (``asperity 2``, from 1)."""
    out = {str(c) for path in touched for c in path if isinstance(c, str)}
    out |= {f"{path[0]} {path[1] + 1}" for path in touched if len(path) > 1 and isinstance(path[1], int)}
    return out


def _run_scene(data: dict, capsys, touched=None) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "scene.toml"
        path.write_text(toml_text(data), encoding="utf-8")
        capsys.readouterr()
        try:
            code = main(["solve", str(path), "--quiet"])
        except _Reached:
            return
        err = capsys.readouterr().err
        assert code == 2, err
        line = _one_line(err)
        if touched:  # the line names what was changed
            assert any(name in line for name in _names(touched)), (touched, line)


@FAST
@given(case=mutated(BASE_SCENE) | mutated(BLOCK_SCENE))
def test_scene_files_from_random_values_validate_or_fail_in_one_line(case, capsys, solve_stub):
    _run_scene(case[0], capsys, case[1])


@FAST
@given(data=st.dictionaries(keys | st.sampled_from(list(BASE_SCENE) + ["influence", "surface"]), values, max_size=5))
def test_scene_files_of_random_structure_fail_in_one_line(data, capsys, solve_stub):
    _run_scene(data, capsys)


@FAST
@given(text=st.text(max_size=80) | st.binary(max_size=80).map(lambda b: b.decode("latin-1")))
def test_scene_files_of_random_text_fail_in_one_line(text, capsys, solve_stub):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "scene.toml"
        path.write_text(text, encoding="utf-8", errors="surrogateescape")
        capsys.readouterr()
        assert main(["solve", str(path), "--quiet"]) == 2
        _one_line(capsys.readouterr().err)


def test_a_block_too_large_to_mesh_is_refused_in_one_line(capsys, solve_stub):
    # found by the many-example run: a block 3.5e16 mm long was meshed until memory ran out
    data = copy.deepcopy(BLOCK_SCENE)
    data["influence"]["size"] = [35210811505629550, 60.0, 10.0]
    _run_scene(data, capsys, [("influence", "size")])


@pytest.mark.slow
@MANY
@given(case=mutated(BASE_SCENE, 5) | mutated(BLOCK_SCENE, 5))
def test_scene_files_many(case, capsys, solve_stub):
    _run_scene(case[0], capsys, case[1])


# ------------------------------------------------------------------ study files
SCENE_TEXT = toml_text(BASE_SCENE)
BASE_STUDY = {
    "study": {"name": "fuzz", "method": "twoscale"},
    "scene": [{"file": "scene.toml", "name": "pair"}],
    "body": [
        {"name": "hs", "kind": "halfspace", "window": [20.0, 10.0]},
        {"name": "blk", "kind": "block", "size": [60.0, 60.0, 10.0], "base": "sliding"},
    ],
    "load": {"penetration": [0.05, 0.1]},
    "positions": {"start": [0.0, 0.0], "end": [1.0, 0.0], "step": 0.5},
    "solver": {"h": 0.1, "tol": 1e-8},
    "sensor": {"nx": 4, "ny": 4, "cell": 1.0},
}


def _check_study(data: dict, touched=None) -> None:
    from twoscale.studies.folder import study_digest
    from twoscale.studies.spec import read_study

    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "scene.toml").write_text(SCENE_TEXT, encoding="utf-8")
        path = Path(tmp) / "study.toml"
        path.write_text(toml_text(data), encoding="utf-8")
        try:
            study = read_study(path)
            study_digest(study)  # the expansion into cases and their keys
        except ValueError as exc:
            msg = str(exc)
            assert msg and "\n" not in msg, msg
            if touched:
                assert any(name in msg for name in _names(touched)), (touched, msg)


@FAST
@given(case=mutated(BASE_STUDY))
def test_study_files_from_random_values_validate_or_fail_in_one_line(case):
    _check_study(*case)


@pytest.mark.slow
@MANY
@given(case=mutated(BASE_STUDY, 5))
def test_study_files_many(case):
    _check_study(*case)


# ------------------------------------------------------------------ height maps
def _array(draw) -> np.ndarray:
    shape = draw(st.sampled_from([(1, 1), (1, 40), (40, 1), (3, 3), (8, 8), (24, 30), (0, 5), (5,), (2, 3, 4)]))
    kind = draw(
        st.sampled_from(
            ["random", "nan", "inf", "constant", "huge", "int", "bool", "complex", "str", "float16", "spikes"]
        )
    )
    n = int(np.prod(shape))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    z = rng.normal(size=n)
    if kind == "nan":
        z[rng.random(n) < draw(st.sampled_from([0.1, 0.9, 1.0]))] = np.nan
    elif kind == "inf":
        z[rng.random(n) < 0.2] = draw(st.sampled_from([np.inf, -np.inf]))
    elif kind == "constant":
        z[:] = draw(st.sampled_from([0.0, 1.0, -1e300]))
    elif kind == "huge":
        z *= draw(st.sampled_from([1e150, 1e300, 1e-300]))
    elif kind == "spikes" and n:
        z[rng.integers(0, n, size=3)] = 1e6
    z = z.reshape(shape)
    if kind == "int":
        return (z * 100).astype(np.int64) if np.isfinite(z).all() else np.zeros(shape, dtype=np.int32)
    if kind == "bool":
        return z > 0
    if kind == "complex":
        return z.astype(complex)
    if kind == "str":
        return z.astype(str)
    if kind == "float16":
        return z.astype(np.float16)
    return z


@st.composite
def height_maps(draw):
    arrays = {"heights": _array(draw)}
    if draw(st.booleans()):
        arrays["spacing"] = draw(
            st.sampled_from([0.1, 0.5, 0.0, -1.0, np.nan, np.inf, 1e-9, 1e9, -1e-300]).map(np.array)
            | st.sampled_from([np.array([0.1, 0.2]), np.array("0.1"), np.array(1, dtype=np.int8)])
        )
    if draw(st.booleans()):
        arrays["units"] = np.array(draw(st.sampled_from(["mm", "um", "nm", "m", "furlong", ""])))
    options = draw(
        st.dictionaries(
            st.sampled_from(
                [
                    "spacing",
                    "units",
                    "fill",
                    "detrend",
                    "crop",
                    "invert",
                    "min_distance",
                    "prominence",
                    "cap_depth",
                    "law",
                ]
            ),
            values,
            max_size=2,
        )
    )
    return arrays, options


def _check_map(arrays: dict, options: dict) -> None:
    from twoscale.surface.scene_table import surface_from_table

    with tempfile.TemporaryDirectory() as tmp:
        np.savez(Path(tmp) / "map.npz", **arrays)
        try:
            surface = surface_from_table({"file": "map.npz", "law_cache": False, **options}, base_dir=tmp)
        except ValueError as exc:
            msg = str(exc)
            assert msg and "\n" not in msg, msg
            return
        assert surface.h > 0 and np.isfinite(surface.h)
        assert np.isfinite(surface.hmap.heights[np.isfinite(surface.hmap.heights)]).all()
        assert all(a.R > 0 and math.isfinite(a.R) for a in surface.asperities)


@FAST
@given(case=height_maps())
def test_height_maps_from_random_arrays_build_or_fail_in_one_line(case):
    _check_map(*case)


@pytest.mark.slow
@MANY
@given(case=height_maps())
def test_height_maps_many(case):
    _check_map(*case)


def test_a_map_file_of_pickled_objects_is_refused_in_one_line(tmp_path):
    from twoscale.surface.scene_table import surface_from_table

    np.savez(tmp_path / "map.npz", heights=np.array([[object()] * 4] * 4, dtype=object))
    with pytest.raises(ValueError) as info:
        surface_from_table({"file": "map.npz", "law_cache": False}, base_dir=os.fspath(tmp_path))
    assert "\n" not in str(info.value) and "map.npz" in str(info.value)
