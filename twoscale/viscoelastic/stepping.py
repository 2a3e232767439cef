"""Choosing the time steps of a history.

Automatic steps (the default): every time of the history and every output time is a step
end; after a step in the load (a first point other than 0) and after every kink the first
step is short (``FIRST_FRACTION`` of the shortest relaxation time, at most a tenth of the
segment), and the steps then grow geometrically, by at most ``growth`` (4) a step, as long as
the error estimate allows. The estimate: the time-stepping is exact when the pressure is
linear in time over a step, so its local error is that of the linear interpolation of the
response over the step, ``dt^2 |x''| / 8`` for each reported quantity ``x`` (the rigid
approach under load control or the total load under penetration control, and every
asperity's force). ``x''`` is measured from the new step and the two before it (no extra
solve): with ``e = x_{n+1} - x_pred`` the departure from the linear extrapolation of
``x_{n-1}, x_n``, ``x'' ~ 2 e / (dt (dt + dt_prev))`` and the estimate is
``|e| dt / (4 (dt + dt_prev))``. A step is accepted when the estimate is at most ``tol``
times the largest ``|x|``, otherwise redone with half the step; the next step is
``dt min(growth, 0.9 sqrt(tol / estimate))`` (the estimate is second order in dt).
A fixed step count or size replaces all of this (:class:`TimeSteps`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: The error of a quantity is relative to its value, but never to less than this fraction of
#: its largest value so far: an approach drawn back to zero, or a contact that opens, made the
#: scale 1e-300 and the estimate 1e285 (the history stopped at the shortest step).
SCALE_FLOOR = 0.01
#: First step after a step or kink, as a fraction of the shortest relaxation time.
FIRST_FRACTION = 0.05
#: A mark (history or output time) at most this many steps away is reached in one step.
STRETCH = 1.25
#: The shortest automatic step, as a fraction of the history's end: a step whose estimate
#: stays above the tolerance at this size stops the history with a message (halving on
#: would not end: a solve that does not converge gives no error that shrinks with dt).
MIN_STEP_FRACTION = 1e-12


@dataclass(frozen=True)
class TimeSteps:
    """How a history's time steps are chosen.

    Parameters
    ----------
    tol : float, default 1e-2
        Automatic steps: the largest local error estimate accepted, relative to the
        largest value of the quantity (module docstring). Measured on 50 dense tips under
        a 10-branch creep over six decades: forces within 0.03 % of a run with halved
        steps (37 steps; 2e-3 and growth 2: 0.01 %, 62 steps).
    growth : float, default 4.0
        Automatic steps: largest ratio of two successive steps.
    count : int, optional
        Fixed steps: this many equal steps over the history (plus the history's and
        output times, which are always step ends).
    size : float, optional
        Fixed steps: this step, s (the same additions).
    max_steps : int, default 5000
        Most steps (a run that would need more stops with a message).
    at : tuple of float, optional
        Fixed steps: these step ends, s (e.g. another run's, to compare two solvers with
        the same steps, or each of its steps halved: :meth:`halved`).
    """

    tol: float = 1e-2
    growth: float = 4.0
    count: int | None = None
    size: float | None = None
    max_steps: int = 5000
    at: tuple | None = None

    def __post_init__(self) -> None:
        if not (isinstance(self.tol, (int, float)) and math.isfinite(self.tol) and 0 < self.tol < 1):
            raise ValueError(f"time.tol must be a number in (0, 1), got {self.tol!r}")
        if not (isinstance(self.growth, (int, float)) and 1.0 < self.growth <= 100.0):
            raise ValueError(f"time.growth must be a number in (1, 100], got {self.growth!r}")
        if self.count is not None and (
            isinstance(self.count, bool) or not isinstance(self.count, int) or self.count < 1
        ):
            raise ValueError(f"time.steps must be an integer >= 1, got {self.count!r}")
        if self.size is not None and not (
            isinstance(self.size, (int, float))
            and not isinstance(self.size, bool)
            and math.isfinite(self.size)
            and self.size > 0
        ):
            raise ValueError(f"time.dt must be a number > 0 (s), got {self.size!r}")
        if sum(v is not None for v in (self.count, self.size, self.at)) > 1:
            raise ValueError(
                f"give one of time.steps, time.dt and explicit step ends, got "
                f"{self.count!r}, {self.size!r}, {self.at!r}"
            )
        if self.at is not None:
            at = tuple(float(t) for t in self.at)
            if not at or any(not math.isfinite(t) or t < 0 for t in at):
                raise ValueError(f"step ends must be finite times >= 0 (s), got {self.at!r}")
            object.__setattr__(self, "at", tuple(sorted(set(at))))
        if isinstance(self.max_steps, bool) or not isinstance(self.max_steps, int) or self.max_steps < 1:
            raise ValueError(f"time.max_steps must be an integer >= 1, got {self.max_steps!r}")

    @property
    def fixed(self) -> bool:
        return self.count is not None or self.size is not None or self.at is not None

    @classmethod
    def halved(cls, ends) -> TimeSteps:
        """Fixed steps at ``ends`` (s) with every step cut in two."""
        t = np.unique(np.asarray(ends, dtype=float))
        return cls(at=tuple(np.concatenate([t, 0.5 * (t[1:] + t[:-1])]).tolist()))

    def describe(self) -> str:
        if self.count is not None:
            return f"fixed: {self.count} equal steps"
        if self.size is not None:
            return f"fixed: dt = {self.size:g} s"
        if self.at is not None:
            return f"fixed: {len(self.at)} given step ends"
        return f"automatic: tol {self.tol:g}, growth {self.growth:g}"


def fixed_times(steps: TimeSteps, end: float, marks) -> np.ndarray:
    """The step ends of a fixed-step run over ``[0, end]``: equal steps (or the given
    ends) plus ``marks``."""
    if steps.at is not None:
        return _merge(np.concatenate([np.asarray(steps.at), np.asarray(marks, dtype=float)]), end)
    n = steps.count if steps.count is not None else max(math.ceil(end / steps.size - 1e-9), 1)
    grid = np.linspace(0.0, end, n + 1) if end > 0 else np.zeros(1)
    return _merge(np.concatenate([grid, np.asarray(marks, dtype=float)]), end)


def _merge(t: np.ndarray, end: float) -> np.ndarray:
    t = np.unique(np.clip(t, 0.0, end))
    keep = np.concatenate([[True], np.diff(t) > 1e-12 * max(end, 1e-300)])
    return t[keep]


def first_step(shortest: float, segment: float) -> float:
    """First automatic step after a kink, s."""
    return min(FIRST_FRACTION * shortest, 0.1 * segment) if math.isfinite(shortest) else segment


def local_error(x_prev, x_now, x_new, dt_prev: float, dt: float, largest: float = 0.0) -> float:
    """Relative local error estimate of a step from the values of one quantity (array) at
    the three last step ends (module docstring), relative to the largest ``|x|`` of the
    last two, but at least :data:`SCALE_FLOOR` times ``largest`` (the largest so far): a
    quantity back to zero (a contact that opened) is measured against what it was, not zero."""
    x_prev, x_now, x_new = (np.asarray(v, dtype=float) for v in (x_prev, x_now, x_new))
    pred = x_now + (dt / dt_prev) * (x_now - x_prev)
    local = max(float(np.max(np.abs(x_new), initial=0.0)), float(np.max(np.abs(x_now), initial=0.0)))
    scale = max(local, SCALE_FLOOR * largest, 1e-300)
    return float(np.max(np.abs(x_new - pred))) * dt / (4.0 * (dt + dt_prev)) / scale


def largest_values(largest: list, quantities) -> list:
    """``largest`` (one float per quantity, or empty) raised to the largest ``|x|`` of each of
    ``quantities`` (arrays): the running scale of :func:`local_error`."""
    now = [float(np.max(np.abs(np.asarray(q, dtype=float)), initial=0.0)) for q in quantities]
    return [max(a, b) for a, b in zip(largest, now)] if largest else now


@dataclass
class Controller:
    """The automatic step size between the marks (history and output times).

    ``propose(t)`` gives the next step end; ``judge(...)`` says whether the step just
    solved is accepted and sets the next step (module docstring)."""

    steps: TimeSteps
    marks: np.ndarray
    shortest: float
    end: float
    dt: float = 0.0
    _since_kink: int = 0
    #: Why the steps cannot go on (a rejected step already at the shortest), else None.
    stuck: str | None = None

    def restart(self, t: float) -> None:
        """A kink at ``t``: the next step is a first step."""
        nxt = self._next_mark(t)
        self.dt = first_step(self.shortest, nxt - t)
        self._since_kink = 0

    def _next_mark(self, t: float) -> float:
        later = self.marks[self.marks > t * (1 + 1e-12) + 1e-300]
        return float(later[0]) if later.size else self.end

    def propose(self, t: float) -> float:
        """The next step end after ``t`` (never beyond the next mark): the mark itself when
        it is at most :data:`STRETCH` steps away, half way to it when at most two steps
        (no sliver of a step before a mark)."""
        nxt = self._next_mark(t)
        left = nxt - t
        if left <= STRETCH * self.dt:
            return nxt
        if left <= 2.0 * self.dt:
            return t + 0.5 * left
        return t + self.dt

    def accept(self, dt: float, error: float | None) -> bool:
        """Record a solved step of length ``dt`` with its estimate (None: none yet);
        return False when it must be redone with a shorter step, or, with :attr:`stuck` set,
        when it is rejected at the shortest step (:data:`MIN_STEP_FRACTION`)."""
        if error is not None and not error <= self.steps.tol:  # NaN: rejected too
            if dt > MIN_STEP_FRACTION * self.end:
                self.dt = 0.5 * dt
            else:
                self.stuck = (
                    f"the step's error estimate {error:.3g} stayed above time.tol = {self.steps.tol:g} "
                    f"down to dt = {dt:.3g} s, the shortest step ({MIN_STEP_FRACTION:g} of the history)"
                )
            return False
        factor = (
            self.steps.growth
            if error is None or error == 0
            else min(self.steps.growth, max(0.5, 0.9 * math.sqrt(self.steps.tol / error)))
        )
        self.dt = max(dt, self.dt) * factor  # a step cut short by a mark keeps the size it had
        self._since_kink += 1
        return True


__all__ = [
    "FIRST_FRACTION",
    "MIN_STEP_FRACTION",
    "STRETCH",
    "Controller",
    "TimeSteps",
    "first_step",
    "fixed_times",
    "local_error",
]
