"""Tips given as arrays, rows or a mapping of arrays, made into :class:`Asperity` objects.

What :func:`twoscale.solve` accepts as tips besides a scene: :func:`asperities` from
columns, :func:`as_asperities` from any accepted form; a bad value is named by its 0-based
index and the tip's number from 1. Units: mm.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .indenters import SHAPES, Asperity

if TYPE_CHECKING:
    from numpy.typing import ArrayLike


def asperities(
    x: ArrayLike, y: ArrayLike, R: ArrayLike, z: ArrayLike = 0.0, *, shape: str = "sphere"
) -> tuple[Asperity, ...]:
    """Asperities from arrays (broadcast against each other), in array order.

    Parameters
    ----------
    x, y : array_like
        Tip positions, mm.
    R : array_like
        Tip radii, mm (> 0).
    z : array_like, default 0
        Tip recesses, mm (a larger z touches later).
    shape : {"sphere", "paraboloid"} or array_like of them, default "sphere"

    Returns
    -------
    tuple of Asperity
        ``result.asperities.forces[k]`` of a solve belongs to the k-th (0-based) entry.

    Raises
    ------
    ValueError
        Arrays that do not broadcast to one dimension, or a bad value (named with its
        0-based index and the tip's number from 1, e.g. ``R[3] (tip 4) must be > 0 (mm), got -1.0``).
    """
    try:
        cols = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, z, R)), np.asarray(shape))
    except ValueError as exc:
        raise ValueError(f"x, y, R, z and shape must broadcast to one length ({exc})") from None
    if cols[0].ndim != 1 or cols[0].size == 0:
        raise ValueError(f"x, y, R, z must be 1-D with at least one tip, got shape {cols[0].shape}")
    out = []
    for k, (xk, yk, zk, rk, sk) in enumerate(zip(*cols)):
        for name, v in (("x", xk), ("y", yk), ("z", zk), ("R", rk)):
            if not math.isfinite(v):
                raise ValueError(f"{name}[{k}] (tip {k + 1}) must be a finite number (mm), got {float(v)!r}")
        if not rk > 0:
            raise ValueError(f"R[{k}] (tip {k + 1}) must be > 0 (mm), got {float(rk)!r}")
        if str(sk) not in SHAPES:
            raise ValueError(f"shape[{k}] (tip {k + 1}) must be one of {SHAPES}, got {str(sk)!r}")
        out.append(Asperity(float(xk), float(yk), float(zk), float(rk), str(sk)))
    return tuple(out)


def _tuple_of_columns(tips: Any) -> bool:
    """A tuple of 3 or 4 plain sequences of 3 or 4 items each: ``(x, y, R[, z])`` columns of
    3 or 4 tips read as rows of as many tips just as well (an outer list is rows, documented)."""
    if not isinstance(tips, tuple) or len(tips) not in (3, 4):
        return False
    items = [t for t in tips if isinstance(t, (list, tuple))]
    return len(items) == len(tips) and len({len(t) for t in items}) == 1 and len(items[0]) in (3, 4)


def as_asperities(tips: Any, *, shape: str = "sphere") -> tuple[Asperity, ...]:
    """Tips in any accepted form as a tuple of Asperity.

    ``tips`` is a sequence of :class:`Asperity`; an ``(n, 3)`` array of columns
    ``x, y, R`` or an ``(n, 4)`` array of ``x, y, R, z`` (mm; ``R`` is always the third
    column), or the same as a list of rows of numbers; or a mapping with arrays ``"x"``,
    ``"y"``, ``"R"`` and optionally ``"z"`` and ``"shape"``. ``shape`` applies to the
    array forms. A sequence of numpy arrays, or a tuple of 3 or 4 lists of 3 or 4 numbers,
    is refused: ``(x, y, R)`` columns and three rows look alike.
    """
    if isinstance(tips, Mapping):
        missing = [k for k in ("x", "y", "R") if k not in tips]
        unknown = [k for k in tips if k not in ("x", "y", "R", "z", "shape")]
        if missing or unknown:
            raise ValueError(
                f"tips as a mapping need keys x, y, R (optional z, shape); missing {missing}, unknown {unknown}"
            )
        return asperities(tips["x"], tips["y"], tips["R"], tips.get("z", 0.0), shape=tips.get("shape", shape))
    if isinstance(tips, Sequence) and any(isinstance(t, np.ndarray) for t in tips):
        # (x, y, R) columns and [row, row, row] rows look alike for 3 or 4 tips: refuse to guess
        raise ValueError(
            "tips as a sequence of numpy arrays are ambiguous (rows or columns?): give "
            "np.column_stack([x, y, R]), {'x': x, 'y': y, 'R': R} or twoscale.asperities(x, y, R, z)"
        )
    if _tuple_of_columns(tips):
        raise ValueError(
            f"tips as a tuple of {len(tips)} sequences of {len(tips[0])} numbers are ambiguous ((x, y, R) columns or "
            "rows?): give rows as a list [[x, y, R], ...], np.column_stack([x, y, R]) or twoscale.asperities(x, y, R, z)"
        )
    if isinstance(tips, np.ndarray) or (isinstance(tips, Sequence) and tips and not isinstance(tips[0], Asperity)):
        a = np.asarray(tips, dtype=float)
        if a.ndim != 2 or a.shape[1] not in (3, 4):
            hint = (
                "; a height map (rows y, columns x) is twoscale.RawMap(heights, spacing=..., units=...)"
                if a.ndim == 2 and min(a.shape) >= 3
                else ""
            )
            raise ValueError(
                f"tips as an array must have shape (n, 3) [x, y, R] or (n, 4) [x, y, R, z], got {a.shape}{hint}"
            )
        return asperities(a[:, 0], a[:, 1], a[:, 2], a[:, 3] if a.shape[1] == 4 else 0.0, shape=shape)
    if isinstance(tips, Sequence) and all(isinstance(t, Asperity) for t in tips):
        return tuple(tips)
    raise ValueError(
        f"tips must be Asperity objects, an (n, 3) or (n, 4) array, or a mapping of arrays, got {type(tips).__name__}"
    )
