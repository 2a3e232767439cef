"""The command line, in-process and as a subprocess: result.json against Hertz, exit
codes, one-line errors, nothing written on bad input."""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from twoscale import Material
from twoscale.analytic import hertz
from twoscale.cli.main import build_parser, main
from twoscale.indenters import Asperity
from twoscale.io.result_json import result_to_dict
from twoscale.api import solve_scene
from twoscale.scene import Scene

E_STAR = Material(10.0, 0.5).E_star
FIXED_FIELDS = (
    "converged",
    "method",
    "penetration",
    "tilt",
    "total_load",
    "h",
    "asperities",
    "iterations",
    "timings_s",
    "version",
)
ASPERITY_FIELDS = ("force", "contact_area", "max_pressure")

HERTZ_TEXT = """
[material]
E = 10.0
nu = 0.5
[load]
penetration = 0.5
[[asperity]]
x = 0.0
y = 0.0
z = 0.0
R = 10.0
shape = "{shape}"
"""


def _needs(module: str):
    """Skip while a module another engineer is writing does not exist yet."""
    if importlib.util.find_spec(module) is None:
        pytest.skip(f"{module} is not written yet")


def _read(out) -> dict:
    with open(out / "result.json", encoding="utf-8") as fh:
        return json.load(fh)


def _check_fixed_fields(res: dict, *, method: str, n_asperities: int) -> None:
    for name in FIXED_FIELDS:
        assert name in res, name
    assert res["method"] == method
    assert len(res["asperities"]) == n_asperities
    for a in res["asperities"]:
        for name in ASPERITY_FIELDS:
            assert isinstance(a[name], float), name
    assert res["units"]["length"] == "mm" and res["units"]["force"] == "N" and res["units"]["pressure"] == "MPa"
    assert res["scene"]["material"] == {"E": 10.0, "nu": 0.5}


# ---------------------------------------------------------------- Hertz through the CLI
@pytest.mark.parametrize("shape,law", [("sphere", hertz.sphere_load), ("paraboloid", hertz.load)])
def test_solve_reference_matches_hertz(shape, law, write_scene, tmp_path, capsys):
    _needs("twoscale.reference")
    out = tmp_path / "out"
    code = main(["solve", str(write_scene(HERTZ_TEXT.format(shape=shape))), "--method", "reference", "--out", str(out)])
    assert code == 0
    res = _read(out)
    _check_fixed_fields(res, method="reference", n_asperities=1)
    assert res["converged"] is True and res["tilt"] is None and res["penetration"] == 0.5
    exact = float(law(10.0, 0.5, E_STAR))
    # default h gives >= 32 cells across the contact, where the reference solver's load
    # error is well under 1 %
    assert res["total_load"] == pytest.approx(exact, rel=0.01)
    assert res["asperities"][0]["force"] == pytest.approx(res["total_load"], rel=1e-12)
    a = float(hertz.sphere_contact_radius(10.0, 0.5)) if shape == "sphere" else math.sqrt(5.0)
    assert 32 <= 2 * a / res["h"] <= 32 / 0.9 and res["h_source"] == "default"
    assert res["asperities"][0]["contact_area"] == pytest.approx(math.pi * a * a, rel=0.05)
    assert "total load" in capsys.readouterr().out


def test_subprocess_python_m_twoscale(examples_dir, tmp_path):
    _needs("twoscale.reference")
    out = tmp_path / "sub"
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "twoscale",
            "solve",
            str(examples_dir / "hertz_sphere.toml"),
            "--method",
            "reference",
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    res = _read(out)
    _check_fixed_fields(res, method="reference", n_asperities=1)
    assert res["total_load"] == pytest.approx(float(hertz.sphere_load(10.0, 0.5, E_STAR)), rel=0.01)
    assert "total load" in proc.stdout
    assert [p for p in os.listdir(out) if p.startswith(".")] == [".twoscale-manifest.json"]  # no temporary file left
    # the usual permissions (umask), not a temporary file's owner-only mode
    mask = os.umask(0)
    os.umask(mask)
    assert os.stat(out / "result.json").st_mode & 0o777 == 0o666 & ~mask


def test_solve_twoscale_records_macro_force(examples_dir, tmp_path):
    _needs("twoscale.driver")
    out = tmp_path / "ts"
    argv = ["solve", str(examples_dir / "hertz_sphere.toml"), "--iteration", "union-cg", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    res = _read(out)
    _check_fixed_fields(res, method="twoscale", n_asperities=1)
    exact = float(hertz.sphere_load(10.0, 0.5, E_STAR))
    assert res["total_load"] == pytest.approx(exact, rel=0.01)
    # a lone sphere's macro force is its exact law at the full approach
    assert res["asperities"][0]["macro_force"] == pytest.approx(exact, rel=1e-6)


def test_command_line_takes_the_python_default_route(examples_dir, tmp_path):
    """A lone sphere on a small grid: the command line (which passes its status line to the
    solver) runs the same default route as ``twoscale.solve`` without options, the full
    grid's one CG, and says so; the answer is Hertz's to the grid's accuracy."""
    _needs("twoscale.driver")
    import twoscale
    from twoscale.io.scene_file import read_scene

    out = tmp_path / "route"
    assert main(["solve", str(examples_dir / "hertz_sphere.toml"), "--out", str(out), "--quiet"]) == 0
    res = _read(out)
    py = twoscale.solve(read_scene(examples_dir / "hertz_sphere.toml"))
    assert res["message"].startswith("default route: the full grid") and res["message"] == py.message
    assert res["total_load"] == pytest.approx(py.total_load, rel=1e-12)
    assert res["total_load"] == pytest.approx(float(hertz.sphere_load(10.0, 0.5, E_STAR)), rel=0.01)


def test_h_option_overrides_scene(examples_dir, tmp_path):
    _needs("twoscale.reference")
    out = tmp_path / "h"
    assert (
        main(
            [
                "solve",
                str(examples_dir / "hertz_sphere.toml"),
                "--method",
                "reference",
                "--h",
                "0.2",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    res = _read(out)
    assert res["h"] == 0.2 and res["h_source"] == "--h" and res["scene"]["grid"] == {"h": 0.2}


# ---------------------------------------------------------------- result.json meanings
def test_force_is_integral_over_owned_cells_and_tilt_is_reported():
    _needs("twoscale.reference")
    mat = Material(10.0, 0.5)
    asps = [Asperity(0.0, 0.0, 0.0, 5.0, "paraboloid"), Asperity(3.0, 0.0, 0.05, 4.0, "paraboloid")]
    scene = Scene(material=mat, asperities=asps, total_load=5.0, tilt=True, pivot=(1.0, 0.0), h=0.1)
    result = solve_scene(scene, method="reference")
    res = result_to_dict(result, scene)
    (f,) = result.fields
    for k in range(2):
        own = f.pressure[f.owner == k].sum() * f.grid.h**2
        assert res["asperities"][k]["force"] == pytest.approx(own, rel=1e-12)
    assert res["total_load"] == pytest.approx(5.0, rel=1e-6)
    assert isinstance(res["tilt"], list) and len(res["tilt"]) == 2 and all(np.isfinite(res["tilt"]))
    json.dumps(res, allow_nan=False)  # JSON-safe


def test_reference_grid_beyond_a_sphere_cap():
    # d = 0.9 R: the grid reaches past the cap (cells without material); the exact-sphere
    # law (Segedin) holds for any contact radius a < R
    _needs("twoscale.reference")
    scene = Scene(material=Material(10.0, 0.5), asperities=[Asperity(0.0, 0.0, 0.0, 1.0)], penetration=0.9)
    result = solve_scene(scene, method="reference")
    assert result.converged, result.message
    assert result.total_load == pytest.approx(float(hertz.sphere_load(1.0, 0.9, E_STAR)), rel=0.01)


def test_not_converged_writes_result_and_exits_1(examples_dir, tmp_path, monkeypatch, capsys):
    _needs("twoscale.reference")
    import twoscale.cli.solve as cli_solve

    def stalled(scene, **kw):
        return dataclasses.replace(solve_scene(scene, **kw), converged=False, message="iteration limit (test)")

    monkeypatch.setattr(cli_solve, "solve_scene", stalled)
    out = tmp_path / "nc"
    assert main(["solve", str(examples_dir / "hertz_sphere.toml"), "--method", "reference", "--out", str(out)]) == 1
    res = _read(out)
    assert res["converged"] is False and res["message"] == "iteration limit (test)"
    assert "iteration limit (test)" in capsys.readouterr().err


# ---------------------------------------------------------------- bad input
SPHERE_TEXT = HERTZ_TEXT.format(shape="sphere")


def _edited(old: str, new: str) -> str:
    """The one-sphere scene with ``old`` replaced by ``new`` (which must occur)."""
    assert old in SPHERE_TEXT, old
    return SPHERE_TEXT.replace(old, new)


BAD = {
    "negative radius": (_edited("R = 10.0", "R = -3.5"), "asperity 1: R", "-3.5"),
    "nu above 0.5": (_edited("nu = 0.5", "nu = 0.75"), "material.nu", "0.75"),
    "unknown key": (SPHERE_TEXT + 'colour = "red"\n', "asperity 1: colour", "'red'"),
    "bool as number": (_edited("E = 10.0", "E = true"), "material.E", "True"),
    "unknown shape": (HERTZ_TEXT.format(shape="cone"), "asperity 1: shape", "'cone'"),
    "both loads": (_edited("[load]", "[load]\ntotal = 3.0"), "load.total", "3.0"),
    "nan": (_edited("y = 0.0", "y = nan"), "asperity 1: y", "nan"),
    "no asperity": (SPHERE_TEXT.split("[[asperity]]")[0], "asperity", "missing"),
    "bad toml": ("[material\nE = 1", "invalid TOML", "line 1"),
    "two tips at one place": (SPHERE_TEXT + "[[asperity]]\nx = 0.0\ny = -0.0\nR = 5.0\n", "asperity 2", "(0.0, -0.0)"),
    # a top-level key must come before the first table in TOML
    "empty asperity list": ("asperity = []\n" + SPHERE_TEXT.split("[[asperity]]")[0], "asperity", "[]"),
    "missing R": (_edited("R = 10.0\n", ""), "asperity 1: R", "missing"),
    "missing nu": (_edited("nu = 0.5\n", ""), "material.nu", "missing"),
    "missing [material]": (_edited("[material]\nE = 10.0\nnu = 0.5\n", ""), "material", "missing"),
    "missing [load]": (_edited("[load]\npenetration = 0.5\n", ""), "load", "missing"),
    "E is a string": (_edited("E = 10.0", 'E = "10"'), "material.E", "'10'"),
    "R infinite": (_edited("R = 10.0", "R = inf"), "asperity 1: R", "inf"),
    "x minus infinity": (_edited("x = 0.0", "x = -inf"), "asperity 1: x", "-inf"),
    "penetration infinite": (_edited("penetration = 0.5", "penetration = inf"), "load.penetration", "inf"),
    "load cases with penetration": (_edited("[load]", "[load]\ncases = [5.0]"), "load.cases", "[5.0]"),
    "load case zero": (_edited("penetration = 0.5", "total = 5.0\ncases = [5.0, 0.0]"), "load.cases[1]", "0.0"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_scene_exit_2_one_line_nothing_written(case, write_scene, tmp_path, capsys):
    text, field, value = BAD[case]
    out = tmp_path / "never"
    code = main(["solve", str(write_scene(text)), "--method", "reference", "--out", str(out)])
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1, err
    assert field in err and value in err, err
    assert not out.exists()


@pytest.mark.parametrize("h", ["-1", "0", "nan", "fine"])
def test_bad_h_exit_2(h, examples_dir, tmp_path, capsys):
    out = tmp_path / "never"
    assert main(["solve", str(examples_dir / "hertz_sphere.toml"), "--h", h, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --h") and repr(h) in err
    assert not out.exists()


def test_missing_scene_file_exit_2(tmp_path, capsys):
    out = tmp_path / "never"
    assert main(["solve", str(tmp_path / "absent.toml"), "--out", str(out)]) == 2
    assert "absent.toml" in capsys.readouterr().err
    assert not out.exists()


def test_block_without_fem_influence_exit_2(write_scene, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "fem_influence", None)
    text = HERTZ_TEXT.format(shape="sphere") + '[influence]\nkind = "block"\n'
    out = tmp_path / "never"
    assert main(["solve", str(write_scene(text)), "--out", str(out)]) == 2
    assert 'kind = "block"' in capsys.readouterr().err
    assert not out.exists()


def test_subprocess_bad_input(write_scene, tmp_path):
    out = tmp_path / "never"
    path = write_scene(_edited("R = 10.0", "R = -3.5"))
    proc = subprocess.run(
        [sys.executable, "-m", "twoscale", "solve", str(path), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "asperity 1: R" in proc.stderr and "-3.5" in proc.stderr
    assert proc.stdout == "" and not out.exists()


def test_usage_errors_and_help(capsys):
    assert main([]) == 2
    assert main(["solve"]) == 2
    assert main(["solve", "x.toml", "--method", "magic"]) == 2
    assert main(["--help"]) == 0
    assert main(["--version"]) == 0


def test_optional_subcommands_registered_only_when_present():
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert "solve" in sub.choices
    for name in ("paper", "compare"):
        assert (name in sub.choices) == (importlib.util.find_spec(f"twoscale.cli.{name}") is not None)


def test_paper_seven_spheres_both_methods_agree(examples_dir, tmp_path):
    # the shipped paper scene through the CLI: the two-scale answer against the
    # reference solver on the same cell size (independent algorithms), and the
    # hexagon's six-fold symmetry up to the square lattice's anisotropy
    _needs("twoscale.reference")
    _needs("twoscale.driver")
    res = {}
    for method in ("reference", "twoscale"):
        out = tmp_path / method
        code = main(
            ["solve", str(examples_dir / "paper_seven_spheres.toml"), "--method", method, "--out", str(out), "--quiet"]
        )
        assert code == 0
        res[method] = _read(out)
        _check_fixed_fields(res[method], method=method, n_asperities=7)
        assert res[method]["h"] == 0.25
    f_ref = np.array([a["force"] for a in res["reference"]["asperities"]])
    f_two = np.array([a["force"] for a in res["twoscale"]["asperities"]])
    np.testing.assert_allclose(f_two, f_ref, rtol=5e-3)
    np.testing.assert_allclose(f_ref[1:], f_ref[1:].mean(), rtol=1e-3)
    # interaction unloads the centre sphere below the outer ones, all below a lone sphere
    lone = float(hertz.sphere_load(10.0, 1.0, E_STAR))
    assert f_ref[0] < f_ref[1:].min() and f_ref.max() < lone


# ---------------------------------------------------------------- reference grid enlargement
def _paraboloid_scene():
    return Scene(
        material=Material(10.0, 0.5), asperities=[Asperity(0.0, 0.0, 0.0, 10.0, "paraboloid")], penetration=0.5, h=0.1
    )


def test_reference_grid_too_small_is_enlarged(monkeypatch):
    # Hertz contact radius sqrt(R d) is 0.71 of the reach sqrt(2 R d): a grid built at
    # half the reach clips the contact, so the solve must enlarge and re-solve
    _needs("twoscale.reference")
    import twoscale.reference.on_scene as scene_mod  # where the reference solve on a scene takes its grid

    full = solve_scene(_paraboloid_scene(), method="reference")
    assert full.details.grid_enlargements == 0
    real = scene_mod.reference_grid
    monkeypatch.setattr(
        scene_mod, "reference_grid", lambda s, h, grow=1.0, rise=0.0: real(s, h, grow=0.5 * grow, rise=rise)
    )
    again = solve_scene(_paraboloid_scene(), method="reference")
    assert again.details.grid_enlargements >= 1 and again.converged
    assert again.total_load == pytest.approx(full.total_load, rel=1e-6)


def test_reference_grid_never_large_enough_is_not_converged(monkeypatch):
    _needs("twoscale.reference")
    import twoscale.reference.on_scene as scene_mod

    real = scene_mod.reference_grid
    monkeypatch.setattr(scene_mod, "reference_grid", lambda s, h, grow=1.0, rise=0.0: real(s, h, grow=0.3, rise=rise))
    result = solve_scene(_paraboloid_scene(), method="reference")
    assert not result.converged and "edge of the reference grid" in result.message


@pytest.mark.parametrize("value", ["0", "1", "1.5", "-0.2", "nan", "wide"])
def test_bad_far_tol_exit_2(value, examples_dir, tmp_path, capsys):
    out = tmp_path / "never"
    assert main(["solve", str(examples_dir / "hertz_sphere.toml"), "--far-tol", value, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --far-tol") and repr(value) in err
    assert not out.exists()


def test_far_tol_needs_the_twoscale_method(examples_dir, tmp_path, capsys):
    out = tmp_path / "never"
    assert (
        main(
            [
                "solve",
                str(examples_dir / "hertz_sphere.toml"),
                "--method",
                "reference",
                "--far-tol",
                "0.2",
                "--out",
                str(out),
            ]
        )
        == 2
    )
    assert "--far-tol" in capsys.readouterr().err
    assert not out.exists()


def test_far_tol_many_asperity_mode_matches_default(examples_dir, tmp_path):
    # S2 (25 spheres, pitch 10 mm) at a coarse cell: the many-asperity mode (far field by
    # resultants, two-level iteration) gives the forces of the exact coupling within 0.5 %
    exact, approx = tmp_path / "exact", tmp_path / "approx"
    scene = str(examples_dir / "S2.toml")
    assert main(["solve", scene, "--h", "0.1", "--out", str(exact), "--quiet"]) == 0
    assert main(["solve", scene, "--h", "0.1", "--far-tol", "0.2", "--out", str(approx), "--quiet"]) == 0
    fe = np.array([a["force"] for a in json.loads((exact / "result.json").read_text())["asperities"]])
    fa = np.array([a["force"] for a in json.loads((approx / "result.json").read_text())["asperities"]])
    assert np.max(np.abs(fa - fe) / fe.max()) <= 5e-3


def test_solve_records_the_policy_choice_and_takes_an_expert_iteration(examples_dir, tmp_path, capsys):
    scene = str(examples_dir / "paper_seven_spheres.toml")
    auto, fixed = tmp_path / "auto", tmp_path / "fixed"
    assert main(["solve", scene, "--out", str(auto)]) == 0
    printed = capsys.readouterr().out
    res = _read(auto)
    assert not res["micro_choice"]["by_caller"] and res["micro_choice"]["reason"]
    assert res["micro_attempts"] and res["micro_attempts"][-1]["converged"]
    assert "micro step" in printed and res["micro_choice"]["reason"] in printed
    assert main(["solve", scene, "--iteration", "union-cg", "--out", str(fixed), "--quiet"]) == 0
    res = _read(fixed)
    assert res["micro_choice"]["by_caller"]
    assert [a["iteration"] for a in res["micro_attempts"]] == ["union-cg"]
    assert res["micro_iteration"] == "union CG"


@pytest.mark.parametrize(
    "extra,needle",
    [
        (["--iteration", "union-cg", "--far-tol", "0.1"], "--far-tol"),
        (["--method", "reference", "--iteration", "block-gs"], "--iteration"),
    ],
)
def test_solve_refuses_iteration_options_that_do_not_apply(examples_dir, tmp_path, capsys, extra, needle):
    out = tmp_path / "out"
    assert main(["solve", str(examples_dir / "hertz_sphere.toml"), "--out", str(out)] + extra) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0] and not out.exists()


def test_summary_numbers_asperities_from_one(examples_dir, capsys):
    assert main(["solve", str(examples_dir / "paper_two_spheres.toml")]) == 0
    lines = capsys.readouterr().out.splitlines()
    head = next(i for i, ln in enumerate(lines) if ln.strip().startswith("asperity"))
    assert "numbered from 1" in lines[head]
    assert [ln.split()[0] for ln in lines[head + 1 : head + 3]] == ["1", "2"]


def test_summary_names_the_default_routes_full_grid(examples_dir, capsys):
    # the one-sphere example is small enough for the default route's full grid: the summary
    # must say so and why, not "two-scale" over a reference solver's iterations
    assert main(["solve", str(examples_dir / "hertz_sphere.toml")]) == 0
    lines = capsys.readouterr().out.splitlines()
    method = next(ln for ln in lines if ln.strip().startswith("method"))
    assert "default route" in method and "full grid" in method
    route = next(ln for ln in lines if ln.strip().startswith("route"))
    assert "cells" in route
