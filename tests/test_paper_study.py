"""The paper's numerical study (docs/method.md section 4) and the ``twoscale paper`` command.

Acceptance: ``100 ||p - p_r|| / ||p_r|| <= 0.1`` for every d/2R against the
reference solver on the same lattice; the eq. 7 error ``100 ||p0 - p_r|| / ||p_r||`` grows
as the spheres approach; sweeps are reported. The quick setting (cells twice the paper's)
runs by default; the paper's cell sizes are marked slow.
"""

import csv
import json
import math

import numpy as np
import pytest
from tidy_tables import assert_tidy

from twoscale.cli.main import main
from twoscale.paper import PAPER_SPACINGS, paper_case, reference_surface, run_study


@pytest.fixture(scope="module")
def quick_study():
    return run_study(quick=True)


def _check_acceptance(study):
    for layout, results in study.cases.items():
        assert [r.case.spacing for r in results] == list(PAPER_SPACINGS[layout])
        for r in results:
            assert r.twoscale.converged, r.twoscale.message
            assert r.ref.converged, r.ref.message
            assert r.err_p_percent <= 0.1, (layout, r.case.spacing, r.err_p_percent)
            assert r.sweeps >= 1
        e0 = [r.err_p0_percent for r in results]
        # the eq. 7 start drifts from p_r as the spheres approach (spacings are increasing)
        assert all(a > b for a, b in zip(e0, e0[1:])), (layout, e0)
        assert e0[0] > 10.0 and e0[-1] < 1.0


def test_quick_study_meets_the_acceptance(quick_study):
    _check_acceptance(quick_study)


@pytest.mark.slow
def test_full_study_meets_the_acceptance():
    _check_acceptance(run_study(quick=False))


def test_far_spheres_are_hertzian(quick_study):
    # d/2R = 5: each sphere is nearly alone; its force is the exact-sphere (Segedin) law
    # with the small Boussinesq interaction of the others, within the discretisation
    from twoscale.analytic import hertz

    r = quick_study.cases["two"][-1]
    c = r.case
    P1 = float(hertz.sphere_load(c.R, c.penetration, c.material.E_star))
    assert r.twoscale.asperities.forces == pytest.approx([P1, P1], rel=0.02)


def test_cases_follow_the_paper():
    two = paper_case("two", 0.25)
    assert math.hypot(
        two.asperities[0].x - two.asperities[1].x, two.asperities[0].y - two.asperities[1].y
    ) == pytest.approx(0.25 * 2 * 10.0)
    assert two.h == pytest.approx(0.0125 * 10.0) and two.penetration == pytest.approx(0.05 * 10.0)
    seven = paper_case("seven", 0.5)
    r = [math.hypot(a.x, a.y) for a in seven.asperities]
    assert r[0] == 0.0 and np.allclose(r[1:], 0.5 * 2 * 10.0)
    assert seven.h == pytest.approx(0.025 * 10.0) and seven.penetration == pytest.approx(1.0)
    assert seven.asperities[seven.upper].y == pytest.approx(10.0)
    # the reference grid is on the two-scale's lattice and covers each sphere's reach
    s = reference_surface(seven)
    for v in (s.grid.x0, s.grid.y0):  # lattice anchored at the origin, like the patches
        assert abs(v / s.grid.h - round(v / s.grid.h)) < 1e-9
    reach = math.sqrt(seven.penetration * (2 * seven.R - seven.penetration))
    xmin, xmax, ymin, ymax = s.grid.bounds
    assert xmin < -10.0 * math.cos(math.pi / 6) - reach and ymax > 10.0 + reach
    with pytest.raises(ValueError, match="layout"):
        paper_case("three", 0.5)


def test_paper_command_writes_csv_and_figures(tmp_path, capsys):
    pytest.importorskip("matplotlib")
    code = main(["paper", "--out", str(tmp_path), "--quick"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "PASS" in out
    for name in (
        "errors_two.csv",
        "errors_seven.csv",
        "profile_two.csv",
        "profile_seven.csv",
        "map_two_0.1.csv",
        "map_seven_0.2.csv",
        "fig3_two_maps.png",
        "fig4_seven_maps.png",
        "fig5_profiles.png",
        "fig6_errors.png",
    ):
        assert (tmp_path / name).stat().st_size > 0, name
    for path in tmp_path.glob("*.csv"):  # every table opens with pandas and csv, no options
        assert_tidy(path)
    with open(tmp_path / "errors_seven.csv", newline="", encoding="utf-8") as fh:  # header first
        rows = list(csv.DictReader(fh))
    assert json.loads((tmp_path / "errors_seven.csv-metadata.json").read_text())["twoscale"]["parameters"]["R_mm"] > 0
    assert [float(r["d_over_2R"]) for r in rows] == list(PAPER_SPACINGS["seven"])
    assert all(float(r["err_p_percent"]) <= 0.1 and int(r["sweeps"]) >= 1 for r in rows)
    # the paper: fewer than 10 sweeps; the closest spheres are one block, the farthest seven
    assert all(int(r["sweeps"]) < 10 for r in rows), [r["sweeps"] for r in rows]
    assert int(rows[0]["blocks"]) == 1 and int(rows[-1]["blocks"]) == 7


def test_paper_command_rejects_bad_tolerance(tmp_path, capsys):
    assert main(["paper", "--out", str(tmp_path), "--tol", "-1"]) == 2
    assert "tol" in capsys.readouterr().err


def _paper_with(study, monkeypatch, tmp_path, capsys, *extra):
    """Run ``twoscale paper`` on an already computed study; (exit code, stdout, stderr, run_study kwargs)."""
    import twoscale.paper

    calls = []
    monkeypatch.setattr(twoscale.paper, "run_study", lambda **kw: calls.append(kw) or study)
    code = main(["paper", "--out", str(tmp_path), "--quick", "--no-figures", *extra])
    cap = capsys.readouterr()
    return code, cap.out, cap.err, calls[0]


def test_paper_quiet_prints_nothing_and_still_writes(quick_study, monkeypatch, tmp_path, capsys):
    code, out, err, kw = _paper_with(quick_study, monkeypatch, tmp_path / "q", capsys, "--quiet")
    assert code == 0 and out == "" and err == ""
    assert not kw["progress"].enabled  # no status line either
    assert (tmp_path / "q" / "errors_two.csv").stat().st_size > 0
    # without --quiet: the table and the acceptance, and a progress callback
    code, out, err, kw = _paper_with(quick_study, monkeypatch, tmp_path / "loud", capsys)
    assert code == 0 and "PASS" in out and callable(kw["progress"])


def test_paper_quiet_still_warns_about_a_missed_case(quick_study, monkeypatch, tmp_path, capsys):
    import dataclasses

    two = list(quick_study.cases["two"])
    two[0] = dataclasses.replace(two[0], err_p_percent=0.5)
    study = dataclasses.replace(quick_study, cases={**quick_study.cases, "two": two})
    code, out, err, _ = _paper_with(study, monkeypatch, tmp_path, capsys, "--quiet")
    assert code == 1 and out == ""
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("warning: two d/2R=") and "0.5 > 0.1" in lines[0], err
