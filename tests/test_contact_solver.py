"""The solver object: state kept between solves, the same answers as one-shot solves."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import twoscale
from twoscale.options import MicroOptions, ResolutionOptions, SolverOptions, list_options, options_markdown
from twoscale.synthetic import random_scene

H = 0.05
# the scenes are coarse on purpose (the starts, not the resolution, are under test)
pytestmark = pytest.mark.filterwarnings("ignore::twoscale.errors.ResolutionWarning")


def _scene(control="load", shift=0.0, n=10):
    sc = random_scene(n, kind="sparse", control=control, shape="sphere", seed=5)
    return dataclasses.replace(sc, asperities=tuple(dataclasses.replace(a, x=a.x + shift) for a in sc.asperities), h=H)


def _close(a, b):
    return np.abs(a.asperities.forces - b.asperities.forces).max() <= 1e-5 * b.asperities.forces.max()


@pytest.mark.parametrize("control", ["load", "penetration"])
def test_solves_in_a_row_equal_one_shot_solves_and_say_what_they_reused(control):
    solver = twoscale.ContactSolver()
    first = solver.solve(_scene(control))
    assert first.reuse.solve == 1 and not first.reuse.body_kept and "nothing to reuse" in str(first.reuse)
    again = solver.solve(_scene(control))
    moved = solver.solve(_scene(control, shift=H))
    assert _close(again, twoscale.solve(_scene(control)))
    assert _close(moved, twoscale.solve(_scene(control, shift=H)))
    for r in (again, moved):
        assert r.reuse.body_kept and r.reuse.macro_start and r.reuse.pressure_start > 0
        assert r.iterations["micro"] <= 1 < first.iterations["micro"]
        # the operators between patches (and of each patch on itself) are taken over, also
        # for the scene moved by one cell: on the half-space they depend on relative positions
        assert sum(r.reuse.operators_kept.values()) > 0 and "patch operators kept" in str(r.reuse)
        assert 0 < r.reuse.cache_bytes <= r.reuse.cache_max_bytes
    assert not first.reuse.operators_kept and sum(first.reuse.operators_built.values()) > 0
    assert solver.body is not None and solver.solves == 3
    assert vars(solver.body) == {"material": solver.body.material}  # the body keeps nothing


def test_dense_blocks_factorisations_are_kept_between_solves():
    # blocks small enough for a dense factorisation: the second solve and the solve moved by
    # one cell take each active set's factorisation over (on the half-space a block's matrix
    # depends on its cells' relative positions only) and factorise nothing anew
    options = SolverOptions(micro=MicroOptions(iteration="block-gs", dense_max_cells=2000))
    solver = twoscale.ContactSolver(options=options)
    first = solver.solve(_scene())
    assert first.reuse.operators_built.get("factor", 0) > 0 and "factor" not in first.reuse.operators_kept
    for scene in (_scene(), _scene(shift=H)):
        r = solver.solve(scene)
        assert r.reuse.operators_kept.get("factor", 0) > 0 and r.reuse.operators_built.get("factor", 0) == 0
        assert _close(r, twoscale.solve(scene, options=options))


def test_the_far_field_and_coarse_shapes_are_kept_between_solves_of_the_same_patches():
    # the far field's point operator (tips and moment-matching sources of the same patches)
    # and the coarse correction's shapes (a local solve per patch and active set) are taken
    # over by the second solve, which builds no operator at all
    options = SolverOptions(micro=MicroOptions(iteration="two-level", far_tol=0.05))
    solver = twoscale.ContactSolver(options=options)
    first = solver.solve(_scene())
    again = solver.solve(_scene())
    assert first.reuse.operators_built.get("points", 0) > 0
    assert again.reuse.operators_kept.get("points", 0) > 0 and not again.reuse.operators_built
    assert again.reuse.operators_kept.get("shape", 0) > 0
    assert _close(again, twoscale.solve(_scene(), options=options))


def test_a_reset_or_start_none_is_a_cold_start():
    solver = twoscale.ContactSolver()
    first = solver.solve(_scene())
    cold = solver.solve(_scene(), start=None)
    assert not cold.reuse.macro_start and cold.reuse.pressure_start == 0 and cold.reuse.body_kept
    assert cold.iterations["micro"] == first.iterations["micro"]
    solver.reset()
    assert solver.solve(_scene()).reuse.pressure_start == 0


def test_the_solver_prints_its_state_in_one_line():
    solver = twoscale.ContactSolver(max_cache_bytes=5e6)
    assert repr(solver) == "<ContactSolver twoscale: no body yet, 0 solves, caches 0.0 of 5 MB, no start kept>"
    second = [solver.solve(_scene()) for _ in range(2)][-1]
    text = repr(solver)
    # the figures of the last solve's own record, and the body as the results name it
    assert text.startswith(f"<ContactSolver twoscale: {second.body.label}, 2 solves, caches ")
    assert f"{second.reuse.cache_bytes / 1e6:.1f} of 5 MB, a start kept>" in text and "\n" not in text


def test_tips_entering_are_matched_by_index_and_unmatched_tips_start_cold():
    solver = twoscale.ContactSolver()
    full = _scene()
    solver.solve(dataclasses.replace(full, asperities=full.asperities[1:]))
    # one more tip and no index: no map between the tips, a cold start
    assert solver.solve(full).reuse.macro_start is False
    solver.solve(dataclasses.replace(full, asperities=full.asperities[1:]))
    entering = solver.solve(full, index=np.arange(-1, len(full.asperities) - 1))
    assert entering.reuse.macro_start and _close(entering, twoscale.solve(full))


def test_the_kept_pressure_and_the_caches_are_bounded():
    solver = twoscale.ContactSolver(max_start_bytes=0, max_cache_bytes=0)
    solver.solve(_scene())
    second = solver.solve(_scene())
    assert second.reuse.macro_start and second.reuse.pressure_start == 0 and second.reuse.kept_bytes < 1000
    assert second.reuse.cache_bytes == 0 and not second.reuse.operators_kept
    assert _close(second, twoscale.solve(_scene()))
    with pytest.raises(ValueError, match="max_cache_bytes must be a number >= 0"):
        twoscale.ContactSolver(max_cache_bytes=-1)


def test_options_reach_the_solve_and_a_cell_size_change_drops_the_pressure_start():
    solver = twoscale.ContactSolver(
        options=SolverOptions(micro=MicroOptions(iteration="block-gs"), resolution=ResolutionOptions(h=0.06))
    )
    r = solver.solve(dataclasses.replace(_scene(), h=None))
    assert r.details.micro.strategy == "block-gs" and r.fields[0].grid.h == pytest.approx(0.06)
    other = twoscale.ContactSolver(options=SolverOptions(resolution=ResolutionOptions(h=0.07)))
    other.solve(_scene())
    other._previous = dataclasses.replace(other._previous, h=0.08)  # as if the last solve ran at another h
    assert other.solve(_scene()).reuse.pressure_start == 0


def test_a_scene_for_another_body_is_refused():
    solver = twoscale.ContactSolver()
    solver.solve(_scene())
    block = dataclasses.replace(_scene(), influence=twoscale.scene.Influence(kind="block", size=(60, 60, 10)))
    with pytest.raises(ValueError, match="make another ContactSolver"):
        solver.solve(block)


@pytest.mark.parametrize("forget", ["reset", "start_none"])
def test_another_body_is_refused_after_the_start_is_forgotten(forget):
    """The body is kept whatever the start: after reset() (or a cold start), a block scene
    or another modulus is refused, not solved on the kept half-space."""
    solver = twoscale.ContactSolver()
    solver.solve(_scene())
    if forget == "reset":
        solver.reset()
    start = {"start": None} if forget == "start_none" else {}
    block = dataclasses.replace(_scene(), influence=twoscale.scene.Influence(kind="block", size=(60, 60, 10)))
    softer = dataclasses.replace(_scene(), material=twoscale.Material(_scene().material.E / 2, 0.5))
    for other in (block, softer):
        with pytest.raises(ValueError, match="make another ContactSolver"):
            solver.solve(other, **start)


@pytest.mark.parametrize(
    "bad, match",
    [
        ({"micro": {"tols": 1e-6}}, r"unknown option micro.tols \(did you mean 'tol'\?\)"),
        ({"mikro": {}}, r"unknown option group 'mikro' \(did you mean 'micro'"),
        ({"micro": {"iteration": "newton"}}, "micro.iteration must be one of"),
        ({"micro": {"far_tol": 2.0}}, r"micro.far_tol must be a number in \(0, 1\)"),
        ({"macro": {"max_iter": 0}}, "macro.max_iter must be an integer >= 1"),
        ({"resolution": {"h": -1}}, "resolution.h must be a finite number > 0"),
    ],
)
def test_bad_options_are_refused_naming_them(bad, match):
    with pytest.raises(ValueError, match=match):
        SolverOptions.from_mapping(bad)


def test_a_misspelt_keyword_of_solve_is_refused_naming_it():
    with pytest.raises(
        ValueError, match=r"unknown option 'iteraton' for the two-scale solver \(did you mean 'iteration'\?\)"
    ):
        twoscale.solve(_scene(), iteraton="block-gs")
    with pytest.raises(ValueError, match=r"unknown keyword 'tol' \(did you mean the option micro.tol\?"):
        twoscale.ContactSolver().solve(_scene(), tol=1e-7)
    with pytest.raises(ValueError, match=r"unknown keyword 'iteraton' \(did you mean the option micro.iteration\?"):
        twoscale.ContactSolver().solve(_scene(), iteraton="block-gs")
    with pytest.raises(ValueError, match=r"unknown keyword 'totl_load' \(did you mean 'total_load'\?\)"):
        twoscale.ContactSolver().solve(_scene(), totl_load=3.0)


def test_every_option_is_listed_documented_and_in_the_docs_table():
    rows = list_options()
    groups = {(o.group, o.name) for o in rows}
    for group, kind in (
        ("macro", twoscale.MacroOptions),
        ("micro", MicroOptions),
        ("reference", twoscale.ReferenceOptions),
        ("resolution", ResolutionOptions),
    ):
        assert {(group, f.name) for f in dataclasses.fields(kind)} <= groups
    assert all(o.doc for o in rows), [o.name for o in rows if not o.doc]
    page = Path(__file__).resolve().parents[1] / "docs" / "options.md"
    assert page.read_text() == options_markdown(), "docs/options.md is stale: regenerate it from options_markdown()"


def test_flat_keywords_map_to_the_groups():
    o = SolverOptions.from_keywords(tol=1e-7, macro_tol=1e-9, h=0.1)
    assert o.micro.tol == 1e-7 and o.macro.tol == 1e-9 and o.resolution.h == 0.1
    assert o.twoscale_keywords()["tol"] == 1e-7 and o.twoscale_keywords()["macro_tol"] == 1e-9


def test_a_group_prefix_on_a_flat_keyword_points_to_the_flat_name():
    with pytest.raises(ValueError, match=r"unknown option 'micro_tol' .*\(did you mean 'tol'\?\)"):
        twoscale.solve(_scene(), micro_tol=1e-7)


@pytest.mark.parametrize("far_tol", [None, 0.1])
def test_each_quantity_is_computed_once_per_solve(far_tol):
    """The Hertz level under load control (asked for by the cell size, the memory estimate,
    the resolution check and the nominal area), the memory check, each patch and the
    result are computed once per solve, by a solver object and one-shot, with and without
    the far field."""
    from unittest import mock

    import twoscale.driver as driver
    import twoscale.micro.patches as patches
    import twoscale.micro.sampling as sampling
    import twoscale.resolution as resolution
    import twoscale.resources as resources

    built = []
    real_make_patch = patches.make_patch

    def make_patch(k, grid, asperities):
        built.append((k, grid))
        return real_make_patch(k, grid, asperities)

    options = SolverOptions.from_keywords(far_tol=far_tol)
    solves = {
        "solver": lambda sc: twoscale.ContactSolver(options=options).solve(sc),
        "one-shot": lambda sc: twoscale.solve(sc, **options.twoscale_keywords()),
    }
    for how, solve in solves.items():
        scene = dataclasses.replace(_scene(), h=None)  # the cell size chosen from the scene
        with (
            mock.patch.object(resolution, "_solve_hertz_level", wraps=resolution._solve_hertz_level) as level,
            mock.patch.object(resources, "check_solve_memory", wraps=resources.check_solve_memory) as memory,
            mock.patch.object(patches, "make_patch", side_effect=make_patch),
            mock.patch.object(sampling, "make_patch", side_effect=make_patch),  # build_patches' own
            mock.patch.object(driver, "_result", wraps=driver._result) as result,
        ):
            r = solve(scene)
        assert (level.call_count, memory.call_count, result.call_count) == (1, 1, 1), how
        assert len(set(built)) == len(built) > 0, f"{how}: a patch was built twice"
        # None: the policy's coupling (on these ten scattered spheres the far field, which
        # it considers on a mostly empty box from two patches on); 0.1: the caller's
        expected = r.details.micro.choice.far_tol if far_tol is None else far_tol
        assert r.converged and r.details.micro.attempts[-1].far_tol == expected
        built.clear()


def test_the_command_line_builds_the_result_record_once(tmp_path, capsys):
    """``twoscale solve SCENE --out DIR`` writes result.json and prints the summary from one
    record."""
    from unittest import mock

    import twoscale.cli.solve as cli_solve
    from twoscale.cli.main import main

    scene = Path(__file__).resolve().parents[1] / "examples" / "paper_seven_spheres.toml"
    with mock.patch.object(cli_solve, "result_to_dict", wraps=cli_solve.result_to_dict) as record:
        assert main(["solve", str(scene), "--out", str(tmp_path / "out")]) == 0
    assert record.call_count == 1 and (tmp_path / "out" / "result.json").exists()
    assert "cell size" in capsys.readouterr().out
