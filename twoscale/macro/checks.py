"""The macro step's input checks: the tips, recesses and laws, and the control."""

from __future__ import annotations

import numpy as np

from ..control import check_control
from ..laws import AsperityLaw, LawStack


def check_scene(tips, z, laws) -> tuple[np.ndarray, np.ndarray, LawStack]:
    tips = np.asarray(tips, dtype=float)
    z = np.asarray(z, dtype=float)
    if tips.ndim != 2 or tips.shape[1] != 2 or tips.shape[0] == 0:
        raise ValueError(f"tips must have shape (N, 2) with N >= 1, got {tips.shape}")
    if z.shape != (tips.shape[0],):
        raise ValueError(f"z must have shape ({tips.shape[0]},), got {z.shape}")
    if not np.all(np.isfinite(tips)):
        raise ValueError(f"tips must be finite (mm), got {tips!r}")
    if not np.all(np.isfinite(z)):
        raise ValueError(f"z must be finite (mm), got {z!r}")
    if isinstance(laws, AsperityLaw):
        laws = [laws] * len(z)
    laws = list(laws)
    if len(laws) != len(z):
        raise ValueError(f"need one law per asperity: {len(z)} asperities, {len(laws)} laws")
    return tips, z, LawStack(laws)


def check_load(penetration, total_load, tilt, pivot, tol, max_iter) -> str:
    check_control(penetration, total_load)
    if penetration is not None and not np.isfinite(penetration):
        raise ValueError(f"penetration must be finite (mm), got {penetration!r}")
    if total_load is not None and not (np.isfinite(total_load) and total_load > 0):
        raise ValueError(f"total_load must be finite and > 0 (N), got {total_load!r}")
    if tilt and total_load is None:
        raise ValueError("tilt=True needs total_load (the joint balances a given load)")
    if len(pivot) != 2 or not np.all(np.isfinite(np.asarray(pivot, dtype=float))):
        raise ValueError(f"pivot must be two finite numbers (mm), got {pivot!r}")
    if not (np.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be > 0, got {tol!r}")
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    return "penetration" if total_load is None else ("tilt" if tilt else "load")
