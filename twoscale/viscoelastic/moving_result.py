"""The result of a moving run (:func:`twoscale.viscoelastic.moving.solve_moving`): a row per
position, as arrays."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..grid import Grid
from ..material import Material


@dataclass(frozen=True)
class StepSummary:
    """One position: its shift (mm), the step to it (s; inf: the relaxed start), ``J_eff``
    (1/MPa), load (N), approach (mm), contact area (mm^2), drag (N), per-tip forces (N) and
    contact areas (mm^2), energy dissipated over the step and stored after it (N mm), local
    error estimate (relative; nan where none), convergence, solver iterations and seconds."""

    shift: float
    dt: float
    J_eff: float
    total_load: float
    penetration: float
    contact_area: float
    drag: float
    forces: np.ndarray
    tip_areas: np.ndarray
    dissipated: float
    stored: float
    error: float
    converged: bool
    message: str
    iterations: int
    seconds: float


def _frozen(a, dtype=float) -> np.ndarray:
    a = np.array(a, dtype=dtype)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class MovingResult:
    """An indenter moved under a (viscoelastic) body; arrays have a row per position.

    Attributes
    ----------
    times : (n,) array
        s, from the first position.
    shifts : (n,) array
        mm.
    total_load, penetration, contact_area, drag : (n,) arrays
        N, mm, mm^2, N. ``drag``: the horizontal force the indenter exerts on the body
        along +x (the direction it moves); positive resists the motion.
    forces, tip_areas : (n, N) arrays
        Per-tip force (N) and contact area (mm^2), tips in the indenter's order (0-based).
    dissipated : (n,) array
        Energy dissipated in the branches over the step to each position, N mm (the
        first: over the ramp from rest, 0 after a relaxed start).
    stored : (n,) array
        Energy stored in the body at each position, N mm.
    errors : (n,) array
        Local error estimate of the time-stepping (relative; nan at the first two).
    step_converged : (n,) bool array
    iterations : (n,) int array
    seconds : (n,) array
    speed : float
        mm/s.
    material : Material
    grid : Grid
        The memory grid.
    control : {"penetration", "total"}
    value : float
        The held approach (mm) or load (N).
    method, start : str
    results : tuple of ContactResult
        Every position's, with ``MovingOptions(keep_results=True)``; else empty.
    memory : dict
        Cells and bytes of the memory at its peak (as in a history).
    converged : bool
    message : str
        The positions that did not converge and why.
    timings_s : dict
    """

    times: np.ndarray
    shifts: np.ndarray
    total_load: np.ndarray
    penetration: np.ndarray
    contact_area: np.ndarray
    drag: np.ndarray
    forces: np.ndarray
    tip_areas: np.ndarray
    dissipated: np.ndarray
    stored: np.ndarray
    errors: np.ndarray
    step_converged: np.ndarray
    iterations: np.ndarray
    seconds: np.ndarray
    speed: float
    material: Material
    grid: Grid
    control: str
    value: float
    method: str
    start: str
    results: tuple
    memory: dict
    converged: bool
    message: str
    timings_s: dict

    @classmethod
    def from_steps(cls, steps, *, times, shifts, seconds: float, **fields) -> MovingResult:
        def col(name, dtype=float):
            return _frozen([getattr(s, name) for s in steps], dtype)

        bad = [f"shift {s.shift:.6g} mm: {s.message or 'not converged'}" for s in steps if not s.converged]
        return cls(
            times=_frozen(times),
            shifts=_frozen(shifts),
            total_load=col("total_load"),
            penetration=col("penetration"),
            contact_area=col("contact_area"),
            drag=col("drag"),
            forces=col("forces"),
            tip_areas=col("tip_areas"),
            dissipated=col("dissipated"),
            stored=col("stored"),
            errors=col("error"),
            step_converged=col("converged", bool),
            iterations=col("iterations", np.int64),
            seconds=col("seconds"),
            converged=not bad,
            message="; ".join(bad),
            timings_s={"total": float(seconds), "steps": float(sum(s.seconds for s in steps))},
            **fields,
        )

    @property
    def distance(self) -> float:
        """Distance moved, mm."""
        return float(self.shifts[-1] - self.shifts[0])

    def drag_work(self, first: int = 0, last: int | None = None) -> float:
        """``int drag ds`` from position ``first`` to ``last`` (default the end), N mm
        (trapezoidal rule over the positions)."""
        s = self.shifts[first : None if last is None else last + 1]
        d = self.drag[first : None if last is None else last + 1]
        return float(np.sum(0.5 * (d[1:] + d[:-1]) * np.diff(s)))

    def vertical_work(self, first: int = 0, last: int | None = None) -> float:
        """``int W dd`` from position ``first`` to ``last``, N mm (trapezoidal): the work of
        the load as the approach changes (0 under penetration control). The energy balance
        is ``drag_work + vertical_work = stored change + dissipated``."""
        s = slice(first, None if last is None else last + 1)
        W, d = self.total_load[s], self.penetration[s]
        return float(np.sum(0.5 * (W[1:] + W[:-1]) * np.diff(d)))

    def dissipated_between(self, first: int = 0, last: int | None = None) -> float:
        """Energy dissipated from position ``first`` to ``last`` (default the end), N mm."""
        return float(np.sum(self.dissipated[first + 1 : None if last is None else last + 1]))

    @property
    def max_error(self) -> float:
        """Largest local error estimate (0 when none could be made)."""
        e = self.errors[np.isfinite(self.errors)]
        return float(e.max()) if e.size else 0.0

    def __repr__(self) -> str:
        state = "converged" if self.converged else "NOT converged"
        return (
            f"<MovingResult {self.method}: {self.shifts.size} positions over {self.distance:.4g} mm at "
            f"{self.speed:.4g} mm/s, mean drag {float(np.mean(self.drag)):.4g} N, dissipated "
            f"{float(np.sum(self.dissipated)):.4g} N mm, {state}, {self.timings_s['total']:.3g} s>"
        )

    __str__ = __repr__


__all__ = ["MovingResult", "StepSummary"]
