"""A viscoelastic body under a rolling road: the track handed to the moving-indenter stepping
of :func:`twoscale.viscoelastic.moving.solve_moving` (the memory lives in the body, on a
grid fixed in it; the road moves under it), its answer read back as a
:class:`~twoscale.rolling.result.RollingResult`.

:class:`RoadIndenter` is the road as the stepping asks for it
(:class:`twoscale.viscoelastic.moving_indenter.MovingIndenter`): the stones that pass under
the face window over the run, in a fixed order, each shifted and seen through the face as
the elastic run sees them (:meth:`~twoscale.rolling.road.Road.stones_at`); a stone with no
sample inside the window at a shift stays in the list far from the body. The memory grid is
the face window (its edges open: the road touches the body's edge there), grown to sides
of 5-smooth lengths (:func:`twoscale.rolling.window.fast_grid`); the body is the scene's at
the relaxed modulus; each position is one time step, ``dt = step / speed``. On a
translation-invariant body (the half-space) each step is one constrained CG over the memory
grid (its operator kept for the run, :class:`~twoscale.rolling.window.KeptBody`;
preconditioned, the search directions' products in float32 (:data:`STEP_CG`), to the KKT
residual of the two-scale solver's union CG;
started from the previous pressure moved with the road, extrapolated from the one
before), as the elastic run's window path; on another body by the two-scale method. A
height map's strip only (its stones are looked up through the shared basins, which carry
the face).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from ..errors import SceneError
from ..grid import Grid
from .record import line_load_of, lines_on_lattice
from .result import Position, RollingResult, StoneSignals
from .road import Road
from .stones import Selection, ShiftedBasins
from .track import Track, footprint_length

#: Recess (mm) of a stone that has no sample inside the window at a shift: out of reach.
FAR = 1e3
#: The step CG's cells: those within this gap (mm) of the road at the last position
#: (``MovingOptions.near_gap``), as the elastic window's
#: (:data:`~twoscale.rolling.window.NEAR_GAP`): on the 20 mm section the same 1,128 CG iterations,
#: 10.1-10.5 against 12.0-13.2 s of CPU in one process, approaches within 2e-12 relative.
NEAR_GAP = 0.2
#: A step's CG settings on a translation-invariant body (``solve_cg``'s, beside the
#: tolerance): the elastic window's one stage, the search directions' products in float32
#: and the conjugate directions kept over a few entering cells
#: (:data:`~twoscale.rolling.window.KEEP_CONJUGACY`). On the benchmark's 20 mm section
#: (ten branches, 21 positions) 1,128 CG iterations against 1,322 with ``"mixed"``'s two
#: stages, 11.5-12.4 against 13.2-14.6 s of CPU alternated in one process (load ~5); the
#: approaches within 3e-10 relative, the drags 2e-8 of the largest. The stones' blocks
#: (:mod:`.blocks`) as the preconditioner took more iterations here (1,308; 1,576 with
#: ``"mixed"``): the circulant inverse stays.
STEP_CG = MappingProxyType({"precision": "single-directions", "precondition": True, "keep_conjugacy": 0.005})

#: A step's micro iteration on another body (a tread block): the two-scale policy's at
#: every step (it takes the union CG where the stones crowd their box), not the two-level
#: iteration with far-field coupling a load history's warm steps take. On the example strip
#: under a 150 x 100 x 10 mm block (21 positions, four branches, 50 km/h): 0.14 against
#: 0.78 s of CPU a position, the loads within 1e-10 of the full-grid reference stepping
#: against 1.3e-6 (the drag 2e-4) with the far field.
ANY_ITERATION = MappingProxyType({"iteration": "auto"})


@dataclass(eq=False)
class RoadIndenter:
    """The road's stones ``numbers`` (0-based) moving under the face (module docstring)."""

    road: Road
    numbers: np.ndarray
    _last: tuple = field(default=(None, ()), repr=False)

    @property
    def n_asperities(self) -> int:
        return len(self.numbers)

    def tips(self, shift: float) -> tuple:
        if self._last[0] == shift:
            return self._last[1]
        road = self.road
        face = road.face
        group = ShiftedBasins(road.basins, shift, face)
        out = []
        for k, stone in zip(self.numbers, road.map_stones(self.numbers, shift, group)):
            if stone is None:
                a = road.tips[int(k)]
                x, y = _inside(road.window, a.x + shift, a.y)
                stone = dataclasses.replace(a, x=x, y=y, z=FAR, basins=group)
            out.append(stone)
        self._last = (shift, tuple(out))
        return self._last[1]

    def surface(self, grid: Grid, shift: float):
        """The road's heights on ``grid`` at ``shift`` (owner: the place in ``numbers``),
        looked up through the shared basins for the stones whose box meets the window
        there (the others have no sample inside it), and the road's x-slope."""
        from ..indenters import Surface

        road = self.road
        near = np.intersect1d(road.candidates(shift, np.inf), self.numbers)
        place = np.searchsorted(self.numbers, near)
        group = ShiftedBasins(road.basins, shift, road.face)
        X, Y = grid.centres()
        height, owner = group.union_on(X, Y, {int(road.tips[k].label): int(m) for k, m in zip(near, place)})
        surf = Surface(grid, height, owner, len(self.numbers))
        slope = road.road_slope(Selection((), self.numbers, shift), X, Y, surf.owner)
        return surf, slope

    def face_on(self, grid: Grid) -> np.ndarray:
        return np.zeros(grid.shape)  # the face is in the stones' heights already


def _inside(window: tuple, x: float, y: float) -> tuple:
    """(x, y) wrapped into the finite sides of ``window``: a stone out of reach still sits on
    the face, since a block answers only for points there and asks it of every tip, loaded
    or not; wrapped, not clamped, so that no two stones meet."""
    x0, x1, y0, y1 = window
    if math.isfinite(x1 - x0) and not x0 <= x <= x1:
        x = x0 + math.fmod(x - x0, x1 - x0) % (x1 - x0)
    if math.isfinite(y1 - y0) and not y0 <= y <= y1:
        y = y0 + math.fmod(y - y0, y1 - y0) % (y1 - y0)
    return x, y


def run_stones(track: Track) -> np.ndarray:
    """The stones (0-based) whose box meets the face window at some shift of the run."""
    x0, x1, y0, y1 = track.road.window
    box = track.road.box
    s0, s1 = float(track.shifts[0]), float(track.shifts[-1])
    meets = (box[:, 1] + s1 >= x0) & (box[:, 0] + s0 <= x1) & (box[:, 3] >= y0) & (box[:, 2] <= y1)
    return np.flatnonzero(meets)


def memory_grid(track: Track) -> Grid:
    """The face window (a tyre without one: 0.6 of its estimated footprint each way, across
    the strip) on the lattice of the cell size."""
    from .window import fast_grid

    x0, x1, y0, y1 = track.road.window
    if not math.isfinite(x1 - x0):
        half = 0.6 * footprint_length(track) + 4 * track.h
        x0, x1 = -half, half
    if not math.isfinite(y1 - y0):
        y0, y1 = float(track.road.box[:, 2].min()), float(track.road.box[:, 3].max())
    return fast_grid(Grid.covering(x0, x1, y0, y1, track.h))


def roll_viscoelastic(track: Track, *, tol: float = 1e-6, progress=None, on_position=None) -> RollingResult:
    """Roll ``track`` (a material with Prony branches) through the moving-indenter stepping."""
    from ..micro.strategies import UNION_TOL_FACTOR
    from ..viscoelastic.moving import MovingOptions, solve_moving
    from .window import KeptBody

    if track.scene.surface is None:
        raise SceneError("material.prony with [rolling] runs on a [surface] strip; give the road as a height map")
    t0 = time.perf_counter()
    scene = track.scene
    numbers = run_stones(track)
    indenter = RoadIndenter(track.road, numbers)
    lines: list = []  # each position's line load, for the space-time picture
    cpu: list = []  # each position's CPU seconds
    provider = dataclasses.replace(
        scene, material=scene.material.relaxed(), rolling=None, surface=None, asperities=(_stand_in(),)
    ).provider()
    body = KeptBody(provider)
    if body.invariant:
        options = MovingOptions(
            method="cg",
            open_edges=True,
            solver={"tol": tol * UNION_TOL_FACTOR, **STEP_CG},
            near_gap=NEAR_GAP,
        )
        provider = body
    else:  # the policy's iteration at every step, as the elastic rolling's: see ANY_ITERATION
        options = MovingOptions(method="twoscale", solver={"tol": tol, **ANY_ITERATION}, open_edges=True)
    moving = solve_moving(
        scene.material,
        provider,
        indenter,
        track.shifts,
        speed=track.spec.speed_mm_s,
        grid=memory_grid(track),
        penetration=scene.penetration,
        total_load=scene.total_load,
        options=options,
        progress=progress,
        on_step=_positions(numbers, on_position, lines, cpu),
    )
    return _result(
        track,
        numbers,
        moving,
        time.perf_counter() - t0,
        "window-cg" if options.method == "cg" else "twoscale",
        lines_on_lattice(lines, track.h),
        cpu,
    )


def _stand_in():
    """A tip for the body-only scene the relaxed provider is built from."""
    from ..indenters import Asperity

    return Asperity(0.0, 0.0, 0.0, 1.0)


def _positions(numbers: np.ndarray, on_position, lines: list, cpu: list):
    """``solve_moving``'s ``on_step``: appends each position's line load (pressure summed
    across y) to ``lines`` and its CPU seconds to ``cpu`` (the thread's since the last
    call, or since this one was made: the stepping's set-up goes to the first position),
    and calls ``on_position`` with a :class:`~twoscale.rolling.run.Position` when given."""
    last = [time.thread_time()]

    def on_step(n: int, shift: float, result, summary=None) -> None:
        now = time.thread_time()
        cpu.append(now - last[0])
        lines.append(line_load_of(result))
        if on_position is not None:
            on_position(Position(n, Selection((), numbers, shift), result, float("nan"), 0.0, cpu[-1]))
        last[0] = time.thread_time()

    return on_step


def _result(track: Track, numbers: np.ndarray, moving, seconds: float, method: str, lines, cpu) -> RollingResult:
    forces, areas = np.asarray(moving.forces), np.asarray(moving.tip_areas)
    pos, k = np.nonzero(areas > 0)
    converged = np.asarray(moving.step_converged, dtype=bool)
    return RollingResult(
        spec=track.spec,
        method=method,
        control=track.control,
        h=track.h,
        times=moving.times,
        shifts=moving.shifts,
        total_load=moving.total_load,
        penetration=moving.penetration,
        contact_area=moving.contact_area,
        drag=moving.drag,
        converged=converged,
        seconds=moving.seconds,
        cpu_seconds=cpu,
        stones=np.full(len(track.shifts), len(numbers)),
        iterations=moving.iterations,
        messages=tuple("" if c else (moving.message or "did not converge") for c in converged),
        asperities=StoneSignals(pos, numbers[k] + 1, forces[pos, k], areas[pos, k]),
        line_x=lines[0],
        line_load=lines[1],
        dissipated=moving.dissipated,
        stored=moving.stored,
        timings_s=track.timings(seconds),
        body=track.body + ", viscoelastic",
        step_check=track.step_check,
    )
