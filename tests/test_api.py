"""The public entry ``twoscale.solve``.

Checks that can fail for a real reason: a Hertz paraboloid against the closed form written
out here; the same tips given as Asperity objects, arrays and a mapping give identical
answers; the reference method and the two-scale method agree on a seeded random scene;
a provider passed in is the one used (a counting wrapper, and a block scene solved without
fem_influence); the printed result is one short line; numbering is 0-based in Python and
1-based where a person reads it (result.json, the terminal table).
"""

import collections
import math
import sys

import numpy as np
import pytest

import twoscale
from twoscale import Asperity, Material, Scene
from twoscale.influence.halfspace import HalfSpace
from twoscale.synthetic import random_scene

MAT = Material(E=10.0, nu=0.5)
E_STAR = 10.0 / (1 - 0.25)


def _hertz(R, d):
    """Hertz (1882) for a paraboloid: load N, contact radius mm, peak pressure MPa."""
    a = math.sqrt(R * d)
    return 4.0 / 3.0 * E_STAR * math.sqrt(R) * d**1.5, a, 2.0 * E_STAR * a / (math.pi * R)


@pytest.mark.parametrize("method", ["twoscale", "reference"])
def test_hertz_paraboloid_against_the_closed_form(method):
    R, d = 10.0, 0.1
    res = twoscale.solve([[0.0, 0.0, R]], material=MAT, penetration=d, shape="paraboloid", method=method)
    load, a, p0 = _hertz(R, d)
    assert res.converged, res.message
    # the default cell puts ~32 cells across the contact: the load is second order in h
    # (0.03 % at 32 cells), the area and the peak first order (about 1 %)
    assert res.total_load == pytest.approx(load, rel=2e-3)
    assert res.forces[0] == pytest.approx(load, rel=2e-3)
    assert res.asperities.contact_areas[0] == pytest.approx(math.pi * a * a, rel=3e-2)
    assert res.asperities.max_pressures[0] == pytest.approx(p0, rel=2e-2)


def test_hertz_under_load_control_gives_the_closed_form_approach():
    R, W = 8.0, 3.0
    res = twoscale.solve({"x": [0.0], "y": [0.0], "R": [R]}, material=MAT, total_load=W, shape="paraboloid")
    d = (3.0 * W / (4.0 * E_STAR * math.sqrt(R))) ** (2.0 / 3.0)
    assert res.converged and res.total_load == pytest.approx(W, rel=1e-9)
    assert res.penetration == pytest.approx(d, rel=2e-3)


def test_arrays_and_objects_give_identical_results():
    rng = np.random.default_rng(3)
    x, y = rng.uniform(-6, 6, 5), rng.uniform(-6, 6, 5)
    R, z = rng.uniform(3, 6, 5), rng.uniform(0, 0.02, 5)
    objects = [Asperity(float(a), float(b), float(c), float(r)) for a, b, c, r in zip(x, y, z, R)]
    kw = dict(material=MAT, total_load=6.0, h=0.08)
    ref = twoscale.solve(objects, **kw)
    forms = [
        np.column_stack([x, y, R, z]),
        {"x": x, "y": y, "R": R, "z": z},
        twoscale.asperities(x, y, R, z),
        np.column_stack([x, y, R, z]).tolist(),
    ]
    for tips in forms:
        got = twoscale.solve(tips, **kw)
        assert np.array_equal(got.forces, ref.forces) and got.penetration == ref.penetration
    # (n, 3) arrays: z = 0
    flat = twoscale.solve(np.column_stack([x, y, R]), **kw)
    assert np.array_equal(flat.forces, twoscale.solve([Asperity(a.x, a.y, 0.0, a.R) for a in objects], **kw).forces)


def test_reference_and_twoscale_agree_on_a_random_scene():
    scene = random_scene(12, seed=5, h=0.1)
    ts = twoscale.solve(scene)
    ref = twoscale.solve(scene, method="reference")
    assert ts.converged and ref.converged, (ts.message, ref.message)
    assert ts.method == "twoscale" and ref.method == "reference" and ref.solver in ("dense", "cg")
    assert ref.details.solver == ref.solver and ref.details.grid_enlargements == 0
    # same discrete problem, the two-scale one on patches: forces agree to its tolerance
    F, Fr = ts.forces, ref.forces
    assert np.max(np.abs(F - Fr)) <= 5e-3 * Fr.max()


def test_reference_by_name_reports_the_solver_that_ran():
    scene = random_scene(4, seed=2, h=0.3)  # 1,385 cells with material: dense is quick
    auto = twoscale.solve(scene, method="reference")
    assert auto.method == "reference" and auto.solver == "dense"  # <= 2,000 cells: dense
    for solver in ("dense", "cg"):
        got = twoscale.solve(scene, method=solver)
        assert got.method == "reference" and got.solver == solver == got.details.solver
        # the same discrete problem solved two ways
        np.testing.assert_allclose(got.forces, auto.forces, rtol=1e-6, atol=1e-9 * auto.forces.max())


class CountingHalfSpace(HalfSpace):
    """The half-space, counting the calls the solvers make to it."""

    def __init__(self, material):
        super().__init__(material)
        object.__setattr__(self, "calls", collections.Counter())

    def grid_operator(self, target, source=None):
        self.calls["grid_operator"] += 1
        return super().grid_operator(target, source)

    def point_compliance(self, targets, sources):
        self.calls["point_compliance"] += 1
        return super().point_compliance(targets, sources)


@pytest.mark.parametrize("method", ["twoscale", "cg"])
def test_a_provider_passed_in_is_used(method, monkeypatch):
    tips = [[0.0, 0.0, 5.0], [4.0, 0.0, 5.0]]
    counting = CountingHalfSpace(MAT)
    got = twoscale.solve(tips, provider=counting, total_load=4.0, h=0.1, method=method)
    assert sum(counting.calls.values()) > 0
    plain = twoscale.solve(tips, material=MAT, total_load=4.0, h=0.1, method=method)
    np.testing.assert_array_equal(got.forces, plain.forces)
    # a block scene with the half-space passed in: the scene's body is not built
    monkeypatch.setitem(sys.modules, "fem_influence", None)
    block = Scene(
        MAT, twoscale.asperities([0.0, 4.0], [0.0, 0.0], 5.0), total_load=4.0, h=0.1, influence={"kind": "block"}
    )
    assert np.array_equal(twoscale.solve(block, provider=CountingHalfSpace(MAT), method=method).forces, plain.forces)
    with pytest.raises(twoscale.SceneError, match="fem_influence"):
        twoscale.solve(block, method=method)


def test_a_callable_method_gets_the_provider_and_the_scene():
    seen = {}

    def mine(provider, scene, *, h, flag):
        seen.update(provider=provider, scene=scene, h=h, flag=flag)
        return twoscale.solve(scene, provider=provider, method="dense")

    res = twoscale.solve([[0.0, 0.0, 5.0]], material=MAT, penetration=0.05, method=mine, flag=7)
    assert isinstance(seen["provider"], HalfSpace) and seen["flag"] == 7
    assert seen["h"] == twoscale.scene.default_h(seen["scene"]) and res.solver == "dense"


def test_the_result_prints_as_one_short_line():
    scene = random_scene(40, kind="sparse", seed=1)
    res = twoscale.solve(scene)
    text = repr(res)
    assert text == str(res) and "\n" not in text and len(text) < 200
    assert "40 tips" in text and "converged" in text and "twoscale" in text and "array" not in text
    assert f"{res.total_load:.6g} N" in text and f"{res.penetration:.6g} mm" in text
    ref = twoscale.solve([[0.0, 0.0, 5.0]], material=MAT, penetration=0.05, method="reference")
    assert repr(ref).startswith(f"<ContactResult reference ({ref.solver}): 1 tip,")


def test_merged_patches_are_0_based_in_python_and_1_based_in_result_json():
    from twoscale.io.result_json import result_to_dict

    tips = [[30.0, 0.0, 5.0], [0.0, 0.0, 5.0], [0.9, 0.0, 5.0]]  # the last two touch
    res = twoscale.solve(tips, material=MAT, total_load=6.0, h=0.05, iteration="block-gs")
    assert res.details.micro.merged_patches == ((1, 2),)
    record = result_to_dict(res, Scene(MAT, twoscale.as_asperities(tips), total_load=6.0, h=0.05))
    assert record["merged_patches"] == [[2, 3]]


def test_the_terminal_table_numbers_tips_from_1(tmp_path, capsys):
    from twoscale.cli.main import main

    scene = tmp_path / "s.toml"
    scene.write_text(
        "[material]\nE = 10.0\nnu = 0.5\n[load]\ntotal = 3.0\n[grid]\nh = 0.1\n"
        "[[asperity]]\nx = 0.0\ny = 0.0\nR = 5.0\n[[asperity]]\nx = 6.0\ny = 0.0\nR = 5.0\n"
    )
    assert main(["solve", str(scene)]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines() if line.startswith("  ")]
    numbers = [r[0] for r in rows if len(r) >= 4 and r[0].isdigit()]
    assert numbers == ["1", "2"]


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: twoscale.solve(random_scene(2), penetration=0.1), "Scene carries its own penetration"),
        (lambda: twoscale.solve([[0, 0, 5.0]], penetration=0.1), "material"),
        (lambda: twoscale.solve([[0, 0, 5.0]], material=MAT), "exactly one of penetration"),
        (lambda: twoscale.solve(np.zeros((2, 5)), material=MAT, penetration=0.1), r"\(n, 3\)"),
        (lambda: twoscale.solve([[0, 0, -5.0]], material=MAT, penetration=0.1), r"R\[0\] \(tip 1\) must be > 0"),
        (lambda: twoscale.solve({"x": [0], "R": [5.0]}, material=MAT, penetration=0.1), "missing"),
        # three column arrays of three tips would read as three rows: refused, not guessed
        (
            lambda: twoscale.solve((np.zeros(3), np.arange(3.0), np.full(3, 5.0)), material=MAT, penetration=0.1),
            "ambiguous",
        ),
        # the same as plain lists: four tips' columns read as three rows with z, solved silently
        (
            lambda: twoscale.solve(([0.0, 6.0, 12.0, 18.0], [1.0] * 4, [5.0] * 4), material=MAT, penetration=0.1),
            "ambiguous",
        ),
        (lambda: twoscale.solve([[0, 0, 5.0]], material=MAT, penetration=0.1, method="lu"), "method must be"),
        (
            lambda: twoscale.solve(
                [[0, 0, 5.0]], provider=HalfSpace(Material(5.0, 0.3)), material=MAT, penetration=0.1
            ),
            "material",
        ),
    ],
)
def test_bad_input_names_the_value(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_public_names():
    for name in ("solve", "Scene", "Asperity", "Material", "Grid", "HalfSpace", "ContactResult", "asperities"):
        assert name in dir(twoscale) and getattr(twoscale, name) is not None
    with pytest.raises(AttributeError):
        twoscale.NoSuchThing


def test_scene_influence_is_read_only():
    scene = Scene(MAT, (Asperity(0.0, 0.0, 0.0, 5.0),), penetration=0.1, influence={"kind": "block"})
    assert scene.influence == {
        "kind": "block",
        "size": (140.0, 140.0, 20.0),
        "base": "bonded",
        "origin": (0.0, 0.0),
        "source_spacing": 5.0,
    }
    with pytest.raises(TypeError):
        scene.influence["kind"] = "halfspace"
    assert hash(Scene(MAT, scene.asperities, penetration=0.1).influence) is not None


def test_results_and_scenes_pickle_and_stay_read_only():
    # a result must cross processes (multiprocessing returns it pickled) and stay frozen
    import pickle

    scene = random_scene(3, seed=4, h=0.1)
    res = twoscale.solve(scene)
    back = pickle.loads(pickle.dumps(res))
    np.testing.assert_array_equal(back.forces, res.forces)
    assert back.details.micro.choice.reason == res.details.micro.choice.reason
    assert dict(back.timings_s) == dict(res.timings_s) and pickle.loads(pickle.dumps(scene)) == scene
    with pytest.raises(TypeError):
        res.timings_s["total"] = 0.0
    with pytest.raises(TypeError):
        res.details.micro.choice.estimates["patches"] = 0
    with pytest.raises(ValueError):
        res.forces[0] = 0.0


def test_dense_on_too_many_cells_names_the_methods_of_solve():
    """A caller of ``solve(method="dense")`` is pointed at the methods of ``solve``, not at a
    lower-level function name."""
    with pytest.raises(ValueError, match=r"exceed max_cells=.*use method='cg'"):
        twoscale.solve([[0.0, 0.0, 10.0]], material=MAT, penetration=0.5, h=0.02, method="dense")
