"""Sensor averaging, indicators e_M / e_m, measured-data readers, pivot centring (eq. 13)."""

import numpy as np
import pytest

from twoscale.grid import Grid
from twoscale.results import ContactResult, PressureField, summarise
from twoscale.sensor import Sensor, centred_tips, e_M, e_m, pivot_from_forces, read_sensor_map, read_tip_forces


def _result(fields, n=1):
    s = summarise(fields, n)
    total = sum(float(f.pressure.sum()) * f.grid.h**2 for f in fields)
    return ContactResult("test", tuple(fields), 0.1, None, total, s, True)


def _field(grid, p, owner=0):
    return PressureField(grid, p, np.full(grid.shape, owner), np.zeros(grid.shape))


# ---------------------------------------------------------------- averaging
def test_sensor_grid_geometry():
    s = Sensor()
    g = s.grid
    assert g.shape == (44, 44)
    xmin, xmax, ymin, ymax = g.bounds
    assert xmin == pytest.approx(-22 * 1.9) and xmax == pytest.approx(22 * 1.9)
    assert ymin == pytest.approx(-22 * 1.9) and ymax == pytest.approx(22 * 1.9)
    s2 = Sensor(nx=3, ny=2, cell=2.0, centre=(10.0, -4.0))
    assert s2.grid.x.tolist() == [8.0, 10.0, 12.0]
    assert s2.grid.y.tolist() == [-5.0, -3.0]


def test_uniform_pressure_reproduced_exactly_misaligned():
    # micro cells of an awkward size and offset cover the whole sensor: every sensor
    # cell is fully covered, so its mean is the uniform value (up to round-off)
    s = Sensor(nx=7, ny=5, cell=1.9, centre=(0.3, -0.2))
    g = Grid.covering(-8, 8, -6, 6, 0.137, anchor=(0.05, 0.01))
    P = s.average_field(g, np.full(g.shape, 0.75))
    assert P.shape == (5, 7)
    np.testing.assert_allclose(P, 0.75, rtol=1e-12)


def test_linear_pressure_reproduced_exactly_when_cells_nest():
    # p = a + b x + c y sampled at micro-cell centres; when every sensor cell is a union of
    # whole micro cells the midpoint rule is exact for a linear field, so the sensor mean
    # equals p at the sensor-cell centre
    s = Sensor(nx=4, ny=3, cell=1.9)
    h = 1.9 / 10
    sg = s.grid
    g = Grid(sg.x0 - 0.5 * sg.h + 0.5 * h, sg.y0 - 0.5 * sg.h + 0.5 * h, h, 40, 30)
    X, Y = g.centres()
    P = s.average_field(g, 2.0 + 0.3 * X - 0.7 * Y)
    SX, SY = sg.centres()
    np.testing.assert_allclose(P, 2.0 + 0.3 * SX - 0.7 * SY, rtol=0, atol=1e-12)


def test_linear_pressure_misaligned_error_bounded_by_cell_size():
    # misaligned micro cells: partial cells carry their centre value, an O(h) error in
    # each boundary strip; the mean error is bounded by |grad p| * h
    s = Sensor(nx=4, ny=3, cell=1.9)
    h = 0.05
    g = Grid.covering(-5, 5, -4, 4, h, anchor=(0.013, 0.021))
    X, Y = g.centres()
    P = s.average_field(g, 2.0 + 0.3 * X - 0.7 * Y)
    SX, SY = s.grid.centres()
    err = np.abs(P - (2.0 + 0.3 * SX - 0.7 * SY)).max()
    assert err <= (0.3 + 0.7) * h


def test_one_micro_cell_split_over_four_sensor_cells():
    # micro cell of side 1 centred on the common corner of four sensor cells, shifted by
    # (0.2, 0.1): overlaps 0.3*0.4, 0.7*0.4, 0.3*0.6, 0.7*0.6 (computed by hand)
    s = Sensor(nx=2, ny=2, cell=2.0)
    g = Grid(0.2, 0.1, 1.0, 1, 1)
    P = s.average_field(g, np.array([[1.0]]))
    expected = np.array([[0.3 * 0.4, 0.7 * 0.4], [0.3 * 0.6, 0.7 * 0.6]]) / 4.0
    np.testing.assert_allclose(P, expected, rtol=1e-13)


def test_force_conserved_for_two_scale_patches():
    rng = np.random.default_rng(3)
    fields = []
    for k, (cx, cy) in enumerate([(-7.3, 2.1), (5.2, -3.3), (0.4, 9.9)]):
        g = Grid.covering(cx - 2, cx + 2, cy - 2, cy + 2, 0.083)
        fields.append(_field(g, rng.random(g.shape), owner=k))
    res = _result(fields, n=3)
    s = Sensor()
    P = s.average(res)
    assert s.force(P) == pytest.approx(res.total_load, rel=1e-12)


def test_force_outside_sensor_is_cut_at_its_edge():
    # sensor covers x in [0, 4]; a uniform pressure 1 on x in [-1, 5], y in [0, 2]
    # (the sensor's full height) puts exactly 4 * 2 = 8 N on the sensor
    s = Sensor(nx=2, ny=1, cell=2.0, centre=(2.0, 1.0))
    g = Grid(-0.9, 0.1, 0.2, 30, 10)
    P = s.average_field(g, np.ones(g.shape))
    assert s.force(P) == pytest.approx(8.0, rel=1e-12)


def test_average_rejects_bad_input():
    s = Sensor(nx=2, ny=2)
    g = Grid(0, 0, 0.1, 3, 3)
    with pytest.raises(ValueError, match="shape"):
        s.average_field(g, np.zeros((2, 3)))
    with pytest.raises(ValueError, match="non-finite"):
        s.average_field(g, np.full((3, 3), np.nan))
    for bad in (dict(nx=0), dict(cell=-1.0), dict(cell=float("inf")), dict(centre=(0.0,))):
        with pytest.raises(ValueError):
            Sensor(**bad)


# ---------------------------------------------------------------- indicators
def test_e_M_closed_form():
    # P = [1, 2, 3], Pref = [1, 1, 4]: sum diff^2 = 0 + 1 + 1 = 2, sum ref^2 = 18
    assert e_M([1, 2, 3], [1, 1, 4]) == pytest.approx(100 * 2 / 18, rel=1e-15)
    assert e_M([2.0, 4.0], [2.0, 4.0]) == 0.0
    # 10 % uniform over-prediction gives 100 * 0.01 = 1 %
    assert e_M(1.1 * np.arange(1, 6), np.arange(1, 6)) == pytest.approx(1.0, rel=1e-12)


def test_e_m_loaded_cells_and_reference_cells():
    ref = np.array([[0.0, 1.0], [2.0, 0.0]])
    p = np.array([[0.5, 1.0], [1.0, 0.0]])
    # loaded (union): diff^2 = 0.25 + 0 + 1 = 1.25; ref^2 = 5
    assert e_m(p, ref) == pytest.approx(100 * 1.25 / 5, rel=1e-15)
    # reference cells only: the spurious 0.5 outside the measured area is not counted
    assert e_m(p, ref, cells="reference") == pytest.approx(100 * 1.0 / 5, rel=1e-15)
    # unloaded cells do not change the value
    big_ref = np.zeros((10, 10))
    big_ref[:2, :2] = ref
    big_p = np.zeros((10, 10))
    big_p[:2, :2] = p
    assert e_m(big_p, big_ref) == pytest.approx(e_m(p, ref), rel=1e-15)


def test_indicators_reject_bad_input():
    with pytest.raises(ValueError, match="shapes differ"):
        e_M([1, 2], [1, 2, 3])
    with pytest.raises(ValueError, match="all zero"):
        e_M([1, 2], [0, 0])
    with pytest.raises(ValueError, match="non-finite"):
        e_m(np.array([np.nan]), np.array([1.0]))
    with pytest.raises(ValueError, match="cells"):
        e_m(np.ones(2), np.ones(2), cells="all")


# ---------------------------------------------------------------- pivot centring
def test_pivot_eq13():
    tips = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    forces = np.array([2.0, 1.0, 1.0])
    # x0 = (10 * 1) / 4 = 2.5, y0 = (10 * 1) / 4 = 2.5
    assert pivot_from_forces(tips, forces) == pytest.approx((2.5, 2.5), rel=1e-15)
    # with the applied total load in place of the sum of measured forces
    assert pivot_from_forces(tips, forces, total=5.0) == pytest.approx((2.0, 2.0), rel=1e-15)
    c = centred_tips(tips, forces)
    np.testing.assert_allclose(c, tips - 2.5)
    # after centring, the force moment about the origin vanishes (the joint's equilibrium)
    np.testing.assert_allclose(c.T @ forces, 0.0, atol=1e-12)


def test_pivot_rejects_bad_input():
    with pytest.raises(ValueError, match="shape"):
        pivot_from_forces(np.zeros((3, 3)), np.ones(3))
    with pytest.raises(ValueError, match=">= 0"):
        pivot_from_forces(np.zeros((2, 2)), [1.0, -1.0])
    with pytest.raises(ValueError, match="total"):
        pivot_from_forces(np.zeros((2, 2)), [0.0, 0.0])


# ---------------------------------------------------------------- readers
def test_read_tip_forces_both_layouts(tmp_path):
    a = tmp_path / "xy.csv"
    a.write_text("# measured at 250 N\nx, y, force\n0, 0, 10.5\n12.0, -3, 9.25\n")
    m = read_tip_forces(a, n_asperities=2)
    np.testing.assert_array_equal(m.force, [10.5, 9.25])
    np.testing.assert_array_equal(m.tips, [[0, 0], [12, -3]])
    b = tmp_path / "idx.csv"
    b.write_text("index,force\n1,3.0\n0,4.0\n2,5.0\n")
    m = read_tip_forces(b)
    np.testing.assert_array_equal(m.force, [4.0, 3.0, 5.0])
    assert m.tips is None
    c = tmp_path / "numbered.csv"  # numbered from 1, as the program's own tables
    c.write_text("asperity,force\n2,3.0\n1,4.0\n3,5.0\n")
    np.testing.assert_array_equal(read_tip_forces(c).force, [4.0, 3.0, 5.0])
    c.write_text("asperity,force\n0,3.0\n1,4.0\n")
    with pytest.raises(ValueError, match="asperity must be the integers 1..2"):
        read_tip_forces(c)
    c.write_text("asperity,force\n1,5.0\n99,3.0\n")  # two of a scene's seven tips
    with pytest.raises(ValueError, match="2 forces for a scene of 7 asperities"):
        read_tip_forces(c, n_asperities=7)


@pytest.mark.parametrize(
    "text, match",
    [
        ("", "no data"),
        ("a,b\n1,2\n", "header"),
        ("index,force\n", "no rows"),
        ("index,force\n0,abc\n", ":2: column 'force' is not a number"),
        ("index,force\n0,nan\n", "not finite"),
        ("index,force\n0,1,2\n", "expected 2 columns"),
        ("index,force\n0,-1\n", ">= 0"),
        ("index,force\n0,1\n0,2\n", "each once"),
        ("x,y,force\n0,0,1\n", "3 asperities"),
    ],
)
def test_read_tip_forces_errors(tmp_path, text, match):
    f = tmp_path / "f.csv"
    f.write_text(text)
    with pytest.raises(ValueError, match=match):
        read_tip_forces(f, n_asperities=3 if "x,y" in text else None)


def test_read_tip_forces_missing_file(tmp_path):
    with pytest.raises(ValueError, match="cannot read"):
        read_tip_forces(tmp_path / "nope.csv")


def test_read_sensor_map_orientation_and_errors(tmp_path):
    s = Sensor(nx=3, ny=2)
    f = tmp_path / "m.csv"
    f.write_text("1,2,3\n4,5,6\n")
    np.testing.assert_array_equal(read_sensor_map(f, sensor=s), [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(read_sensor_map(f, sensor=s, first_row="ymax"), [[4, 5, 6], [1, 2, 3]])
    with pytest.raises(ValueError, match="ny = 44"):
        read_sensor_map(f)
    f.write_text("1,2\n4,5\n")
    with pytest.raises(ValueError, match="nx = 3"):
        read_sensor_map(f, sensor=s)
    f.write_text("1,2,3\n4,-5,6\n")
    with pytest.raises(ValueError, match="negative"):
        read_sensor_map(f, sensor=s)


def test_forces_from_map_recovers_separated_tip_forces():
    # two Hertz-like patches far apart; the sensor map of their pressure, split by nearest
    # tip, gives back each patch's force (every loaded sensor cell is nearer its own tip)
    from twoscale.sensor import forces_from_map

    fields = []
    for k, (cx, cy, a) in enumerate([(-10.0, 3.0, 2.0), (12.0, -5.0, 3.0)]):
        g = Grid.covering(cx - a, cx + a, cy - a, cy + a, 0.07)
        X, Y = g.centres()
        p = np.sqrt(np.clip(1 - ((X - cx) ** 2 + (Y - cy) ** 2) / a**2, 0, None))
        fields.append(_field(g, p, owner=k))
    res = _result(fields, n=2)
    s = Sensor()
    F = forces_from_map(s.average(res), np.array([[-10.0, 3.0], [12.0, -5.0]]), sensor=s)
    np.testing.assert_allclose(F, res.asperities.forces, rtol=1e-12)
    # a radius smaller than the contact drops the outer cells: less force, never more
    F2 = forces_from_map(s.average(res), np.array([[-10.0, 3.0], [12.0, -5.0]]), sensor=s, radius=1.0)
    assert np.all(F2 < F) and np.all(F2 > 0)
    with pytest.raises(ValueError, match="shape"):
        forces_from_map(np.zeros((3, 3)), np.zeros((1, 2)), sensor=s)
