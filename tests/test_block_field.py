"""The block's displacement field: BlockProvider.displacement_field and ``solve --block-field``.

A 60 x 60 x 10 mm block meshed at 5-10 mm keeps this to seconds. Checks against
independent quantities: the provider's own surface compliance (the same correction
reached by a different path: top-face interpolant of per-lattice fields vs one combined
volume solve), the bonded base condition u = 0 (the field must cancel the Boussinesq
displacement there), and a round trip of the .vtu file through meshio.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("skfem")
pytest.importorskip("meshio")

from fem_influence import BlockProvider
from fem_influence.boussinesq import point_displacement
from twoscale.cli.main import main
from twoscale.io.block_field import BLOCK_FIELD_NAME, read_block_field
from twoscale.material import Material

MAT = Material(E=2.0, nu=0.5)
SMALL = dict(size=(60.0, 60.0, 10.0), h_fine=5.0, h_coarse=10.0, fine_half_width=10.0)


@pytest.fixture(scope="module")
def block():
    return BlockProvider(material=MAT, use_cache=False, progress=False, **SMALL)


def patch_load(total=1.0, half=1.0, step=0.2):
    """Uniform point forces on a square patch around (0.3, -0.2), N."""
    xs = np.arange(-half, half + 1e-9, step)
    X, Y = np.meshgrid(xs + 0.3, xs - 0.2)
    P = np.column_stack([X.ravel(), Y.ravel()])
    return P, np.full(len(P), total / len(P))


def far_top(points, loads, r_min=15.0, inner=22.0):
    """Top-face vertices farther than r_min from every load and inside the lattice."""
    d = np.min(np.hypot(points[:, None, 0] - loads[None, :, 0], points[:, None, 1] - loads[None, :, 1]), axis=1)
    return np.where((points[:, 2] == 0) & (d > r_min) & (np.abs(points[:, :2]).max(axis=1) < inner))[0]


def test_surface_matches_point_compliance_without_aggregation(block):
    # aggregate = 0: the same point forces on both sides; at vertices the Q2 top
    # interpolant is exact and the combined solve is the same linear problem, so only
    # the solver residual (1e-10 relative) separates them
    P, f = patch_load()
    fld = block.displacement_field(P, f, aggregate=0.0)
    idx = far_top(fld.points, P)
    assert len(idx) >= 8
    expect = block.point_compliance(fld.points[idx, :2], P) @ f
    np.testing.assert_allclose(fld.displacement[idx, 2], expect, rtol=1e-6)


def halfspace_scale(W, r):
    """Boussinesq surface displacement W / (pi E* r), mm: the scale of the far-field errors."""
    return W * (1.0 - MAT.nu**2) / (np.pi * MAT.E * r)


def test_far_surface_displacement_is_compliance_times_total_force(block):
    # one force W at the centre of force c instead of the patch: the neglected quadrupole
    # term of the 1/r kernel is at most (s / r)^2 u_B(r) (s^2 = second moment of the load
    # about c; Legendre P2 <= 1); the smooth correction varies on the thickness scale and
    # measured 0.4 of that bound. 1 mm aggregates add at most (a / r)^2 u_B with a = 1 mm.
    # (Compared with u_B, not with the total: on a thin bonded block the total changes
    # sign near r = 2 t, where a relative error is meaningless.)
    P, f = patch_load(total=3.0, half=2.0)
    fld = block.displacement_field(P, f, aggregate=1.0)
    c = (f @ P) / f.sum()
    s2 = float(f @ np.sum((P - c) ** 2, axis=1) / f.sum())
    idx = far_top(fld.points, P)
    r = np.hypot(*(fld.points[idx, :2] - c).T)
    expect = block.point_compliance(fld.points[idx, :2], c[None, :])[:, 0] * f.sum()
    err = np.abs(fld.displacement[idx, 2] - expect)
    assert np.all(err <= (s2 + 1.0) / r**2 * halfspace_scale(f.sum(), r)), err.max()
    assert fld.total_force == pytest.approx(3.0)


def test_bonded_base_does_not_move(block):
    # bonded base: u_Boussinesq + u_correction = 0 there, up to the cubic source-lattice
    # interpolation of the base data (1.3 % of the correction at spacing / thickness 0.5,
    # docs/records/fem_status.md): a sign or frame error would leave |u| ~ |u_B|
    P, f = patch_load()
    fld = block.displacement_field(P, f, aggregate=0.0)
    base = fld.points[:, 2] == fld.points[:, 2].max()
    central = base & (np.abs(fld.points[:, :2]).max(axis=1) < 20)
    uB = fld.halfspace[central]
    assert np.abs(uB).max() > 0
    assert np.abs(fld.displacement[central]).max() <= 0.02 * np.abs(uB).max()


def test_halfspace_part_is_boussinesq(block):
    P = np.array([[1.0, 2.0]])
    fld = block.displacement_field(P, np.array([2.5]), aggregate=0.0)
    deep = fld.points[:, 2] > 0
    ref = point_displacement(fld.points[deep], MAT, source=P[0], P=2.5)
    np.testing.assert_allclose(fld.halfspace[deep], ref, rtol=1e-12, atol=1e-15)


def test_displacement_field_rejects_bad_input(block):
    with pytest.raises(ValueError, match="forces"):
        block.displacement_field(np.zeros((2, 2)), np.ones(3))
    with pytest.raises(ValueError, match="aggregate"):
        block.displacement_field(np.zeros((1, 2)), np.ones(1), aggregate=-1.0)


SCENE = """
[material]
E = 2.0
nu = 0.5
[load]
total = 2.0
[grid]
h = 0.2
[influence]
kind = "{kind}"
{block}
[[asperity]]
x = 0.0
y = 0.0
R = 5.0
[[asperity]]
x = 4.0
y = 1.0
R = 5.0
"""
BLOCK = 'size = [60.0, 60.0, 10.0]\nbase = "bonded"'


def test_cli_block_field_round_trip(tmp_path, monkeypatch):
    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path / "cache"))
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE.format(kind="block", block=BLOCK))
    out = tmp_path / "out"
    assert main(["solve", str(scene), "--out", str(out), "--block-field", "--quiet"]) == 0
    content = read_block_field(out / BLOCK_FIELD_NAME)
    meta = content.metadata
    res = json.loads((out / "result.json").read_text())
    assert meta["version"] == res["version"]
    assert meta["units"]["length"] == "mm" and meta["units"]["force"] == "N"
    assert meta["scene"] == res["scene"]
    assert meta["total_force"] == pytest.approx(res["total_load"], rel=1e-9)
    assert content.cells.shape[1] == 8 and content.points.shape == content.displacement.shape
    # VTK hexahedra: vertical edges 0-4, 1-5, 2-6, 3-7 and a positive volume (the mirrored
    # z axis must not turn the cells inside out); their volumes add up to the block's
    X = content.points[content.cells]
    a, b, e = X[:, 1] - X[:, 0], X[:, 3] - X[:, 0], X[:, 4] - X[:, 0]
    vol = np.einsum("ij,ij->i", np.cross(a, b), e)
    assert np.all(vol > 0)
    assert vol.sum() == pytest.approx(60.0 * 60.0 * 10.0, rel=1e-12)
    # z up in the file: the top face sits at z = 0, the pressed surface moves down
    assert content.points[:, 2].max() == 0.0 and content.points[:, 2].min() == pytest.approx(-10.0)
    # far from the load: point compliance (depth-positive) times the total force at the
    # centre of force, within (s^2 + a^2) / r^2 u_B(r) as above; s^2 adds each contact's
    # own second moment, <= its radius^2 = area / pi
    tips = np.array([[0.0, 0.0], [4.0, 1.0]])
    F = np.array([a["force"] for a in res["asperities"]])
    areas = np.array([a["contact_area"] for a in res["asperities"]])
    c = F @ tips / F.sum()
    s2 = float(F @ (np.sum((tips - c) ** 2, axis=1) + areas / np.pi) / F.sum())
    pts = content.points * np.array([1, 1, -1])
    idx = far_top(pts, tips)
    assert len(idx) >= 4
    provider = BlockProvider(material=MAT, size=(60.0, 60.0, 10.0), base="bonded", progress=False)
    expect = provider.point_compliance(pts[idx, :2], c[None, :])[:, 0] * F.sum()
    r = np.hypot(*(pts[idx, :2] - c).T)
    err = np.abs(-content.displacement[idx, 2] - expect)
    assert np.all(err <= (s2 + 1.0) / r**2 * halfspace_scale(F.sum(), r)), err.max()


def test_cli_builds_the_block_once_for_the_solve_and_its_field(tmp_path, monkeypatch):
    # the field comes from the block the solve ran on: its factorisation and cache read
    # are not made again (the memory check, the solve and the field: one block)
    import twoscale

    monkeypatch.setenv("TWOSCALE_CACHE_DIR", str(tmp_path / "cache"))
    built = []
    provider = twoscale.Scene.provider
    monkeypatch.setattr(twoscale.Scene, "provider", lambda self, **kw: built.append(1) or provider(self, **kw))
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE.format(kind="block", block=BLOCK))
    assert main(["solve", str(scene), "--out", str(tmp_path / "out"), "--block-field", "--quiet"]) == 0
    assert len(built) == 1
    content = read_block_field(tmp_path / "out" / BLOCK_FIELD_NAME)
    assert content.metadata["total_force"] == pytest.approx(2.0, rel=1e-9)


@pytest.mark.parametrize(
    "extra, message",
    [
        ([], '--block-field needs [influence] kind = "block"'),
    ],
)
def test_block_field_needs_block(tmp_path, capsys, extra, message):
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE.format(kind="halfspace", block=""))
    out = tmp_path / "out"
    assert main(["solve", str(scene), "--out", str(out), "--block-field", *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_block_field_needs_out(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE.format(kind="block", block=BLOCK))
    assert main(["solve", str(scene), "--block-field"]) == 2
    assert "--block-field needs --out DIR" in capsys.readouterr().err
