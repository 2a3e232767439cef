"""The two-level iteration's growth check before a round converges.

A round of sweeps asks :attr:`SweepLimits.early_growth` once its change is at most
:data:`EARLY_GROWTH_CHANGE`; a True answer ends the round as the caller's ``stop`` does, so
the patches grow before the round converges on the old ones. Checks: the verdict asks it
only below that change and not once converged, with the sweep's pressures and approach;
and on a scene whose patches must grow (an asperity penetrating outside its block), the
solve that grows early reaches the same tip forces as the one that grows only at
convergence, within the iteration's tolerance, in fewer sweeps, and both the full-grid
reference's within the far field's accuracy.
"""

import numpy as np

from twoscale.micro import twolevel
from twoscale.micro.twolevel import EARLY_GROWTH_CHANGE, SweepLimits, verdict
from twoscale.stopping import StopReason


def test_the_check_is_asked_below_its_change_and_ends_the_round():
    asked = []

    def early(p, theta):
        asked.append((p, theta))
        return True

    limits = SweepLimits(tol=1e-6, max_sweeps=50, early_growth=early)
    p, theta = [np.ones(3)], np.array([0.01, 0.0, 0.0])
    # above the change: the round goes on, nothing asked
    assert verdict([0.5, 2.0 * EARLY_GROWTH_CHANGE], True, limits, 2, p, theta) is None
    assert asked == []
    # at or below it: asked with the sweep's pressures and approach; True stops the round
    message, reason, converged = verdict([0.5, 0.5 * EARLY_GROWTH_CHANGE], True, limits, 2, p, theta)
    assert (message, reason, converged) == ("stopped", StopReason.STOPPED, False)
    assert len(asked) == 1 and asked[0][0] is p and asked[0][1] is theta
    # converged: the round ends as converged, the check left to the round's end
    assert verdict([0.5, 1e-7], False, limits, 2, p, theta)[1] is StopReason.CONVERGED
    assert len(asked) == 1
    # a False answer: the round goes on
    quiet = SweepLimits(tol=1e-6, max_sweeps=50, early_growth=lambda p, theta: False)
    assert verdict([0.5, 1e-4], True, quiet, 2, p, theta) is None


def _solve(scene, monkeypatch, early: bool):
    """The default solve of ``scene`` with the two-level iteration forced (far field 0.3),
    the growth checked early or (``early`` False: never below any change) only at a round's
    end; returns the result and the early check's answers."""
    import twoscale
    from twoscale.micro import block_iterations

    answers = []
    ask = block_iterations.EarlyGrowth.__call__

    def spy(self, p, theta):
        answers.append(ask(self, p, theta))
        return answers[-1]

    with monkeypatch.context() as m:
        m.setattr(block_iterations.EarlyGrowth, "__call__", spy)
        m.setattr(twolevel, "EARLY_GROWTH_CHANGE", EARLY_GROWTH_CHANGE if early else -1.0)
        res = twoscale.solve(scene, iteration="two-level", far_tol=0.3)
    return res, answers


def test_patches_grown_early_give_the_converged_forces(monkeypatch):
    import twoscale
    from twoscale.scenespace import build, sweep

    # 9 paraboloids under penetration control (the sweep's seed 0, #46): an asperity
    # penetrates outside its block after the first sweeps, found at convergence otherwise
    (spec,) = [s for s in sweep(200, 0) if s.index == 46]
    scene = build(spec)
    early, asked = _solve(scene, monkeypatch, early=True)
    late, never = _solve(scene, monkeypatch, early=False)
    assert True in asked and never == []
    assert early.converged and late.converged
    assert early.iterations["micro"] < late.iterations["micro"]
    fe, fl = (np.asarray(r.asperities.forces) for r in (early, late))
    # the same patches at the end: the same fixed point, within the sweeps' tolerance (1e-6)
    assert np.max(np.abs(fe - fl)) <= 1e-5 * np.max(fl)
    assert abs(fe.sum() - fl.sum()) <= 1e-6 * fl.sum()
    ref = np.asarray(twoscale.solve(scene, method="reference").asperities.forces)
    # the far field's error against the full grid's CG at the same h (3.1e-5 either way)
    assert np.max(np.abs(fe - ref)) <= 1e-4 * np.max(ref)
