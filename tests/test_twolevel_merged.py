"""The two-level iteration where contacts merge: the coarse step's compliance between
tips closer than their contacts, and the trial of a two-level attempt chosen by the policy.

Checks: the coarse system is positive definite for two tips closer than their contacts
(the point compliance alone makes it indefinite); a seeded 18-tip scene of merged contacts,
where the two-level iteration with far-field coupling used to cycle until its stall rule
stopped it, converges to the full-grid reference's forces; a two-level attempt on trial goes
on past its trial while its change falls fast, and stops at it otherwise.
"""

import numpy as np
import pytest
import scipy.sparse as sp

import twoscale
from twoscale import Material
from twoscale.driver import solve_twoscale
from twoscale.influence import HalfSpace
from twoscale.micro import driver
from twoscale.micro.coarse import CoarseSpace
from twoscale.micro.policy import Choice
from twoscale.micro.twolevel import SLOW_RATE, converging

from helpers import random_scene

MAT = Material(10.0, 0.5)
HS = HalfSpace(MAT)
MERGED = dict(h=0.15, total_load=108.0, tol=1e-8)


def test_coarse_system_stays_positive_definite_where_tips_meet():
    # two contacts of radius 0.1 mm whose tips are 0.01 mm apart: 1 / (pi E* r) is ten
    # times the patches' own compliance 1 / (2 a E*)
    tips = np.array([[0.0, 0.0], [0.01, 0.0], [3.0, 0.0]])
    lower = sp.csr_matrix(([1.0, 1.0, 1.0], ([1, 2, 2], [0, 0, 1])), shape=(3, 3))
    coarse = CoarseSpace(HS, tips, lower)
    kappa = np.full(3, 2.0 * 0.1 * MAT.E_star)
    point = np.array(HS.point_compliance(tips, tips), dtype=float)
    point[np.diag_indices(3)] = 1.0 / kappa
    assert np.linalg.eigvalsh(point).min() < 0.0
    near = coarse.near_correction(kappa).toarray()
    smeared = point + near + near.T
    assert np.linalg.eigvalsh(smeared).min() > 0.0
    # the far pair keeps its point compliance to 1e-3
    assert smeared[2, 0] == pytest.approx(point[2, 0], rel=1e-3)


def test_two_level_on_merged_contacts_reaches_the_full_grid_answer(monkeypatch):
    # seeded 18 tips, a third of them in tight pairs: with the point compliance between
    # merged tips the two-level iteration cycled (cells flipping) until its stall rule
    # stopped it. It needs about 8 sweeps (30 at 0.6 a sweep before the tight pairs were one
    # block each): chosen by the policy on a trial of 5 sweeps it goes on (a fixed cap
    # restarted block Gauss-Seidel from eq. 7)
    monkeypatch.setattr(driver, "TWO_LEVEL_SWEEPS", 5)
    monkeypatch.setattr(driver, "choose", lambda *a, **k: Choice("two-level", 0.05, "test", {"coverage": 0.0}))
    asps = random_scene(2, 18)
    res = solve_twoscale(HS, asps, max_sweeps=100, **MERGED)
    tried = res.details.micro.attempts
    assert res.converged and len(tried) == 1, res.message
    assert tried[0].iteration == "two-level" and tried[0].sweeps > 5
    ref = twoscale.solve(asps, method="reference", material=MAT, h=MERGED["h"], total_load=MERGED["total_load"])
    fe, fa = np.asarray(ref.asperities.forces), np.asarray(res.asperities.forces)
    assert np.max(np.abs(fa - fe)) <= 5e-3 * fe.max()


def test_converging_reads_the_rate_of_the_last_sweeps():
    fast = [0.1 * 0.6**k for k in range(8)]
    slow = [0.1 * (SLOW_RATE + 0.05) ** k for k in range(8)]
    assert converging(fast) and not converging(slow)
    assert not converging(fast[:3])  # too few sweeps to read a rate
    assert not converging([1e-3, 1e-3, 2e-3, 4e-3, 8e-3])


@pytest.mark.slow
def test_a_slow_two_level_trial_ends_at_its_trial(monkeypatch):
    # the same scene held to a rate it cannot show: the attempt ends at its trial and block
    # Gauss-Seidel with the same far field decides (the tight pairs as separate blocks, as
    # before they were merged: about 30 sweeps at 0.6)
    from twoscale.micro import setup, twolevel, workset

    apart = lambda patches, p, only=None: [[k] for k in range(len(patches))]  # noqa: E731
    monkeypatch.setattr(setup, "touching_groups", apart)
    monkeypatch.setattr(workset, "touching_groups", apart)

    monkeypatch.setattr(twolevel, "SLOW_RATE", 0.1)
    monkeypatch.setattr(driver, "TWO_LEVEL_SWEEPS", 6)
    monkeypatch.setattr(driver, "choose", lambda *a, **k: Choice("two-level", 0.05, "test", {"coverage": 0.0}))
    res = solve_twoscale(HS, random_scene(2, 18), max_sweeps=100, **MERGED)
    first, second = res.details.micro.attempts
    assert first.iteration == "two-level" and not first.converged and first.sweeps == 6
    assert "trial" in first.message
    assert second.iteration == "block-gs" and res.converged
