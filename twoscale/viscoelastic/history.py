"""Load histories: a piecewise-linear total load or rigid approach in time, and the times
to report.

A history is a list of points ``[[t, value], ...]`` (s; N or mm) with strictly increasing
times ``t >= 0``; between points the value is linear, before the first point it is 0, after
the last it is held. A first point with a value other than 0 is a step at its time (the
response just after it is the glassy one). Bad data raise ``ValueError`` with one line
naming the field (``load.total[2]``, ``time.output[0]``) and the value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np

from .stepping import TimeSteps

#: Control kinds: ``"total"`` (N, load control) or ``"penetration"`` (mm).
CONTROL_KINDS = ("total", "penetration")


def _number(path: str, v, unit: str) -> float:
    if (
        isinstance(v, (bool, np.bool_))
        or not isinstance(v, (int, float, np.integer, np.floating))
        or not math.isfinite(float(v))
    ):
        raise ValueError(f"{path} must be a finite number ({unit}), got {v!r}")
    return float(v)


@dataclass(frozen=True)
class LoadHistory:
    """A piecewise-linear load history and its output times.

    Parameters
    ----------
    kind : {"total", "penetration"}
        What is prescribed: the total load (N) or the rigid approach (mm).
    points : sequence of (t, value)
        Times (s, >= 0, strictly increasing) and values (N >= 0, or mm).
    output : sequence of float, optional
        Times reported (s, within the history's first and last times); default: every step taken plus
        each time of the history.
    steps : TimeSteps, optional
        How the time steps are chosen (default: automatic, :class:`TimeSteps`).
    """

    kind: str
    points: tuple
    output: tuple | None = None
    steps: TimeSteps = field(default_factory=TimeSteps)

    def __post_init__(self) -> None:
        if self.kind not in CONTROL_KINDS:
            raise ValueError(f"history kind must be one of {CONTROL_KINDS}, got {self.kind!r}")
        path, unit = f"load.{self.kind}", ("N" if self.kind == "total" else "mm")
        pts = self.points
        if isinstance(pts, (str, bytes)) or not hasattr(pts, "__len__") or len(pts) == 0:
            raise ValueError(f"{path} must be a number or a list of [t, value] pairs (s, {unit}), got {pts!r}")
        out = []
        for i, row in enumerate(pts):
            if isinstance(row, (str, bytes, dict)) or not hasattr(row, "__len__") or len(row) != 2:
                raise ValueError(f"{path}[{i}] must be a pair [t, value] (s, {unit}), got {row!r}")
            t = _number(f"{path}[{i}] time", row[0], "s")
            v = _number(f"{path}[{i}] value", row[1], unit)
            if t < 0:
                raise ValueError(f"{path}[{i}] time must be >= 0 (s), got {row[0]!r}")
            if out and not t > out[-1][0]:
                raise ValueError(
                    f"{path}[{i}] time must be greater than the one before ({out[-1][0]!r} s): "
                    f"times must increase, got {row[0]!r}"
                )
            if self.kind == "total" and v < 0:
                raise ValueError(f"{path}[{i}] value must be >= 0 (N), got {row[1]!r}")
            out.append((t, v))
        object.__setattr__(self, "points", tuple(out))
        if self.kind == "total" and not any(v > 0 for _, v in out):
            raise ValueError(f"{path} never exceeds 0 N, got {list(map(list, out))!r}")
        if not isinstance(self.steps, TimeSteps):
            raise ValueError(f"history steps must be a TimeSteps, got {self.steps!r}")  # noqa: TRY004
        if self.output is not None:
            object.__setattr__(self, "output", self._checked_output())

    def _checked_output(self) -> tuple:
        o = self.output
        if isinstance(o, (str, bytes)) or not hasattr(o, "__len__") or len(o) == 0:
            raise ValueError(f"time.output must be a list of times (s), got {o!r}")
        start, end = self.points[0][0], self.end
        out = []
        for i, t in enumerate(o):
            t = _number(f"time.output[{i}]", t, "s")
            if not start <= t <= end:
                raise ValueError(f"time.output[{i}] = {o[i]!r} s is outside the history [{start!r}, {end!r}] s")
            out.append(t)
        if any(b <= a for a, b in pairwise(out)):
            raise ValueError(f"time.output must increase, got {list(o)!r}")
        return tuple(out)

    # ---------------------------------------------------------------- derived
    @property
    def times(self) -> np.ndarray:
        return np.array([t for t, _ in self.points])

    @property
    def values(self) -> np.ndarray:
        return np.array([v for _, v in self.points])

    @property
    def end(self) -> float:
        """Last time of the history, s."""
        return float(self.points[-1][0])

    @property
    def peak(self) -> float:
        """Largest value (N or mm)."""
        return float(max(v for _, v in self.points))

    def value(self, t) -> np.ndarray:
        """The prescribed value at times ``t`` (just after a step at the first point)."""
        t = np.asarray(t, dtype=float)
        if self.points[0][0] > 0:
            return np.where(t < self.points[0][0], 0.0, np.interp(t, self.times, self.values))
        return np.interp(t, self.times, self.values)

    @property
    def jump(self) -> float:
        """The step at the first point (its value; 0 when the history starts from 0)."""
        return float(self.points[0][1])

    @property
    def kinks(self) -> np.ndarray:
        """Times where the slope changes (every point), s."""
        return self.times


__all__ = ["CONTROL_KINDS", "LoadHistory"]
