"""Checks of the plain values scenes and study files hold: numbers and lists of numbers.

Each check returns the value as floats or raises :class:`~twoscale.errors.SceneError`
whose one-line message names the field by its path (``load.total``, ``pivot[1]``) and the
bad value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from .errors import SceneError


def is_number(v: Any) -> bool:
    """True for int/float (and numpy scalars) but not bool."""
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def check_number(path: str, v: Any, *, positive: bool = False, unit: str = "") -> float:
    """Return ``float(v)`` or raise :class:`SceneError` naming ``path`` and ``v``."""
    unit_txt = f" ({unit})" if unit else ""
    if not is_number(v):
        raise SceneError(f"{path} must be a number{unit_txt}, got {v!r}")
    if not math.isfinite(v):
        raise SceneError(f"{path} must be a finite number{unit_txt}, got {v!r}")
    if positive and not v > 0:
        raise SceneError(f"{path} must be > 0{unit_txt}, got {v!r}")
    return float(v)


def check_pair(path: str, v: Any, n: int = 2, *, positive: bool = False, unit: str = "") -> tuple:
    """Return a tuple of ``n`` finite floats or raise naming ``path`` and ``v``."""
    if isinstance(v, (str, bytes)) or not isinstance(v, (Sequence, np.ndarray)) or len(v) != n:
        raise SceneError(f"{path} must be a list of {n} numbers, got {v!r}")
    return tuple(check_number(f"{path}[{i}]", x, positive=positive, unit=unit) for i, x in enumerate(v))
