"""Running studies: Dask against one-by-one solves, Hertz, resume, interruption, failures.

The scene: two paraboloids (R = 10 mm) 6 mm apart on a half-space (E = 10 MPa, nu = 0.5)
under penetration control. Body "both" sees both tips; body "left" is a window around the
left tip only, so there the left tip is alone: Hertz's closed form.
"""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from twoscale.analytic import hertz
from twoscale.cli.main import main
from twoscale.material import Material
from twoscale.api import solve_scene
from twoscale.studies import execute
from twoscale.studies.cases import case_scene, expand
from twoscale.studies.execute import run_study
from twoscale.studies.keys import case_key
from twoscale.studies.outputs import write_outputs
from twoscale.studies.spec import read_study
from twoscale.studies.store import CaseStore

from helpers import paraboloid_scene

SCENE = paraboloid_scene([-3.0, 3.0])

STUDY = """
[study]
name = "two tips"
[[scene]]
file = "scene.toml"
name = "pair"
[[body]]
name = "both"
kind = "halfspace"
[[body]]
name = "left"
kind = "halfspace"
window = [3.0, 3.0]
centre = [-3.0, 0.0]
[load]
penetration = [0.05, 0.1]
[positions]
shifts = [[0.0, 0.0], [0.5, 0.0]]
"""


@pytest.fixture
def study(tmp_path):
    (tmp_path / "scene.toml").write_text(SCENE, encoding="utf-8")
    path = tmp_path / "study.toml"
    path.write_text(STUDY, encoding="utf-8")
    return read_study(path)


def _forces(store, key):
    return np.array(store.read(key)["result"]["forces"])


def test_dask_cluster_gives_the_one_by_one_numbers(study, tmp_path):
    run = run_study(study, tmp_path / "out", workers=2, batch=3, quiet=True)  # tasks of 3, 3 and 2 cases
    assert run.ran == 8 and run.skipped == 0 and "2 workers" in run.where
    store = CaseStore(tmp_path / "out")
    for case, key in zip(expand(study), run.keys):
        alone = solve_scene(case_scene(case, study))  # the public solver, one case
        assert store.status(key) == "converged"
        np.testing.assert_allclose(_forces(store, key), alone.asperities.forces, rtol=1e-12, atol=1e-12)


def test_results_against_hertz_and_translation_invariance(study, tmp_path):
    run = run_study(study, tmp_path / "out", quiet=True)
    store = CaseStore(tmp_path / "out")
    E_star = Material(10.0, 0.5).E_star
    by = {(c.body.name, c.load[1], c.position): _forces(store, k) for c, k in zip(expand(study), run.keys)}
    for d in (0.05, 0.1):
        P_hertz = float(hertz.load(10.0, d, E_star))
        for p in (0, 1):
            # the left tip alone on the half-space: Hertz, to the discretisation (h = 0.1 mm,
            # 14-20 cells across the contact)
            assert by["left", d, p] == pytest.approx([P_hertz], rel=0.015)
            # with its neighbour 6 mm away, the neighbour's displacement lowers its force
            assert by["both", d, p][0] < by["left", d, p][0]
        # the half-space has no position: a shift of both tips changes nothing (to the solver tol)
        np.testing.assert_allclose(by["both", d, 1], by["both", d, 0], rtol=1e-6)  # solver tol 1e-6


def test_resume_skips_finished_cases(study, tmp_path, monkeypatch):
    out = tmp_path / "out"
    calls = []
    real = execute.solve_ref

    def interrupted(study_, ref, key, providers):
        if len(calls) == 3:
            raise KeyboardInterrupt
        calls.append(key)
        return real(study_, ref, key, providers)

    monkeypatch.setattr(execute, "solve_ref", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_study(study, out, quiet=True)
    store = CaseStore(out)
    finished = [k for k in dict.fromkeys(case_key(c, study) for c in expand(study)) if store.finished(k)]
    assert finished == calls  # the cases done before Ctrl-C are intact
    stamps = {k: os.stat(store.path(k) / "case.json").st_mtime_ns for k in finished}
    (store.folder / f".{calls[0]}.tmp-left").mkdir()  # what an interrupted write leaves
    monkeypatch.setattr(execute, "solve_ref", real)
    run = run_study(study, out, quiet=True)
    assert (run.ran, run.skipped) == (5, 3)
    assert {k: os.stat(store.path(k) / "case.json").st_mtime_ns for k in finished} == stamps
    assert not any(p.name.startswith(".") for p in store.folder.iterdir())
    assert run_study(study, out, quiet=True).ran == 0


def test_failing_case_is_recorded_and_others_run(study, tmp_path, capsys):
    text = STUDY.replace("[[0.0, 0.0], [0.5, 0.0]]", "[[0.0, 0.0], [5.0, 0.0]]")  # 5 mm: no tip in "left"
    path = tmp_path / "study.toml"
    path.write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["study", str(path), "--out", str(out), "--workers", "0", "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "pair left penetration=0.05 p1 failed" in err and "no tip lies in the footprint" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["counts"] == {"converged": 6, "not-converged": 0, "failed": 2, "missing": 0}
    assert all("no tip lies in the footprint" in f["reason"] for f in summary["failed"])
    # failed cases are solved again by a rerun; the finished ones are not
    assert main(["study", str(path), "--out", str(out), "--workers", "0", "--quiet"]) == 1
    assert json.loads((out / "summary.json").read_text())["run"]["ran"] == 2


def test_outputs_tables_and_figures(study, tmp_path):
    pa = pytest.importorskip("pyarrow.parquet")
    out = tmp_path / "out"
    run = run_study(study, out, quiet=True)
    summary = write_outputs(out, study, run)
    assert summary["counts"]["converged"] == 8
    cases = pa.read_table(out / "cases.parquet").to_pylist()
    tips = pa.read_table(out / "asperities.parquet").to_pylist()
    assert len(cases) == 8 and len(tips) == 4 * 2 + 4 * 1  # "both": 2 tips, "left": 1
    for c in cases:  # each case's total is the sum of its tips' forces
        assert c["total_load_N"] == pytest.approx(sum(t["force_N"] for t in tips if t["key"] == c["key"]), rel=1e-9)
    assert (out / "cases.csv").read_text().splitlines()[0].startswith("scene,body,load_kind,load,position")
    ind = pa.read_table(out / "indicators.parquet").to_pylist()
    assert {(r["reference"], r["body"]) for r in ind} == {("both", "left")} and len(ind) == 4
    for r in ind:  # e_M of "left" against "both": the right tip is missing from "left"
        both = {
            t["asperity"]: t["force_N"]
            for t in tips
            if (t["body"], t["load"], t["position"]) == ("both", r["load"], r["position"])
        }
        left = {
            t["asperity"]: t["force_N"]
            for t in tips
            if (t["body"], t["load"], t["position"]) == ("left", r["load"], r["position"])
        }
        # tips numbered from 1, as in the scene file
        expected = 100 * ((left[1] - both[1]) ** 2 + both[2] ** 2) / (both[1] ** 2 + both[2] ** 2)
        assert r["e_M_percent"] == pytest.approx(expected, rel=1e-9)
    names = sorted(p.name for p in (out / "figures").iterdir())
    assert names == [
        "asperity_forces_pair_both.png",
        "asperity_forces_pair_left.png",
        "indicators_pair.png",
        "load_approach_pair.png",
        "track_pair_both.png",
        "track_pair_left.png",
    ]


def test_existing_scheduler_and_the_reference_method(tmp_path):
    """``scheduler=ADDRESS`` runs on a cluster the caller started; ``method = "reference"``
    solves each case on the full grid, agreeing with the two-scale cases to the
    discretisation."""
    import logging

    from distributed import LocalCluster

    (tmp_path / "scene.toml").write_text(SCENE, encoding="utf-8")
    text = STUDY.replace('name = "two tips"', 'name = "ref"\nmethod = "reference"')
    text = text.replace("penetration = [0.05, 0.1]", "penetration = [0.1]").replace(
        "[[0.0, 0.0], [0.5, 0.0]]", "[[0.0, 0.0]]"
    )
    (tmp_path / "ref.toml").write_text(text, encoding="utf-8")
    ref = read_study(tmp_path / "ref.toml")
    (tmp_path / "ts.toml").write_text(text.replace('method = "reference"', ""), encoding="utf-8")
    ts = read_study(tmp_path / "ts.toml")
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None, silence_logs=logging.ERROR
    ) as cluster:
        run = run_study(ref, tmp_path / "out", scheduler=cluster.scheduler_address, quiet=True)
    assert run.where == cluster.scheduler_address and run.ran == 2
    run_ts = run_study(ts, tmp_path / "out", quiet=True)
    assert set(run_ts.keys).isdisjoint(run.keys)  # the method is an input
    store = CaseStore(tmp_path / "out")
    for k_ref, k_ts in zip(run.keys, run_ts.keys):
        np.testing.assert_allclose(_forces(store, k_ref), _forces(store, k_ts), rtol=5e-3)


def test_non_converged_case_is_recorded_with_the_solver_message(tmp_path, capsys):
    (tmp_path / "scene.toml").write_text(SCENE, encoding="utf-8")
    text = STUDY + '[solver]\niteration = "block-gs"\nmax_sweeps = 1\ntol = 1e-14\n'
    text = text.replace("[[0.0, 0.0], [0.5, 0.0]]", "[[0.0, 0.0]]").replace(
        "penetration = [0.05, 0.1]", "penetration = [0.1]"
    )
    (tmp_path / "study.toml").write_text(text, encoding="utf-8")
    out = tmp_path / "out"
    assert main(["study", str(tmp_path / "study.toml"), "--out", str(out), "--workers", "0", "--quiet"]) == 1
    summary = json.loads((out / "summary.json").read_text())
    assert summary["counts"]["not-converged"] == 2
    assert all("reached 1 sweeps" in c["reason"] for c in summary["not_converged"])
    assert "did not converge: block Gauss-Seidel reached 1 sweeps" in capsys.readouterr().err
    # a result that did not converge is a result: a rerun does not solve it again
    assert main(["study", str(tmp_path / "study.toml"), "--out", str(out), "--workers", "0", "--quiet"]) == 1
    assert json.loads((out / "summary.json").read_text())["run"]["ran"] == 0


@pytest.mark.slow
def test_the_example_study_runs(tmp_path, examples_dir):
    """The README's tour step: the shipped example on a 2-worker cluster (builds the
    block's correction the first time: up to a minute)."""
    out = tmp_path / "s2_study"
    assert main(["study", str(examples_dir / "study.toml"), "--out", str(out), "--workers", "2", "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["counts"]["converged"] == 12
    for c in json.loads((out / "summary.json").read_text())["indicators_percent"]:
        assert 0 < c["e_M_percent"] < 5  # block against half-space: close, not equal
    assert len(list((out / "figures").glob("*.png"))) == 6


def test_unreachable_scheduler_exits_2(study, tmp_path, capsys, monkeypatch):
    from twoscale.studies import execute as ex

    real = ex.run_study
    monkeypatch.setattr("twoscale.studies.execute.run_study", lambda *a, **k: real(*a, **{**k, "timeout": 1.0}))
    out = tmp_path / "out"
    assert main(["study", study.source, "--out", str(out), "--scheduler", "tcp://127.0.0.1:1", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--scheduler 'tcp://127.0.0.1:1' cannot be reached" in err
    assert not out.exists()


def test_study_folder_is_refused_unless_it_is_this_studys(study, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "asperities.csv").write_text("my own table\n", encoding="utf-8")  # a user's file
    assert main(["study", study.source, "--out", str(out), "--workers", "0", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is no twoscale study folder" in err
    assert (out / "asperities.csv").read_text() == "my own table\n"  # untouched
    fresh = tmp_path / "fresh"
    assert main(["study", study.source, "--out", str(fresh), "--workers", "0", "--quiet"]) == 0
    cases = {p.name for p in (fresh / "cases").iterdir()}
    assert main(["study", study.source, "--out", str(fresh), "--workers", "0", "--quiet"]) == 0  # resume
    # another study (one load only) into that folder: refused, then replaced with --overwrite
    other = tmp_path / "other.toml"
    other.write_text(
        STUDY.replace("penetration = [0.05, 0.1]", "penetration = [0.05]").replace(
            'name = "two tips"', 'name = "half"'
        ),
        encoding="utf-8",
    )
    capsys.readouterr()
    assert main(["study", str(other), "--out", str(fresh), "--workers", "0", "--quiet"]) == 2
    assert "holds another study ('two tips')" in capsys.readouterr().err
    assert main(["study", str(other), "--out", str(fresh), "--workers", "0", "--quiet", "--overwrite"]) == 0
    summary = json.loads((fresh / "summary.json").read_text())
    assert summary["run"]["ran"] == 0 and summary["cases"] == 4  # its 4 cases were among the 8 kept
    assert {p.name for p in (fresh / "cases").iterdir()} == cases


def test_contact_box_covers_the_tips_reach(study):
    # the box the block warm-up asks the correction for: every tip and its contact inside
    from twoscale.scene import expected_contact_radii
    from twoscale.studies.providers import contact_box

    scene = case_scene(expand(study)[0], study)
    x0, x1, y0, y1 = contact_box(scene)
    for (x, y), a in zip(scene.tips, expected_contact_radii(scene)):
        assert x0 <= x - a and x + a <= x1 and y0 <= y - a and y + a <= y1
