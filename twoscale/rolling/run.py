"""The rolling loop: every position of the track solved as a static contact of the road at
that shift, warm-started from the previous position.

Per position (:func:`solve_position`, the one call a persistent solver object can take
over): the stones within reach of the footprint (:meth:`~twoscale.rolling.road.Road.stones_at`)
go to the two-scale solver (:func:`twoscale.driver.solve_twoscale`) with the previous
position's macro forces, approach and tilt as the start (mapped stone by stone:
:meth:`~twoscale.macro.start.MacroStart.from_result`). The answer is the static solve's to
its tolerance; only the start differs. Under load control the approach is not known
before the solve: the stones are taken below a bound on it, and the position is solved
again with a larger bound when the solved approach exceeds it (never needed when the
bound holds: no stone left out can touch).

A viscoelastic material (Prony branches) runs through
:func:`twoscale.viscoelastic.moving.solve_moving` instead (its memory carried in the body
frame): :func:`twoscale.rolling.viscous.roll_viscoelastic`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..macro.start import MacroStart
from ..results import ContactResult
from ..collector import frozen_objects
from .record import Recorder
from .result import Position, RollingResult
from .first_contact import hertz_level
from .stones import Selection
from .track import Track, prepare, tyre_contact_length, warn_if_cut
from ..threads import single_threads

#: Load control: the stones are taken below ``d_prev + BOUND_GROWTH (d_prev - z_low)``.
BOUND_GROWTH = 0.5
#: Re-solves of one position allowed when the approach leaves its bound.
MAX_REBOUNDS = 4


@dataclass(frozen=True)
class RollingOptions:
    """How the positions are solved.

    Parameters
    ----------
    tol : float, default 1e-6
        The two-scale solver's tolerance (eq. 9: relative change of the pressure).
    iteration : str, default "auto"
        The micro step's iteration (:func:`twoscale.driver.solve_twoscale`).
    warm : bool, default True
        Start each position from the previous one (False: every position from cold, for
        comparison; the answers agree to the tolerance).
    pressure_start : bool, default True
        With ``warm``: also start the micro step from the previous pressure moved with
        the road (else the macro step only).
    h : float, optional
        Cell size for a scene of tips, mm (default: the scene's rule); a height map's
        spacing otherwise.
    solver : {"auto", "window", "twoscale"}, default "auto"
        ``"window"``: each position one constrained CG over a window kept in the body, its
        FFT operator built once, started from the previous pressures moved with the road
        (:mod:`twoscale.rolling.window`); ``"twoscale"``: the two-scale solver per
        position (:func:`solve_position`); ``"auto"``: the window with ``iteration="auto"``
        (but for tips on a block), else the two-scale solver. On a block too: its CG over the face's window finds every
        contact the bulge makes at once, where the two-scale solver takes in the stones it
        lifts by a check and rounds (:mod:`twoscale.bulge_rounds`: a tyre at 600 N on a
        bonded 10 mm block, 4 of 21 positions solved twice, 1.3 times the CPU it took when
        it missed them), at 0.89-1.05 of the CPU the two-scale path took then (four scenes).
    """

    tol: float = 1e-6
    iteration: str = "auto"
    warm: bool = True
    pressure_start: bool = True
    h: float | None = None
    solver: str = "auto"

    def __post_init__(self) -> None:
        if self.solver not in SOLVERS:
            raise ValueError(f"RollingOptions.solver must be one of {SOLVERS}, got {self.solver!r}")


#: The per-position solvers of :class:`RollingOptions`.
SOLVERS = ("auto", "window", "twoscale")


def solve_position(track: Track, selection: Selection, *, start=None, options: RollingOptions) -> ContactResult:
    """The static solve of the road at one position (the stones of ``selection``), from
    ``start`` (a :class:`~twoscale.warm_start.WarmStart` or None): the one call per position.

    :class:`twoscale.ContactSolver` keeps the same start between solves of a Scene; a
    position's stones are shifted basins of the strip (not a Scene of their own), so the
    driver builds the start itself and calls the two-scale solver directly."""
    from ..driver import solve_twoscale

    scene = track.scene
    return solve_twoscale(
        track.provider,
        selection.stones,
        h=track.h,
        penetration=scene.penetration,
        total_load=scene.total_load,
        tol=options.tol,
        iteration=options.iteration,
        start=start,
    )


def drag_of(track: Track, selection: Selection, result: ContactResult) -> float:
    """Force the road exerts on the body along +x, N: the sum over the pressure fields'
    cells of pressure x the road's x-slope x the cell area (the slope sampled on the loaded
    cells only: ~7 % of a tyre's window)."""
    total = 0.0
    for f in result.fields:
        X, Y = f.grid.centres()
        on = np.flatnonzero(f.pressure)  # (flat indices once: the same cells in the same order)
        slope = track.road.road_slope(selection, X.ravel()[on], Y.ravel()[on], f.owner.ravel()[on])
        total += float(np.sum(f.pressure.ravel()[on] * slope)) * f.grid.h**2
    return total


def _start(previous: Position | None, selection: Selection, options: RollingOptions):
    """The previous position's answer as this one's start (:func:`twoscale.warm_start.warm_start`),
    stone by stone: the macro forces, and the pressure around each stone moved with the
    road (by the step: the previous tips are given where the stones were, one step back
    from where they are now); the approach moved with the lowest stone, so that the start
    keeps the local approach (a stone rising under a tyre's face would otherwise start out
    of contact)."""
    if previous is None or not options.warm or not previous.selection.stones:
        return None
    from ..warm_start import WarmStart, warm_start

    where = {int(n): k for k, n in enumerate(previous.selection.numbers)}
    index = np.array([where.get(int(n), -1) for n in selection.numbers], dtype=np.int64)
    tips = np.array([[s.x, s.y] for s in previous.selection.stones], dtype=float)
    moved = selection.shift - previous.selection.shift
    for m in np.flatnonzero(index >= 0):  # where the road put each kept stone's tip, one step back
        stone = selection.stones[m]
        tips[index[m]] = (stone.x - moved, stone.y)
    h = previous.result.fields[0].grid.h if previous.result.fields else 0.0
    ws = warm_start(
        previous.result, tips, len(selection.stones), h or 1.0, index=index, pressure=options.pressure_start
    )
    low_then, low_now = previous.selection.low, selection.low
    macro = MacroStart(ws.macro.forces, previous.result.penetration + (low_now - low_then), ws.macro.tilt)
    return WarmStart(macro, ws.micro)


def _depth(position: Position | None, h: float) -> float:
    """The previous position's local approach (approach less its lowest stone's recess), mm."""
    if position is None or not position.selection.stones:
        return h
    return max(position.result.penetration - position.selection.low, h)


def _bound(track: Track, shift: float, previous: Position | None) -> float:
    """Largest approach the stones are taken for (module docstring): the held approach, or
    the previous approach moved with this position's lowest possible stone, with room."""
    scene = track.scene
    if track.control == "penetration":
        return float(scene.penetration)
    if previous is not None:
        low, depth = float(np.min(track.road.lowest(shift), initial=np.inf)), _depth(previous, track.h)
        return max(previous.result.penetration, low + depth) + BOUND_GROWTH * depth
    wide = _all_stones(track, shift)
    d = hertz_level(wide.stones, scene.material.E_star, scene.total_load)
    return d + 2.0 * max(d - wide.low, track.h)


def _all_stones(track: Track, shift: float) -> Selection:
    """Every stone under the footprint at ``shift`` (load control: something must be)."""
    wide = track.road.stones_at(shift, np.inf)
    if not wide.stones:
        from ..errors import SceneError

        raise SceneError(
            f"rolling: no stone of the road lies under the footprint at shift {shift:g} mm "
            f"(check rolling.start, rolling.end and rolling.footprint against the road)"
        )
    return wide


def step(track: Track, index: int, previous: Position | None, options: RollingOptions, state=None) -> Position:
    """Solve position ``index`` (module docstring); ``state``: a
    :class:`~twoscale.rolling.window.WindowState` to solve it on the kept window instead."""
    t0, c0 = time.perf_counter(), time.thread_time()
    shift = float(track.shifts[index])
    # where the surface can rise (a block), an approach bound does not bound the stones that
    # touch: the solver takes them all (the two-scale macro step, or the window's CG, sees
    # the rise)
    bound = math.inf if track.rises else _bound(track, shift, previous)
    selection = track.road.stones_at(shift, bound)
    if not selection.stones and track.control == "penetration":  # nothing within reach of the body here
        return Position(index, selection, _no_contact(track), 0.0, time.perf_counter() - t0, time.thread_time() - c0)
    if not selection.stones:
        bound = _all_stones(track, shift).low + (1 + BOUND_GROWTH) * _depth(previous, track.h)
        selection = track.road.stones_at(shift, bound)
    for attempt in range(MAX_REBOUNDS + 1):
        if attempt:
            selection = track.road.stones_at(shift, bound)
        result = _solve(track, selection, bound, previous, options, state)
        if track.control == "penetration" or result.penetration < bound:
            break
        bound = result.penetration + BOUND_GROWTH * max(result.penetration - selection.low, track.h)
    else:  # the approach kept passing the bound: stones left out might touch
        result = dataclasses.replace(
            result,
            converged=False,
            message=(f"{result.message}; " if result.message else "")
            + f"the approach {result.penetration:.6g} mm still "
            f"passes the bound {bound:.6g} mm the stones were taken for after {MAX_REBOUNDS} enlargements",
        )
    drag = drag_of(track, selection, result)
    return Position(index, selection, result, drag, time.perf_counter() - t0, time.thread_time() - c0)


def _solve(
    track: Track, selection: Selection, bound: float, previous: Position | None, options: RollingOptions, state
) -> ContactResult:
    """One position's static solve: on the kept window (``state``), else by the two-scale
    solver warm-started from ``previous``; a solve that does not converge is redone by
    the two-scale solver from cold."""
    if state is not None:
        from .window import solve_window

        result = solve_window(track, selection, bound, state, options.tol)
        if result is not None and result.converged:
            state.keep(result, selection.shift)
            return result
        state.past.clear()
    else:
        start = _start(previous, selection, options)
        result = solve_position(track, selection, start=start, options=options)
        if result.converged or start is None:
            return result
    return solve_position(track, selection, start=None, options=options)


def window_state(track: Track, options: RollingOptions):
    """The :class:`~twoscale.rolling.window.WindowState` of a run on the window path
    (:class:`RollingOptions` ``solver``), or None."""
    from .blocks import StoneBlocks
    from .shiftstep import ShiftStep
    from .window import GAP_STIFFNESS, KeptBody, WindowState

    if options.solver == "twoscale" or (options.solver == "auto" and options.iteration != "auto"):
        return None
    body = KeptBody(track.provider)
    if options.solver == "auto" and not body.invariant and track.scene.surface is None:
        return None  # tips on a block: the two-scale solver checks their patches against its face
    stiffness = GAP_STIFFNESS / track.provider.self_compliance(track.h)
    ahead = ShiftStep(body, track.spec.face, track.control != "penetration", stiffness)
    half = 0.5 * tyre_contact_length(track) if track.spec.tyre_radius is not None else None
    return WindowState(
        body,
        blocks=StoneBlocks(body) if body.invariant else None,
        ahead=ahead,
        footprint=None if half is None else (-half, half),
    )


def _no_contact(track: Track) -> ContactResult:
    """The answer where no stone can touch: no load, nothing to solve."""
    from ..results import summarise

    return ContactResult(
        method="twoscale",
        fields=(),
        penetration=float(track.scene.penetration),
        tilt=None,
        total_load=0.0,
        asperities=summarise((), 0),
        converged=True,
        message="",
        timings_s={"total": 0.0},
    )


def roll(
    scene,
    *,
    options: RollingOptions | None = None,
    provider=None,
    on_position: Callable[[Position], None] | None = None,
    progress=None,
    track: Track | None = None,
) -> RollingResult:
    """Roll the road of ``scene`` (a :class:`~twoscale.scene.Scene` with ``rolling``) under its body.

    Parameters
    ----------
    scene : Scene
        With ``rolling`` (:class:`~twoscale.rolling.spec.RollingSpec`), a ``surface`` (the
        road strip) or asperities, and the load: ``penetration`` (mm below the road's
        highest point, held) or ``total_load`` (N, held).
    options : RollingOptions, optional
    provider : InfluenceProvider, optional
        A prebuilt body (default: the scene's).
    on_position : callable, optional
        Called with each solved :class:`Position` (e.g. to write a VTK frame).
    progress : callable, optional
        Called with a short text per position.
    track : Track, optional
        The scene already prepared (:func:`twoscale.rolling.track.prepare`: checked,
        segmented), so that a caller that checked it first does not prepare it twice.

    Returns
    -------
    RollingResult
    """
    # the BLAS and OpenMP libraries one thread each (twoscale.threads); the objects alive
    # before the run out of the collector's full passes (.collector)
    with single_threads(), frozen_objects():
        return _roll(scene, options, provider, on_position, progress, track)


def _roll(scene, options, provider, on_position, progress, track) -> RollingResult:
    """:func:`roll` with the thread counts as they are."""
    options = options or RollingOptions()
    track = track if track is not None else prepare(scene, h=options.h, provider=provider)
    if track.scene.material.viscoelastic:  # the memory in the body: the moving-indenter stepping
        from .viscous import roll_viscoelastic

        result = roll_viscoelastic(track, tol=options.tol, progress=progress, on_position=on_position)
        warn_if_cut(track, result)
        return result
    t1 = time.perf_counter()
    record, previous = Recorder(), None
    state = window_state(track, options)
    for k in range(len(track.shifts)):
        pos = step(track, k, previous, options, state)
        if on_position is not None:
            on_position(pos)
        if progress is not None:
            progress(f"position {k + 1} of {len(track.shifts)}: {pos.result.total_load:.4g} N, {pos.seconds:.2f} s")
        record.add(pos)
        previous = pos
    t2 = time.perf_counter()
    result = record.result(
        track,
        track.timings(t2 - t1),
        "twoscale" if state is None else "window-cg",
    )
    warn_if_cut(track, result)
    return result


def roll_at_twice_the_step(track, *, tol: float = 1e-6):
    """The run of ``track`` (prepared: :func:`twoscale.rolling.track.prepare`) at twice its
    step on the same samples and from the same first shift; a RollingResult."""
    import warnings

    from ..errors import StepWarning, SurfaceWarning

    spec = dataclasses.replace(track.spec, start=float(track.shifts[0]), step=2.0 * track.spec.step)
    # the run at the step said whether it is coarse, and what the road and the face give
    # to warn of (the same road under the same face over the same distance)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StepWarning)
        warnings.simplefilter("ignore", SurfaceWarning)
        return roll(dataclasses.replace(track.scene, rolling=spec), options=RollingOptions(tol=tol))
