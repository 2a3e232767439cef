"""The ``[rolling]`` table of a scene: where the road starts and ends, the step, the speed,
and the body's face (a slick tyre's cylinder, a footprint window).

A road point at x (its own frame: the map centred on the scene's origin, or the tips'
coordinates) appears at body x + shift; the shifts run from ``start`` to ``end`` by
``step`` (mm) and the time of a position is ``(shift - start) / speed``. Units: mm, km/h, s.

Every bad value raises :class:`~twoscale.errors.SceneError` naming the field
(``rolling.step``) and the value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ..errors import SceneError

#: Keys of the ``[rolling]`` table.
ROLLING_KEYS = ("start", "end", "step", "speed", "tyre_radius", "tyre_shape", "footprint")
#: Shapes of a tyre's face: the parabola ``x^2 / (2 R)`` (Hertz's) or the exact circle.
TYRE_SHAPES = ("parabola", "circle")
#: Positions a run may have at most (a 1 m section at 0.01 mm steps).
MAX_POSITIONS = 100_000
#: km/h in mm/s.
KMH = 1e6 / 3600.0


def _number(key: str, v: Any, *, positive: bool = False, unit: str = "mm") -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v):
        raise SceneError(f"rolling.{key} must be a finite number ({unit}), got {v!r}")
    if positive and not v > 0:
        raise SceneError(f"rolling.{key} must be > 0 ({unit}), got {v!r}")
    return float(v)


@dataclass(frozen=True)
class RollingSpec:
    """A rolling run: positions, speed and the body's face.

    Parameters
    ----------
    start, end : float
        Shift of the road along +x relative to the body at the first and last position, mm
        (``end >= start``).
    step : float
        Distance between positions, mm (> 0). The last position is the last
        ``start + k step`` not beyond ``end``.
    speed : float
        Rolling speed, km/h (> 0): the time of a position is its distance from ``start``
        over the speed.
    tyre_radius : float, optional
        Radius of a slick tyre whose face is a cylinder about the y axis, mm: the face
        rises by ``x^2 / (2 R)`` (``tyre_shape = "parabola"``) or ``R - sqrt(R^2 - x^2)``
        (``"circle"``) at body x, added to the gap. None: a flat face.
    tyre_shape : {"parabola", "circle"}, default "parabola"
    footprint : (float, float), optional
        Length (along x) and width (along y) of the body's face window centred on the
        origin, mm: the road outside it never touches. Required for a flat face on the
        half-space; a tyre without it is as wide as the strip; a finite block's face is
        its top face unless given.
    """

    start: float
    end: float
    step: float
    speed: float
    tyre_radius: float | None = None
    tyre_shape: str = "parabola"
    footprint: tuple | None = None

    def __post_init__(self) -> None:
        for key in ("start", "end"):
            object.__setattr__(self, key, _number(key, getattr(self, key)))
        object.__setattr__(self, "step", _number("step", self.step, positive=True))
        object.__setattr__(self, "speed", _number("speed", self.speed, positive=True, unit="km/h"))
        if self.end < self.start:
            raise SceneError(f"rolling.end must not be before rolling.start = {self.start!r} mm, got {self.end!r}")
        if self.tyre_radius is not None:
            object.__setattr__(self, "tyre_radius", _number("tyre_radius", self.tyre_radius, positive=True))
        if self.tyre_shape not in TYRE_SHAPES:
            raise SceneError(f"rolling.tyre_shape must be one of {', '.join(TYRE_SHAPES)}, got {self.tyre_shape!r}")
        if self.footprint is not None:
            fp = self.footprint
            if isinstance(fp, (str, bytes)) or not hasattr(fp, "__len__") or len(fp) != 2:
                raise SceneError(f"rolling.footprint must be [length, width] (mm), got {fp!r}")
            object.__setattr__(
                self, "footprint", tuple(_number(f"footprint[{i}]", v, positive=True) for i, v in enumerate(fp))
            )
        n = self.count
        if n > MAX_POSITIONS:
            raise SceneError(
                f"rolling.step = {self.step!r} mm gives {n} positions from {self.start!r} to "
                f"{self.end!r} mm, more than {MAX_POSITIONS}: use a larger step"
            )

    @property
    def count(self) -> int:
        """Number of positions."""
        return int(math.floor((self.end - self.start) / self.step * (1 + 1e-12) + 1e-9)) + 1

    @property
    def speed_mm_s(self) -> float:
        """The speed in mm/s."""
        return self.speed * KMH

    def shifts(self) -> np.ndarray:
        """The shift of every position, mm."""
        return self.start + self.step * np.arange(self.count)

    def times(self) -> np.ndarray:
        """The time of every position, s (0 at the first)."""
        return (self.shifts() - self.start) / self.speed_mm_s

    def face(self, x: np.ndarray) -> np.ndarray:
        """Height of the body's face above its lowest point at body x, mm (0 for a flat
        face; ``inf`` beyond the circle)."""
        x = np.asarray(x, dtype=float)
        R = self.tyre_radius
        if R is None:
            return np.zeros_like(x)
        if self.tyre_shape == "parabola":
            return x * x / (2.0 * R)
        inside = np.abs(x) < R
        with np.errstate(invalid="ignore"):
            return np.where(inside, x * x / (R + np.sqrt(np.where(inside, R * R - x * x, 0.0))), np.inf)

    def to_table(self) -> dict:
        """The ``[rolling]`` table (TOML/JSON-ready)."""
        out: dict[str, Any] = {"start": self.start, "end": self.end, "step": self.step, "speed": self.speed}
        if self.tyre_radius is not None:
            out["tyre_radius"] = self.tyre_radius
            out["tyre_shape"] = self.tyre_shape
        if self.footprint is not None:
            out["footprint"] = list(self.footprint)
        return out


def rolling_from_table(table: Mapping[str, Any]) -> RollingSpec:
    """The :class:`RollingSpec` of a ``[rolling]`` table (unknown keys refused)."""
    from ..io.table_checks import check_keys

    check_keys("rolling", table, ROLLING_KEYS, required=("start", "end", "step", "speed"))
    try:
        return RollingSpec(**dict(table))
    except TypeError as exc:  # pragma: no cover - check_keys names every key first
        raise SceneError(f"rolling: {exc}") from None


__all__ = ["RollingSpec", "rolling_from_table", "ROLLING_KEYS", "TYRE_SHAPES", "MAX_POSITIONS"]
