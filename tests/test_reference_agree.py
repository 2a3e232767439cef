"""The two reference solvers on the same problems: dense (Johnson) vs CG (Polonsky-Keer).

They share nothing but the problem statement (dense: factorisations of the Love matrix on
trial contact sets; CG: FFT products and projected gradients), so agreement to 1e-6
relative in the pressure (L2) and the total load, and in d and the tilt, checks both.
Also: the KKT conditions of each answer, input validation, and the trivial cases.
"""

import numpy as np
import pytest

from twoscale import Grid, Material
from twoscale.indenters import Asperity, Tilt, surface_on
from twoscale.influence import HalfSpace
from twoscale.reference import AUTO_DENSE_CELLS, solve_cg, solve_dense, solve_reference

HS = HalfSpace(Material(10.0, 0.5))

SCENES = {
    # two spheres whose caps overlap (the union's crease touches), one lower one out of reach
    "overlapping": (
        [Asperity(0.0, 0.0, 0.0, 1.0), Asperity(0.7, 0.1, 0.005, 0.8), Asperity(-0.4, -1.2, 0.2, 1.0)],
        Grid.covering(-1.0, 1.4, -1.8, 0.9, 0.05),
    ),
    # four asperities, mixed shapes and heights, one barely touching
    "mixed": (
        [
            Asperity(0.0, 0.0, 0.0, 1.0, "sphere"),
            Asperity(0.9, 0.2, 0.01, 0.8, "sphere"),
            Asperity(-0.5, 0.8, 0.02, 1.2, "paraboloid"),
            Asperity(0.1, -1.0, 0.028, 1.0),
        ],
        Grid.covering(-1.2, 1.5, -1.5, 1.3, 0.05),
    ),
    # three separate spheres on a non-square grid, odd sizes
    "separate": (
        [Asperity(-1.0, 0.0, 0.0, 1.5), Asperity(0.6, 0.3, 0.01, 1.0), Asperity(1.8, -0.4, 0.04, 2.0)],
        Grid.covering(-1.6, 2.4, -0.8, 0.9, 0.045),
    ),
}


def _rel(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def _agree(rd, rc, grid):
    assert rd.converged, rd.message
    assert rc.converged, rc.message
    pd, pc = rd.fields[0].pressure, rc.fields[0].pressure
    assert _rel(pc, pd) <= 1e-6
    assert rc.total_load == pytest.approx(rd.total_load, rel=1e-6)
    assert np.allclose(rc.asperities.forces, rd.asperities.forces, rtol=0, atol=1e-6 * rd.total_load)


def _kkt(r, tol=1e-6):
    f = r.fields[0]
    p, gap = f.pressure, f.gap
    umax = float(np.max(np.abs(gap[np.isfinite(gap)]))) + r.penetration
    assert np.all(p >= 0)
    assert np.all(p[~np.isfinite(f.gap)] == 0)  # no pressure where no indenter has material
    fin = np.isfinite(gap)
    assert np.min(gap[fin]) >= -tol * umax
    assert np.max(np.abs(gap[p > 0])) <= tol * umax


@pytest.mark.parametrize("name", list(SCENES))
def test_penetration_control(name):
    asps, grid = SCENES[name]
    s = surface_on(grid, asps)
    rd = solve_dense(HS, s, penetration=0.03)
    rc = solve_cg(HS, s, penetration=0.03)
    _agree(rd, rc, grid)
    assert rd.penetration == rc.penetration == 0.03
    _kkt(rd), _kkt(rc)
    # the out-of-reach sphere of "overlapping" carries nothing
    if name == "overlapping":
        assert rd.asperities.forces[2] == 0.0


@pytest.mark.parametrize("name", list(SCENES))
def test_load_control(name):
    asps, grid = SCENES[name]
    s = surface_on(grid, asps)
    rd = solve_dense(HS, s, total_load=0.25)
    rc = solve_cg(HS, s, total_load=0.25)
    _agree(rd, rc, grid)
    assert rd.total_load == pytest.approx(0.25, rel=1e-12)
    assert rc.penetration == pytest.approx(rd.penetration, rel=1e-6)
    _kkt(rd), _kkt(rc)


def test_load_control_inverts_penetration_control():
    asps, grid = SCENES["mixed"]
    s = surface_on(grid, asps)
    rp = solve_dense(HS, s, penetration=0.04)
    rl = solve_cg(HS, s, total_load=rp.total_load)
    assert rl.penetration == pytest.approx(0.04, rel=1e-6)


@pytest.mark.parametrize(
    "name,pivot", [("mixed", (0.1, 0.1)), ("separate", (0.3, 0.0)), ("overlapping", (0.35, -0.05))]
)
def test_tilt(name, pivot):
    asps, grid = SCENES[name]
    s = surface_on(grid, asps)
    W = 0.3
    rd = solve_dense(HS, s, total_load=W, tilt=True, pivot=pivot)
    rc = solve_cg(HS, s, total_load=W, tilt=True, pivot=pivot)
    _agree(rd, rc, grid)
    X, Y = grid.centres()
    h2 = grid.h**2
    # moment scale: load times the size of the loaded region
    arm = max(np.ptp(X[rd.fields[0].pressure > 0]), np.ptp(Y[rd.fields[0].pressure > 0]))
    for r in (rd, rc):
        p = r.fields[0].pressure
        assert h2 * p.sum() == pytest.approx(W, rel=1e-6)
        assert abs(h2 * ((X - pivot[0]) * p).sum()) <= 1e-6 * W * arm
        assert abs(h2 * ((Y - pivot[1]) * p).sum()) <= 1e-6 * W * arm
        _kkt(r)
    assert rc.penetration == pytest.approx(rd.penetration, rel=1e-6)
    (ad, bd), (ac, bc) = rd.tilt, rc.tilt
    tilt_scale = max(abs(ad), abs(bd))
    assert abs(ac - ad) <= 1e-6 * tilt_scale and abs(bc - bd) <= 1e-6 * tilt_scale


def test_tilt_recovers_an_imposed_rotation():
    """A surface rotated by known angles about the pivot, loaded through the joint there,
    must come back with the opposite angles when the untilted problem is symmetric."""
    asps = [
        Asperity(-0.8, 0.0, 0.0, 1.0),
        Asperity(0.8, 0.0, 0.0, 1.0),
        Asperity(0.0, 0.8, 0.0, 1.0),
        Asperity(0.0, -0.8, 0.0, 1.0),
    ]
    grid = Grid.covering(-1.3, 1.3, -1.3, 1.3, 0.05)
    alpha, beta = 0.004, -0.006
    s = surface_on(grid, asps, Tilt(alpha, beta, (0.0, 0.0)))
    r = solve_cg(HS, s, total_load=0.5, tilt=True)
    assert r.converged
    assert r.tilt[0] == pytest.approx(-alpha, rel=1e-5)
    assert r.tilt[1] == pytest.approx(-beta, rel=1e-5)
    forces = r.asperities.forces
    assert np.ptp(forces) <= 1e-5 * forces.mean()


def test_auto_dispatch():
    asps, grid = SCENES["separate"]
    s = surface_on(grid, asps)
    r = solve_reference(HS, s, penetration=0.02)
    n = int(np.isfinite(s.height).sum())
    # the method is the reference; the solver that ran is named beside it
    assert r.method == "reference" and r.solver == ("dense" if n <= AUTO_DENSE_CELLS else "cg")
    assert r.details.solver == r.solver
    assert solve_reference(HS, s, method="cg", penetration=0.02).solver == "cg"
    with pytest.raises(ValueError, match="method"):
        solve_reference(HS, s, method="lu", penetration=0.02)


# ------------------------------------------------------------------ trivial and invalid input
@pytest.mark.parametrize("solver", [solve_dense, solve_cg])
def test_nothing_touches_gives_zero_pressure(solver):
    asps, grid = SCENES["mixed"]
    s = surface_on(grid, asps)
    r = solver(HS, s, penetration=-0.01)
    assert r.converged and r.total_load == 0.0 and r.penetration == -0.01
    assert np.all(r.fields[0].pressure == 0)
    r0 = solver(HS, s, total_load=0.0)
    assert r0.converged and r0.total_load == 0.0 and r0.penetration == 0.0


@pytest.mark.parametrize("solver", [solve_dense, solve_cg])
@pytest.mark.parametrize(
    "kw,word",
    [
        ({}, "exactly one"),
        ({"penetration": 0.1, "total_load": 1.0}, "exactly one"),
        ({"penetration": 0.1, "tilt": True}, "tilt"),
        ({"penetration": float("nan")}, "penetration"),
        ({"total_load": -1.0}, "total_load"),
        ({"total_load": float("inf")}, "total_load"),
        ({"total_load": 1.0, "tilt": True, "pivot": (0.0, float("nan"))}, "pivot"),
        ({"total_load": 1.0, "tilt": True, "pivot": (5.0, 0.0)}, "pivot"),  # outside the grid: no equilibrium
    ],
)
def test_invalid_input_raises_naming_the_value(solver, kw, word):
    asps, grid = SCENES["mixed"]
    s = surface_on(grid, asps)
    with pytest.raises(ValueError, match=word):
        solver(HS, s, **kw)


def test_iteration_limit_is_reported_not_raised():
    asps, grid = SCENES["mixed"]
    s = surface_on(grid, asps)
    r = solve_cg(HS, s, penetration=0.03, max_iter=3)
    assert not r.converged and "max_iter" in r.message
    r = solve_dense(HS, s, penetration=0.03, max_iter=1)
    assert not r.converged and "max_iter" in r.message


def test_tilt_with_pivot_off_the_line_of_two_asperities():
    """Two asperities and a pivot off the line joining them: equilibrium needs a large
    tilt that brings the caps' flanks into contact. Johnson's plain iteration cycled here
    (the trial set shrank to two cells, leaving the moments undetermined)."""
    asps = [Asperity(0.923, -0.413, 0.0434, 2.264, "sphere"), Asperity(-0.949, 0.262, 0.0098, 2.992, "paraboloid")]
    grid = Grid.covering(-4.0, 4.0, -4.0, 4.0, 0.16)
    s = surface_on(grid, asps)
    kw = dict(total_load=1.594, tilt=True, pivot=(-0.486, -0.854))
    rd, rc = solve_dense(HS, s, **kw), solve_cg(HS, s, **kw)
    _agree(rd, rc, grid)
    assert np.all(rd.asperities.forces > 0)
    assert rc.tilt == pytest.approx(rd.tilt, rel=1e-6)


@pytest.mark.parametrize("seed", [3, 8])
def test_random_scenes_all_modes(seed):
    rng = np.random.default_rng(seed)
    asps = [
        Asperity(
            float(rng.uniform(-3, 3)),
            float(rng.uniform(-3, 3)),
            float(rng.uniform(0, 0.05)),
            float(rng.uniform(1, 3)),
            str(rng.choice(["sphere", "paraboloid"])),
        )
        for _ in range(int(rng.integers(3, 7)))
    ]
    grid = Grid.covering(-4.0, 4.0, -4.0, 4.0, 0.16)
    s = surface_on(grid, asps)
    for kw in (
        dict(penetration=0.06),
        dict(total_load=3.0),
        dict(total_load=3.0, tilt=True, pivot=(float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)))),
    ):
        _agree(solve_dense(HS, s, **kw), solve_cg(HS, s, **kw), grid)


def test_dense_on_a_mostly_empty_grid_uses_only_cells_with_material():
    """Two small caps on a wide grid: with max_cells below the grid size the dense solver
    builds the matrix of the cells with material only, and still agrees with CG."""
    asps = [Asperity(-2.0, 0.0, 0.0, 0.5), Asperity(2.0, 0.3, 0.002, 0.5)]
    grid = Grid.covering(-3.0, 3.0, -2.0, 2.0, 0.05)
    s = surface_on(grid, asps)
    n_mat = int(np.isfinite(s.height).sum())
    assert n_mat < grid.size // 4
    rd = solve_dense(HS, s, total_load=0.2, max_cells=2 * n_mat)
    _agree(rd, solve_cg(HS, s, total_load=0.2), grid)
    with pytest.raises(ValueError, match="max_cells"):
        solve_dense(HS, s, total_load=0.2, max_cells=n_mat - 1)
