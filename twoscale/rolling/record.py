"""Recording a rolling run position by position into its :class:`RollingResult`: the
signals' row of each position, the forces of its stones in contact, and its line load
(pressure summed across y) on one lattice of columns for the space-time picture."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..results import ContactResult
from .result import Position, RollingResult, StoneSignals
from .track import Track


@dataclass
class Recorder:
    """What a rolling loop has solved so far (one entry per position, in order)."""

    rows: list = field(default_factory=list)
    stones: list = field(default_factory=list)
    lines: list = field(default_factory=list)

    def add(self, pos: Position) -> None:
        """Record one solved position."""
        self.rows.append(_row(pos))
        self.stones.append(_stone_rows(pos))
        self.lines.append(line_load_of(pos.result))

    def result(self, track: Track, timings: dict, method: str) -> RollingResult:
        """The run's result: every recorded position, the timings (s) and the solver used."""
        cols = list(zip(*self.rows))
        line_x, line_load = lines_on_lattice(self.lines, track.h)
        stones = np.concatenate(self.stones) if self.stones else np.zeros((0, 4))
        return RollingResult(
            spec=track.spec,
            method=method,
            control=track.control,
            h=track.h,
            times=track.times,
            shifts=track.shifts,
            total_load=cols[0],
            penetration=cols[1],
            contact_area=cols[2],
            drag=cols[3],
            converged=cols[4],
            seconds=cols[5],
            cpu_seconds=cols[6],
            stones=cols[7],
            iterations=cols[8],
            messages=cols[9],
            asperities=StoneSignals(stones[:, 0], stones[:, 1], stones[:, 2], stones[:, 3]),
            line_x=line_x,
            line_load=line_load,
            timings_s=timings,
            body=track.body,
            step_check=track.step_check,
        )


def _row(pos: Position) -> tuple:
    r = pos.result
    return (
        r.total_load,
        r.penetration,
        r.contact_area,
        pos.drag,
        r.converged,
        pos.seconds,
        pos.cpu_seconds,
        len(pos.selection.stones),
        int(r.iterations.get("micro", r.iterations.get("cg", 0))),
        r.message,
    )


def _stone_rows(pos: Position) -> np.ndarray:
    a = pos.result.asperities
    touching = np.flatnonzero(a.contact_areas > 0)
    return np.column_stack(
        [
            np.full(len(touching), pos.index),
            pos.selection.numbers[touching] + 1,
            a.forces[touching],
            a.contact_areas[touching],
        ]
    )


def line_load_of(result: ContactResult) -> tuple[int, np.ndarray]:
    """Pressure summed across y (x the cell size), N/mm, per cell column: (first column's
    lattice index round(x / h), values)."""
    if not result.fields:
        return 0, np.zeros(0)
    h = result.fields[0].grid.h
    starts = [int(round(f.grid.x0 / h)) for f in result.fields]
    i0 = min(starts)
    out = np.zeros(max(s + f.grid.nx for s, f in zip(starts, result.fields)) - i0)
    for s, f in zip(starts, result.fields):
        out[s - i0 : s - i0 + f.grid.nx] += f.pressure.sum(axis=0) * h
    return i0, out


def lines_on_lattice(lines: list, h: float) -> tuple[np.ndarray, np.ndarray]:
    """The line loads of every position on one lattice of columns."""
    used = [(i0, v) for i0, v in lines if v.size]
    if not used:
        return np.zeros(0), np.zeros((len(lines), 0))
    lo = min(i0 for i0, _ in used)
    hi = max(i0 + v.size for i0, v in used)
    out = np.zeros((len(lines), hi - lo))
    for k, (i0, v) in enumerate(lines):
        out[k, i0 - lo : i0 - lo + v.size] = v
    return (lo + np.arange(hi - lo)) * h, out
