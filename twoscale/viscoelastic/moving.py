"""Indenters moving under a viscoelastic body: the core of rolling.

The memory of the body (:mod:`twoscale.viscoelastic.memory`) lives on a grid fixed in the
body, the *memory grid*; the indenter moves along +x (a point of it at ``x`` appears at
body ``x + shift``, :mod:`.moving_indenter`). Position ``n`` is reached at
``t_n = (shift_n - shift_0) / speed``; each step is, exactly as in a load history
(:mod:`.solve`), the elastic contact problem at the compliance ``J_eff`` of the step with the
history displacement ``K H`` of the memory, on the indenter at its new position, solved by
the full-grid reference on the memory grid or by the two-scale method (patches on the
memory grid's lattice). The steps are the positions: there is no time-step control; the
local error estimate of the time-stepping (:func:`.stepping.local_error`) is reported per
step all the same.

The memory grid must cover every cell the contact reaches over the run (the footprint
swept from the first to the last shift); :func:`sweep_grid` builds it for tips, and a step
whose pressure reaches the grid's edge, or lies partly beyond it, says so (not converged),
unless the grid is declared the body's footprint (``MovingOptions(open_edges=True)``: a
tread block's face, or a window of the half-space under a road, where contact is cut at
the edge by the body itself).

Drag: ``drag_N = h^2 sum p dz/dx`` over the contact, ``z`` the moving surface's recess (the
road's, not a fixed face's), that is ``-h^2 sum p dH/dx`` with ``H = -z`` the road's height
towards the body: the horizontal force the indenter exerts on the body along +x, the
direction it moves (the road's surface pushes along its normal, which leans back, -x, where
the road rises). Positive drag resists the motion (the road must be pushed); its
integral over the distance is the work put in, so over a steady run the mean drag times the
distance is the energy dissipated in the branches, reported per step from their internal
variables (:mod:`.dissipation`: exact for a pressure linear in time over a step).
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Callable

import numpy as np

from ..indenters import Surface
from ..material import Material
from .dissipation import BranchEnergy
from .memory import Memory, effective_compliance
from .moving_result import MovingResult, StepSummary
from .prony import creep_compliance
from .stepping import largest_values, local_error
from .steps import StepProblem, TwoScaleStep, scaled
from .motion import MOVING_METHODS, MOTION_KEYWORDS, STARTS, Motion, MovingOptions, motion_of, sweep_grid  # noqa: F401


def _check(material, provider) -> None:
    if not isinstance(material, Material):
        raise ValueError(f"material must be a twoscale.material.Material, got {type(material).__name__}")
    if provider.material.relaxed() != material.relaxed():
        raise ValueError(
            f"the provider's material {provider.material!r} is not the relaxed "
            f"{material.relaxed()!r} (build the body at the relaxed modulus)"
        )


def solve_moving(
    material: Material,
    provider,
    indenter,
    motion: Motion,
    *,
    options: MovingOptions | None = None,
    progress: Callable | None = None,
    on_step: Callable | None = None,
    **legacy,
) -> MovingResult:
    """Move ``indenter`` through ``shifts`` under a viscoelastic body, the memory in the body.

    Parameters
    ----------
    material : Material
        With Prony branches (or none: quasi-static elastic, every position a static solve).
    provider : InfluenceProvider
        The body at the relaxed modulus (``material.relaxed()``): half-space or block.
    indenter : MovingIndenter
        The rigid surface as a function of the shift: :class:`.moving_indenter.MovingAsperities`,
        :class:`.moving_indenter.MovingHeights`, or any object with their methods.
    motion : Motion
        The positions (mm), the speed (mm/s), the memory grid and the held control.
        The older form, the shifts here with ``speed=``, ``grid=``, ``penetration=`` or
        ``total_load=`` as keywords (``**legacy``), builds the same :class:`Motion`.
    options : MovingOptions, optional
    progress : callable, optional
        Called with a line per position.
    on_step : callable, optional
        Called as ``on_step(n, shift, result, summary)`` with each position's ContactResult
        and its :class:`~.moving_result.StepSummary` (load, approach, area, drag, energy...):
        to write rows and fields or reduce them as the run goes, without keeping them.

    Returns
    -------
    MovingResult
    """
    t0 = time.perf_counter()
    motion = motion_of(motion, legacy)
    _check(material, provider)
    s, grid = np.asarray(motion.shifts, dtype=float), motion.grid
    options = options or MovingOptions()
    if options.method == "twoscale" and indenter.tips(float(s[0])) is None:
        raise ValueError("method 'twoscale' needs tips (MovingAsperities); a height field runs with 'reference'")
    kind, value = motion.control
    roll = _Roll(material, provider, indenter, grid, kind, value, options)
    times = (s - s[0]) / float(motion.speed)
    for n, shift in enumerate(s):
        dt = times[n] - times[n - 1] if n else _first_step(options.start, times)
        result = roll.step(n, float(shift), float(dt))
        if progress is not None:
            progress(
                f"shift {shift:.4g} mm, t = {times[n]:.4g} s: load {result.total_load:.4g} N, approach "
                f"{result.penetration:.4g} mm, drag {roll.records[-1].drag:.4g} N"
            )
        if on_step is not None:
            on_step(n, float(shift), result, roll.records[-1])
    return roll.result(s, times, float(motion.speed), time.perf_counter() - t0)


def _first_step(start: str, times: np.ndarray) -> float:
    """The step to the first position (s): inf from a relaxed hold, else the ramp over the
    first step's time (0, the glassy instant, for a single position)."""
    if start == "relaxed":
        return math.inf
    return float(times[1] - times[0]) if times.size > 1 else 0.0


class _Roll:
    """The state of one moving run: memory, energy, previous answers, records."""

    def __init__(self, material, provider, indenter, grid, kind, value, options: MovingOptions):
        self.material, self.provider, self.indenter, self.grid = material, provider, indenter, grid
        self.kind, self.value, self.options = kind, value, options
        self.J = creep_compliance(material)
        self.memory = Memory(self.J, grid.size)
        self.energy = BranchEnergy(self.memory, grid.h)
        self.E0 = float(provider.material.E)
        self.op = provider.grid_operator(grid)
        self.records: list[StepSummary] = []
        self.results: list = []
        self.last = self.before = None  # (shift, ContactResult, pressure on the grid)
        self.quantities: list = []
        self.largest: list = []  # the largest |x| of each stepped quantity so far

    def _solve(self, shift: float, factor: float, u_H: np.ndarray) -> tuple:
        o = self.options
        if o.method == "twoscale":
            step = TwoScaleStep(
                self.provider,
                self.indenter.tips(shift),
                self.grid,
                h=self.grid.h,
                kind=self.kind,
                tilt=False,
                pivot=(0.0, 0.0),
                options=o.solver,
            )
            start = self.last[1] if self.last is not None else None
            before = (
                None
                if self.last is None
                else np.array([[a.x, a.y] for a in self.indenter.tips(self.last[0])], dtype=float).reshape(-1, 2)
            )
            _, slope = self.indenter.surface(self.grid, shift)
            extra = u_H + self.indenter.face_on(self.grid)
            return step.solve(StepProblem(self.value, factor, extra, start, before)), slope
        from ..reference import AUTO_DENSE_CELLS, solve_reference

        surf, slope = self.indenter.surface(self.grid, shift)
        moved = Surface(self.grid, surf.height + u_H, surf.owner, surf.n_asperities)
        solver = o.method
        if solver == "reference":
            solver = "dense" if np.count_nonzero(np.isfinite(surf.height)) <= AUTO_DENSE_CELLS else "cg"
        opts = dict(o.solver)
        if solver == "cg" and self.last is not None:
            opts.setdefault("start", self._moved_start(shift) * factor)
            if o.near_gap is not None and self.last[1].fields:
                gap = self.last[1].fields[0].gap
                near = self._moved(np.where(np.isfinite(gap), gap, np.inf), shift - self.last[0], np.inf)
                opts.setdefault("reach", (near < o.near_gap) | (opts["start"] > 0.0))
        load = {"penetration": self.value} if self.kind == "penetration" else {"total_load": self.value * factor}
        return scaled(solve_reference(self.provider, moved, method=solver, **load, **opts), 1.0 / factor), slope

    def _moved_start(self, shift: float) -> np.ndarray:
        """A CG warm start: the last pressure moved with the indenter by whole cells, and
        extrapolated linearly in time (in the indenter's frame) from the one before."""
        last = self._moved(self.last[2], shift - self.last[0])
        if self.before is None:
            return last
        return np.maximum(2.0 * last - self._moved(self.before[2], shift - self.before[0]), 0.0)

    def _moved(self, p: np.ndarray, by: float, fill: float = 0.0) -> np.ndarray:
        k = int(round(by / self.grid.h))
        p = p.reshape(self.grid.shape)
        out = np.full_like(p, fill)
        if 0 <= k < p.shape[1]:
            out[:, k:] = p[:, : p.shape[1] - k]
        return out

    def step(self, n: int, shift: float, dt: float):
        t0 = time.perf_counter()
        J_eff = effective_compliance(self.J, dt)
        H = self.memory.history_field(dt)
        u_H = self.E0 * self.op.apply(H.reshape(self.grid.shape)) if np.any(H) else np.zeros(self.grid.shape)
        factor = self.E0 * J_eff
        result, slope = self._solve(shift, factor, u_H)
        p = result.pressure_on(self.grid).ravel()
        p_old = np.zeros(self.grid.size)
        p_old[self.memory.cells] = self.memory.p
        K_dp = self.E0 * self.op.apply((p - p_old).reshape(self.grid.shape)).ravel()
        dissipated = self.energy.step(dt, p, K_dp)
        self.memory.advance(dt, p)
        stored = self.energy.stored()
        h2 = self.grid.h**2
        edge = []
        on_grid = h2 * float(p.sum())
        if abs(on_grid - result.total_load) > 1e-9 * max(abs(result.total_load), 1e-300):
            edge.append(f"{result.total_load - on_grid:.3g} N of pressure lies beyond the memory grid")
        if not self.options.open_edges and _on_edge(p.reshape(self.grid.shape)):
            edge.append("pressure reaches the memory grid's edge")
        message = "; ".join(([result.message] if result.message and not result.converged else []) + edge)
        self.quantities.append(
            (
                np.array([result.penetration if self.kind == "total" else result.total_load]),
                np.asarray(result.forces, dtype=float),
            )
        )
        self.largest = largest_values(self.largest, self.quantities[-1])
        self.records.append(
            StepSummary(
                shift=shift,
                dt=dt,
                J_eff=J_eff,
                total_load=float(result.total_load),
                penetration=float(result.penetration),
                contact_area=float(result.contact_area),
                drag=h2 * float(p @ slope.ravel()),
                forces=np.asarray(result.forces, dtype=float),
                tip_areas=np.asarray(result.asperities.contact_areas),
                dissipated=dissipated,
                stored=stored,
                error=self._estimate(dt),
                converged=bool(result.converged) and not edge,
                message=message,
                iterations=_iterations(result),
                seconds=time.perf_counter() - t0,
            )
        )
        self.before, self.last = self.last, (shift, result, p)
        if self.options.keep_results:
            self.results.append(result)
        return result

    def _estimate(self, dt: float) -> float:
        """Local error estimate of the time-stepping at the step just solved, from it and the
        two positions before (nan before the third position)."""
        if len(self.quantities) < 3 or not math.isfinite(self.records[-1].dt) or self.records[-1].dt <= 0:
            return math.nan
        x = self.quantities[-3:]
        return max(local_error(a, b, c, self.records[-1].dt, dt, m) for a, b, c, m in zip(*x, self.largest))

    def result(self, shifts, times, speed: float, seconds: float) -> MovingResult:
        nb = int(self.J.lambdas.size)
        memory = {
            "branches": nb,
            "peak_cells": int(self.memory.peak_cells),
            "bytes_per_cell": 8 * (2 + nb),
            "peak_bytes": int(8 * (2 + nb) * self.memory.peak_cells),
            "grid_cells": int(self.grid.size),
            "grid": dataclasses.asdict(self.grid),
        }
        return MovingResult.from_steps(
            self.records,
            times=times,
            shifts=shifts,
            speed=speed,
            material=self.material,
            grid=self.grid,
            control=self.kind,
            value=self.value,
            method=self.options.method,
            start=self.options.start,
            results=tuple(self.results),
            memory=memory,
            seconds=seconds,
        )


def _on_edge(p: np.ndarray) -> bool:
    return bool(np.any(p[0] > 0) or np.any(p[-1] > 0) or np.any(p[:, 0] > 0) or np.any(p[:, -1] > 0))


def _iterations(result) -> int:
    return int(sum(v for v in result.iterations.values() if isinstance(v, (int, np.integer))))


__all__ = ["MOVING_METHODS", "MOTION_KEYWORDS", "Motion", "MovingOptions", "solve_moving", "sweep_grid"]
