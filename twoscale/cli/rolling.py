"""``twoscale solve SCENE --out DIR`` on a scene with a ``[rolling]`` table: the road rolls
under the body; every position is solved and the signals written
(:mod:`twoscale.io.rolling_outputs`: ``signals.csv``, ``asperity_signals.csv`` (+ Parquet),
``rolling.json``, ``fields.pvd``).

Exit codes as ``twoscale solve``: 0 every position converged; 1 some did not (the files
are written all the same, ``rolling.json`` says which); 2 bad input (one ``error: ...``
line naming the field; nothing written: the files go to a temporary folder renamed to DIR
at the end).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from ..progress import StatusLine
from .heap import keep_heap
from .staging import staged_directory

#: VTK frames written at most (every k-th position beyond that: a metre of road at fine
#: steps would otherwise write gigabytes).
MAX_FRAMES = 200
#: Refused options of ``twoscale solve`` on a rolling scene (the run's own solver is fixed).
_NOT_ROLLING = (
    ("method", "twoscale", "--method"),
    ("far_tol", None, "--far-tol"),
    ("block_field", False, "--block-field"),
)


def run_rolling(scene, args: argparse.Namespace, log=None) -> int:
    """Run the rolling scene ``scene`` (read from ``args.scene``); the exit code. ``log``: the
    :class:`~twoscale.io.warning_log.WarningLog` whose warnings ``rolling.json`` lists."""
    from ..rolling.run import RollingOptions, roll

    try:
        for key, default, name in _NOT_ROLLING:
            value = getattr(args, key, default)
            if value != default:
                given = name if isinstance(value, bool) else f"{name} {value}"
                raise ValueError(
                    f"{given} does not apply to a [rolling] scene (its positions are solved by the rolling's "
                    f"own solver, chosen by the body: RollingOptions.solver)"
                )
        options = RollingOptions(iteration=getattr(args, "iteration", "auto"))
        track = _prepared(scene, args.scene)  # every check before anything is solved or written
        if getattr(args, "step_error", False) and not scene.material.viscoelastic:
            raise ValueError(
                "--step-error needs a viscoelastic material (material.prony): an elastic body has no hysteresis"
            )
        keep_heap()  # (a position's arrays reused, not faulted in again: .heap)
        t0 = time.perf_counter()
        with StatusLine(quiet=args.quiet) as status:
            if args.out is None:
                result = roll(track.scene, options=options, track=track, progress=status)
                result = _with_step_error(result, track, args)
            else:
                with staged_directory(
                    args.out, overwrite=getattr(args, "overwrite", False), command=f"solve {args.scene}"
                ) as tmp:
                    result = _roll_into(tmp, scene, track, options, status, args, log)
        wall = time.perf_counter() - t0
    except ValueError as exc:  # SceneError, an output folder that cannot be used
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if not args.quiet:
        print(summary(result, args.scene, wall, args.out, material=scene.material))
    if not result.all_converged:
        bad = int(np.sum(~result.converged))
        print(
            f"warning: {bad} of {len(result.shifts)} positions did not converge (rolling.json lists them)",
            file=sys.stderr,
        )
        return 1
    return 0


def _prepared(scene, path):
    """``prepare(scene)``, its refusals naming the scene file first as the reader's do
    (``tyre.toml: rolling.tyre_radius = ...``)."""
    from ..rolling.track import prepare
    from ..scene import SceneError

    try:
        return prepare(scene)
    except SceneError as exc:
        raise SceneError(f"{path}: {exc}") from None


def _with_step_error(result, track, args):
    """``result`` with the friction's step error (``--step-error``: the run again at twice the
    step, :func:`twoscale.rolling.stepcheck.step_error`), else as it is."""
    if not getattr(args, "step_error", False):
        return result
    import dataclasses

    from ..rolling.run import roll_at_twice_the_step
    from ..rolling.stepcheck import step_error

    return dataclasses.replace(result, step_error=step_error(result, roll_at_twice_the_step(track)))


def _roll_into(out: Path, scene, track, options, status, args, log=None):
    """Roll, writing the VTK frames as the positions come, then the tables."""
    from .._version import __version__
    from ..io.rolling_outputs import FrameWriter, write_rolling_tables, write_signal_products
    from ..rolling.run import roll

    every = max(1, math.ceil(len(track.shifts) / MAX_FRAMES))
    frames = FrameWriter(out, frame_grid(track), track.times, comment=f"twoscale {__version__}; units mm, MPa, s")

    def on_position(pos) -> None:
        if pos.index % every == 0:
            frames(pos)

    result = roll(track.scene, options=options, track=track, on_position=on_position, progress=status)
    frames.close()
    result = _with_step_error(result, track, args)
    write_rolling_tables(result, scene, out, warnings=() if log is None else log.entries())
    write_signal_products(result, scene, out, name=figure_name(Path(args.scene).stem, scene, result))
    return result


def figure_name(stem: str, scene, result) -> str:
    """The run as the figures' titles name it: the scene file's stem, the speed and what is
    held (two runs of one strip at two speeds or loads are told apart by their titles)."""
    held = f"W={scene.total_load:g}N" if result.control == "load" else f"d={scene.penetration:g}mm"
    return f"{stem} {held} {result.spec.speed:g}km/h"


def frame_grid(track):
    """The body grid of the VTK frames: the face window, or around a tyre's footprint."""
    from ..grid import Grid
    from ..rolling.track import footprint_length

    x0, x1, y0, y1 = track.road.window
    h = track.h
    if not math.isfinite(x1 - x0):
        half = 0.6 * footprint_length(track) + 4 * h
        x0, x1 = -half, half
    if not math.isfinite(y1 - y0):
        box = track.road.box
        y0, y1 = float(box[:, 2].min()), float(box[:, 3].max())
    return Grid.covering(x0, x1, y0, y1, h)


#: How the positions were solved, as the summary's first line says it (``rolling.json`` ``method``).
_METHOD_WORDS = {
    "window-cg": "each position one CG over the kept window",
    "twoscale": "each position a two-scale solve",
}


def summary(result, scene_path: str, wall: float, out, *, material=None) -> str:
    """What a user reads after a rolling run (``material``: the body's, for a viscoelastic
    run's start from rest)."""
    n = len(result.shifts)
    bad = int(np.sum(~result.converged))
    lines = [
        f"twoscale solve {scene_path}: rolling, {result.body}, {result.control} control, "
        f"{_METHOD_WORDS.get(result.method, result.method)}",
        f"  positions    {n}, shift {result.shifts[0]:g} to {result.shifts[-1]:g} mm by {result.spec.step:g} mm at "
        f"{result.spec.speed:g} km/h ({result.times[-1]:.4g} s); cell size {result.h:g} mm",
        f"  converged    {'all' if bad == 0 else f'{n - bad} of {n}'}",
        f"  total load   {result.total_load.min():.5g} to {result.total_load.max():.5g} N "
        f"(mean {result.total_load.mean():.5g})",
        f"  approach     {result.penetration.min():.5g} to {result.penetration.max():.5g} mm",
        f"  contact area {result.contact_area.min():.5g} to {result.contact_area.max():.5g} mm2",
        f"  drag         mean {result.mean_drag:.4g} N (road on body along +x), range {result.drag.min():.4g} "
        f"to {result.drag.max():.4g} N",
        f"  time         {wall:.3g} s ({np.mean(result.seconds):.3g} s per position)",
    ]
    if n >= 2:
        lines.insert(-1, _bands_line(result))
    if material is not None and material.viscoelastic:
        lines.insert(-1, start_line(result, material))
    if result.step_error is not None:
        lines.insert(-1, step_error_line(result.step_error, result.step_check))
    balance = result.energy_balance()
    if balance is not None and balance["mismatch"] is not None:
        lines.insert(
            -1,
            f"  energy       drag and load work {balance['drag_work'] + balance['vertical_work']:.4g} N mm against "
            f"{balance['stored_change'] + balance['dissipated']:.4g} N mm stored and dissipated in the branches "
            f"({100 * balance['mismatch']:+.1f} %)",
        )
    if out is not None:
        names = sorted(p.name for p in Path(out).iterdir() if not p.name.startswith("."))
        lines.append(f"  wrote        {out}/: {', '.join(names)}")
    return "\n".join(lines)


def step_error_line(e, check=None) -> str:
    """The summary line of ``--step-error``. The correction assumes the friction's error first
    order in the step; where the two runs differ in sign or by more than half the friction,
    the steps are too coarse for that, and the line says so instead of offering the
    extrapolation as the answer."""
    from ..rolling.stepcheck import first_order_holds

    fine, coarse = e["friction_N"], e["friction_at_twice_the_step_N"]
    line = (
        f"  step error   friction {fine:.4g} N, {coarse:.4g} N at twice the step: about "
        f"{e['estimated_error_N']:+.3g} N to add (extrapolated {e['extrapolated_friction_N']:.4g} N)"
    )
    if first_order_holds(fine, coarse):
        return line
    finer = f" (step <= {check.limit:.3g} mm)" if check is not None and check.coarse else ""
    return (
        f"{line}; the two runs differ by more than half the friction, too far apart for the first-order "
        f"correction to hold: the extrapolation is not an answer, roll at a finer step{finer}"
    )


def start_line(result, material) -> str:
    """The summary line of a viscoelastic run's start: the rubber has no memory at the first
    position and creeps toward the rolling state over a few ``v lambda`` of road (lambda the
    creep compliance's slowest retardation time), which the bands and the mean drag include."""
    from ..viscoelastic.prony import creep_compliance

    lam = float(np.max(creep_compliance(material).lambdas))
    reach = lam * result.spec.speed_mm_s
    run = float(abs(result.shifts[-1] - result.shifts[0]))
    return (
        f"  start        from rest: the rubber creeps toward the rolling state over a few v lambda = {reach:.3g} mm "
        f"of road (slowest retardation time {lam:.3g} s); the first {3 * reach:.3g} mm of this {run:.3g} mm run "
        f"are in the bands and the mean drag"
    )


def _bands_line(result) -> str:
    """Which third-octave bands the run resolves (a band needs 3 frequency bins), and the road
    length the 315 Hz band would need at this speed."""
    from ..io.rolling_outputs import band_signal
    from ..rolling.bands import third_octave_levels

    dt, signal = result.spec.step / result.spec.speed_mm_s, band_signal(result)
    levels = third_octave_levels(signal, dt)
    bands = [f"{float(f):g}" for f in levels.nominal]
    fc = 1000.0 * 10.0 ** (-5 / 10)  # the 315 Hz band's exact centre
    need = 3.0 / (fc * (10**0.05 - 10**-0.05)) * result.spec.speed_mm_s
    said = f"{len(bands)} third-octave band{'s' if len(bands) != 1 else ''} resolved" + (
        f" ({bands[0]} to {bands[-1]} Hz)" if len(bands) > 1 else f" ({bands[0]} Hz)" if bands else ""
    )
    if not bands or float(levels.nominal[0]) > 315:
        said += f"; 315 Hz needs a run of about {need:.3g} mm at this speed (3 bins a band)"
    unit = "N" if result.control == "penetration" else "mm"
    return f"  bands        {said}{_drift_words(signal, levels, dt, unit)}"


def _drift_words(signal: np.ndarray, levels, dt: float, unit: str) -> str:
    """Which bands stand less than 10 dB above what the signal's drift leaks into them: the
    bands see the run as periodic, so the step from the last value back to the first leaks
    like a sawtooth into every band (docs/rolling_signals.md). The leak is measured as the
    levels of a straight line from the first value to the last, by the same periodogram."""
    from ..rolling.bands import third_octave_levels

    if not levels.nominal.size:
        return ""
    jump = float(signal[-1] - signal[0])
    ramp = third_octave_levels(np.linspace(0.0, jump, signal.size), dt).mean_square
    near = int(np.sum(10.0 * ramp > levels.mean_square))
    if not near:
        return ""
    return (
        f"; {near} of them less than 10 dB above what the drift from the first position to the last "
        f"({jump:+.3g} {unit}) leaks into them: there the levels measure the drift, not the texture "
        f"(run longer, or start and end where the signal is alike)"
    )
