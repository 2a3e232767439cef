"""A viscoelastic history on a small finite block (constant nu): the two-scale solver
against the reference with the same steps; the glassy instant against the elastic solve
on a block built at the glassy modulus (the block's compliance scales as 1 / E), the
long-time state against the elastic solve at the relaxed modulus."""

import numpy as np
import pytest

import twoscale
from twoscale.indenters import Asperity
from twoscale.material import Material
from twoscale.scene import Scene
from twoscale.viscoelastic import LoadHistory, TimeSteps, solve_history

fem_influence = pytest.importorskip("fem_influence")

SMALL = {"size": (60.0, 60.0, 10.0), "h_fine": 5.0, "h_coarse": 10.0, "fine_half_width": 10.0}
BODY = {"kind": "block", "size": (60.0, 60.0, 10.0)}
TIPS = (Asperity(0.0, 0.0, 0.0, 6.0), Asperity(5.0, 1.0, 0.02, 5.0), Asperity(-2.0, 5.0, 0.04, 5.0))


def _block(E):
    return fem_influence.BlockProvider(material=Material(E, 0.5), use_cache=False, progress=False, **SMALL)


def test_block_history():
    m = Material(3.0, 0.5, prony=((12.0, 0.1), (15.0, 10.0)))
    end = 3000.0  # retardation times up to ~100 s: relaxed at the end
    scene = Scene(
        m,
        TIPS,
        h=0.15,
        influence=BODY,
        history=LoadHistory("total", ((0.0, 6.0), (end, 6.0)), output=(0.0, 1.0, 100.0, end)),
    )
    block = _block(m.E)
    ts = solve_history(scene, method="twoscale", provider=block)
    ref = solve_history(scene, method="cg", provider=block, steps=TimeSteps(at=tuple(s.t for s in ts.steps)))
    assert np.abs(ts.forces - ref.forces).max() < 1e-5 * ref.forces.max()
    glassy = twoscale.solve(
        Scene(Material(m.E_glassy, 0.5), TIPS, h=0.15, total_load=6.0, influence=BODY), provider=_block(m.E_glassy)
    )
    assert ts.penetration[0] == pytest.approx(glassy.penetration, rel=1e-8)
    np.testing.assert_allclose(ts.forces[0], glassy.forces, rtol=1e-6)
    relaxed = twoscale.solve(Scene(m.relaxed(), TIPS, h=0.15, total_load=6.0, influence=BODY), provider=block)
    assert ts.penetration[-1] == pytest.approx(relaxed.penetration, rel=2e-3)
    assert np.abs(ts.forces[-1] - relaxed.forces).max() < 3e-3 * relaxed.forces.max()
