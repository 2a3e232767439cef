"""A stalled macro Newton on a small box defers its safe path (``policy.DEFER_SAFE_PATH_MAX_CELLS``):
the union CG solves the merged contacts from Newton's last iterate; another iteration picked
runs the safe path first, on patches sized as without the deferral.

Expected figures are the same scene solved with the deferral turned off (the safe path
taken at once), whose forces the sweep checked against the full-grid reference."""

import numpy as np
import pytest

import twoscale
import twoscale.micro.driver as micro_driver
import twoscale.micro.policy as policy
from twoscale.micro.policy import Choice
from twoscale.scenespace import build, sweep


#: An iteration named, so that the two-scale solver itself runs (49 spheres on #53's 11,880
#: cells would by default be their full grid's one CG); "auto" leaves the choice to the policy.
TWO_SCALE = {"iteration": "auto"}


def _scene(index: int):
    """The held-out sweep's scene ``index`` (seed 1)."""
    (spec,) = [s for s in sweep(200, 1) if s.index == index]
    return build(spec)


def _largest_difference(a, b) -> float:
    F, G = np.asarray(a.asperities.forces), np.asarray(b.asperities.forces)
    return float(np.max(np.abs(F - G)) / np.max(np.abs(G)))


@pytest.mark.parametrize("index", [53, 159])  # 49 merged spheres, penetration; 34 under load
def test_the_union_cg_solves_a_stalled_macro_step_without_its_safe_path(monkeypatch, index):
    scene = _scene(index)
    deferred = twoscale.solve(scene, **TWO_SCALE)
    assert deferred.converged and "safe path deferred" in deferred.message
    assert deferred.details.micro.strategy == "union-cg"
    monkeypatch.setattr(policy, "DEFER_SAFE_PATH_MAX_CELLS", 0)
    taken = twoscale.solve(scene, **TWO_SCALE)
    assert taken.converged and "deferred" not in taken.message
    assert taken.details.micro.strategy == "union-cg"
    assert _largest_difference(deferred, taken) <= 1e-7
    assert abs(deferred.penetration - taken.penetration) <= 1e-7 * abs(taken.penetration)


def test_an_unstable_equilibrium_still_takes_the_safe_path():
    # six paraboloids: Newton converges to a saddle, whose forces would size the box short
    result = twoscale.solve(_scene(180))
    assert result.converged and result.details.macro.converged and "deferred" not in result.message


def test_another_iteration_runs_the_deferred_safe_path_on_the_patches_its_forces_size(monkeypatch):
    # 49 merged spheres: Newton stalls at a residual of 6e-2, so the deferred step's patches
    # reach as far as each sphere can touch; block Gauss-Seidel, picked here, needs the safe
    # path's forces and their patches, as when nothing was deferred
    scene = _scene(53)
    picked = Choice("block-gs", None, "block Gauss-Seidel (picked by the test)", {})
    monkeypatch.setattr(micro_driver, "choose", lambda *args, **kw: picked)
    refined = twoscale.solve(scene, **TWO_SCALE)
    assert refined.converged and "deferred" not in refined.message
    assert refined.details.micro.strategy == "block-gs"
    assert refined.details.macro.converged  # the safe path ran: Newton alone stalls at 6e-2
    monkeypatch.setattr(policy, "DEFER_SAFE_PATH_MAX_CELLS", 0)
    taken = twoscale.solve(scene, **TWO_SCALE)
    assert [f.grid for f in refined.fields] == [f.grid for f in taken.fields]
    assert np.array_equal(refined.details.macro.forces, taken.details.macro.forces)
    assert _largest_difference(refined, taken) <= 1e-12


def test_the_deferral_counts_the_cells_of_every_tips_reach(monkeypatch):
    # the box of each tip's Asperity.reach at the approach (a sphere's cap at most R wide), in
    # cells of side h: deferred up to DEFER_SAFE_PATH_MAX_CELLS, not one cell more
    from twoscale.indenters import Asperity

    rng = np.random.default_rng(3)
    tips = [
        Asperity(float(x), float(y), float(z), float(r), shape=shape)
        for shape in ("sphere", "paraboloid")
        for x, y, z, r in rng.uniform([-3, -3, 0, 0.5], [3, 3, 1, 2], (20, 4))
    ]
    h = 0.01
    assert policy.safe_path_deferral(tips, h, 0.5, True) is None  # a free tilt sizes its box by the macro tilt
    for d in (0.3, 1.2, 3.0):  # the last beyond every sphere's radius
        reach = np.array([a.reach(d - a.z) for a in tips])
        on = reach > 0
        x, y = np.array([a.x for a in tips])[on], np.array([a.y for a in tips])[on]
        r = reach[on]
        cells = ((np.max(x + r) - np.min(x - r)) / h + 1) * ((np.max(y + r) - np.min(y - r)) / h + 1)
        for limit, expected in ((0.999 * cells, False), (1.001 * cells, True)):
            monkeypatch.setattr(policy, "DEFER_SAFE_PATH_MAX_CELLS", limit)
            assert policy.safe_path_deferral(tips, h, d, False)(np.zeros(0)) is expected
            assert policy.safe_path_deferral(tips, h, None, False)(np.array([d])) is expected  # load control
