"""Validation of the finite-block provider on the paper's 140 x 140 x 20 mm block.

Figures from docs/method.md section 6 / issue 4 (point force at the centre, nu = 0.5,
surface displacement over Boussinesq's): bonded 0.57, 0.22, -0.13 and sliding 0.71,
0.46, 0.13 at r = 5, 10, 20 mm, +-0.02; and the independent layer theory
(:mod:`fem_influence.layer`, Hankel transform) for an infinite layer. All slow
(one Q2-Q1 factorisation of ~39k unknowns each, 10-30 s on this machine).
"""
import numpy as np
import pytest

from fem_influence import BlockProvider
from fem_influence.layer import point_ratio
from meshes import block_mesh
from twoscale.material import Material

pytestmark = pytest.mark.slow

MAT = Material(E=1.0, nu=0.5)
R = np.array([5.0, 10.0, 20.0])


def _ratios(provider, r=R):
    tgt = np.column_stack([r, 0 * r])
    u = provider.point_compliance(tgt, np.zeros((1, 2)))[:, 0]
    return u * np.pi * provider.material.E_star * r


@pytest.fixture(scope="module")
def bonded():
    return BlockProvider(material=MAT, base="bonded", use_cache=False, progress=False)


@pytest.fixture(scope="module")
def sliding():
    return BlockProvider(material=MAT, base="sliding", use_cache=False, progress=False)


def test_bonded_targets(bonded):
    np.testing.assert_allclose(_ratios(bonded), [0.57, 0.22, -0.13], atol=0.02)


def test_bonded_against_layer_theory(bonded):
    # sides 3.5 thicknesses away: the block centre behaves as the infinite layer
    np.testing.assert_allclose(_ratios(bonded), point_ratio(R, 20.0, 0.5, "bonded"), atol=0.01)


def test_sliding_targets_near(sliding):
    np.testing.assert_allclose(_ratios(sliding, R[:2]), [0.71, 0.46], atol=0.02)


@pytest.mark.xfail(strict=True, reason="measured 0.153 on the 140 mm block: the free sides of the "
                   "sliding block add compliance at 20 mm; a 280 mm block gives 0.135 "
                   "(test_sliding_wide_block_is_the_layer), layer theory 0.129")
def test_sliding_target_far(sliding):
    assert _ratios(sliding, R[2:])[0] == pytest.approx(0.13, abs=0.02)


def test_sliding_wide_block_is_the_layer():
    wide = BlockProvider(material=MAT, base="sliding", size=(280.0, 280.0, 20.0), h_coarse=20.0,
                         use_cache=False, progress=False)
    np.testing.assert_allclose(_ratios(wide), point_ratio(R, 20.0, 0.5, "sliding"), atol=0.01)


def test_nu_half_against_nearly_half(bonded):
    near = BlockProvider(material=Material(1.0, 0.4999), base="bonded", use_cache=False, progress=False)
    np.testing.assert_allclose(_ratios(near), _ratios(bonded), rtol=5e-3)


def test_correction_vanishes_as_block_grows(bonded):
    # scale the whole block (and its mesh) by s: C at a fixed 5 mm offset must fall
    # like 1/s (dimensional analysis: C = f(r/s) / (E s), f smooth at 0)
    c = [bonded.correction(np.array([[5.0, 0.0]]), np.zeros((1, 2)))[0, 0]]
    scales = [1.0, 2.0, 4.0]
    for s in scales[1:]:
        big = BlockProvider(material=MAT, size=(140.0 * s, 140.0 * s, 20.0 * s), h_fine=5.0 * s,
                            h_coarse=12.0 * s, fine_half_width=25.0 * s, source_spacing=5.0 * s,
                            use_cache=False, progress=False)
        c.append(big.correction(np.array([[5.0, 0.0]]), np.zeros((1, 2)))[0, 0])
    rate = np.polyfit(np.log(scales), np.log(np.abs(c)), 1)[0]
    print(f"|C(5 mm)| for block scale {scales}: {np.abs(c)}; rate {rate:.3f}")
    assert rate == pytest.approx(-1.0, abs=0.1)
    assert np.all(np.diff(np.abs(c)) < 0)
