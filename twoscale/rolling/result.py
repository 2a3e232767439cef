"""What a rolling run returns: a signal per position, the stones' forces, convergence and
timings, as a frozen :class:`RollingResult` (arrays read-only)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any
from dataclasses import dataclass, field

import numpy as np

from ..results import FrozenMapping, frozen_array
from .spec import RollingSpec


@dataclass(frozen=True)
class Position:
    """One solved position: its index, the stones given (a
    :class:`~twoscale.rolling.stones.Selection`), the solve (a ContactResult), the drag (N),
    the wall-clock time it took (s) and the CPU time of the thread that solved it (s; nan
    where it was not taken)."""

    index: int
    selection: Any
    result: Any
    drag: float
    seconds: float
    cpu_seconds: float = float("nan")


#: Per-position arrays of a :class:`RollingResult` (one entry per position).
SIGNALS = (
    "times",
    "shifts",
    "total_load",
    "penetration",
    "contact_area",
    "drag",
    "converged",
    "seconds",
    "cpu_seconds",
    "stones",
    "iterations",
)


@dataclass(frozen=True)
class StoneSignals:
    """Forces of the stones in contact, one row per (position, stone).

    Attributes
    ----------
    position : (M,) int array
        Index of the position (0-based, as in :attr:`RollingResult.shifts`).
    stone : (M,) int array
        The stone's number, from 1: its segmentation label + 1 on a height map, its
        place in the scene's asperity list otherwise.
    force : (M,) array, N
    contact_area : (M,) array, mm^2
    """

    position: np.ndarray
    stone: np.ndarray
    force: np.ndarray
    contact_area: np.ndarray

    def __post_init__(self) -> None:
        for name in ("position", "stone"):
            object.__setattr__(self, name, frozen_array(getattr(self, name), np.int64))
        for name in ("force", "contact_area"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))


@dataclass(frozen=True)
class RollingResult:
    """A rolling run: the road under the body at every position.

    Attributes
    ----------
    spec : RollingSpec
        The run as asked (``shifts`` are the ones solved: on a height map they sit on
        its lattice, see :func:`twoscale.rolling.run.lattice`).
    method : str
        The per-position solver: ``"window-cg"`` (one constrained CG over a window kept in
        the body, :mod:`twoscale.rolling.window`) or ``"twoscale"`` (the two-scale solver).
    control : str
        ``"penetration"`` (the approach held, the force varies) or ``"load"``.
    h : float
        Cell size, mm (on a height map: its spacing, resampled so that the step is a
        multiple of it).
    times, shifts : (n,) arrays, s and mm
    total_load, penetration, contact_area, drag : (n,) arrays
        N, mm (below the road's highest point), mm^2, N. ``drag`` is the force the road
        exerts on the body along +x: the sum over the contact of the pressure times the
        road's x-slope (the slope of its recess below the highest point), times the cell
        area; positive when the road pushes the body forward.
    converged : (n,) bool array
    seconds : (n,) array
        Wall-clock time of each position, s.
    cpu_seconds : (n,) array
        CPU time of each position, s: the thread's that solved it (on a shared host the
        wall-clock time counts the other jobs' turns, this one does not).
    stones : (n,) int array
        Stones given to the solver at each position (within reach of the footprint).
    iterations : (n,) int array
        Per position: the micro step's sweeps (``method="twoscale"``) or the CG's
        iterations (``"window-cg"``).
    messages : tuple of str
        The solver's message per position ("" when it converged cleanly).
    asperities : StoneSignals
        The stones in contact at each position.
    line_x : (m,) array, mm
        Body x of the cell columns of ``line_load`` (the lattice of cell ``h``).
    line_load : (n, m) array, N/mm
        Pressure summed across y (times the cell size) at each position and body x: the
        space-time picture in which the stones go through the footprint.
    dissipated, stored : (n,) arrays, N mm
        A viscoelastic run's energy dissipated in the branches over the step to each position
        (the first: over the ramp-in) and stored in the body at each position; empty for an
        elastic run (nothing dissipated; the stored energy is not computed).
    timings_s : mapping
        Wall seconds: ``segment`` (the strip's segmentation, when the scene was read or, for
        a strip resampled to the step's lattice, within ``prepare``; 0 for tips), ``prepare``
        (the checks, the body, the road's tables), ``positions``, ``total`` (``prepare`` and
        ``positions``).
    body : str
        What the body is (``"half-space"``, ``"block 150 x 100 x 10 mm, bonded base"``).
    step_check : StepCheck, optional
        The step against the road's samples and the active Prony branches
        (:mod:`twoscale.rolling.stepcheck`; coarse only for a viscoelastic run).
    step_error : mapping, optional
        The friction's step error from a run at twice the step
        (:func:`twoscale.rolling.stepcheck.step_error`), when it was measured.
    """

    spec: RollingSpec
    method: str
    control: str
    h: float
    times: np.ndarray
    shifts: np.ndarray
    total_load: np.ndarray
    penetration: np.ndarray
    contact_area: np.ndarray
    drag: np.ndarray
    converged: np.ndarray
    seconds: np.ndarray
    cpu_seconds: np.ndarray
    stones: np.ndarray
    iterations: np.ndarray
    messages: tuple
    asperities: StoneSignals
    line_x: np.ndarray = field(default_factory=lambda: np.zeros(0))
    line_load: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    dissipated: np.ndarray = field(default_factory=lambda: np.zeros(0))
    stored: np.ndarray = field(default_factory=lambda: np.zeros(0))
    timings_s: Mapping = field(default_factory=dict)
    body: str = ""
    step_check: Any = None
    step_error: Mapping | None = None

    def __post_init__(self) -> None:
        for name in SIGNALS:
            dtype = {"converged": bool, "stones": np.int64, "iterations": np.int64}.get(name, float)
            object.__setattr__(self, name, frozen_array(getattr(self, name), dtype))
        n = len(self.shifts)
        for name in SIGNALS:
            if getattr(self, name).shape != (n,):
                raise ValueError(f"{name} has shape {getattr(self, name).shape}, expected ({n},)")
        object.__setattr__(self, "messages", tuple(self.messages))
        object.__setattr__(self, "line_x", frozen_array(self.line_x))
        object.__setattr__(self, "line_load", frozen_array(self.line_load))
        for name in ("dissipated", "stored"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))
        object.__setattr__(self, "timings_s", FrozenMapping(self.timings_s))
        if self.step_error is not None:
            object.__setattr__(self, "step_error", FrozenMapping(self.step_error))

    @property
    def all_converged(self) -> bool:
        """Whether every position converged."""
        return bool(np.all(self.converged))

    @property
    def mean_drag(self) -> float:
        """Mean of ``drag`` over the positions, N (the rolling resistance the texture
        causes; zero for an elastic body over a periodic road)."""
        return float(np.mean(self.drag))

    def drag_work(self) -> float:
        """Work of the drag over the run, N mm: the trapezoid rule over the shifts (for a
        viscoelastic run it equals the energy stored plus dissipated from the first
        position on, to second order in the step)."""
        d, s = self.drag, self.shifts
        return float(np.sum(0.5 * (d[1:] + d[:-1]) * np.diff(s)))

    def vertical_work(self) -> float:
        """Work of the load as the approach changes, ``int W dd`` over the run, N mm
        (trapezoid rule; 0 under penetration control)."""
        W, d = self.total_load, self.penetration
        return float(np.sum(0.5 * (W[1:] + W[:-1]) * np.diff(d)))

    def energy_balance(self) -> dict | None:
        """A viscoelastic run's energy balance from the first position on, N mm: the work the
        road does on the rubber (``drag_work`` + ``vertical_work``) against the energy the
        branches store (``stored_change``) and dissipate (``dissipated``); ``mismatch`` =
        work / energy - 1. The stepping meets it to second order in the step, so a mismatch
        of more than a few percent says the step is too coarse (:mod:`twoscale.rolling.stepcheck`);
        a small one does not prove the friction converged (it moves at first order in the
        step). None for an elastic run."""
        if not self.dissipated.size:
            return None
        work = self.drag_work() + self.vertical_work()
        dissipated = float(np.sum(self.dissipated[1:]))
        stored = float(self.stored[-1] - self.stored[0])
        energy = dissipated + stored
        return {
            "drag_work": self.drag_work(),
            "vertical_work": self.vertical_work(),
            "stored_change": stored,
            "dissipated": dissipated,
            "mismatch": work / energy - 1.0 if energy > 0 else None,
        }

    def __repr__(self) -> str:
        state = "converged" if self.all_converged else f"{int(np.sum(~self.converged))} positions NOT converged"
        return (
            f"<RollingResult {len(self.shifts)} positions from {self.shifts[0]:g} to {self.shifts[-1]:g} mm, "
            f"{self.control} control, load {self.total_load.min():.4g}-{self.total_load.max():.4g} N, "
            f"mean drag {self.mean_drag:.4g} N, {state}, {self.timings_s.get('total', 0.0):.3g} s>"
        )
