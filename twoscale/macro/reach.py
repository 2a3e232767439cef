"""The tips that can touch: under penetration control the macro step solves among them.

The offset of tip ``k`` is ``o_k = d - z_k`` and its local penetration
``delta_k = o_k - sum_l T_kl P_l`` (paper eq. 4). On a body whose surface only sinks under
a pressure nowhere negative (``surface_rises`` False: the half-space) every ``T_kl >= 0``,
so ``delta_k <= o_k``: a tip with ``o_k <= 0`` carries no force at any solution. Its row of
the macro equations is ``P_k = 0`` and its column adds nothing to the others' rows, so the
equations among the reaching tips are the whole problem; the others get no force and their
local penetrations from the loaded tips' forces (:func:`widened`). Seed 7's #3: 1,215 of
1,652 paraboloids reach, the interaction matrix holds 0.54 of the entries.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..control import Loading
from ..laws import AsperityLaw
from .result import MacroResult

#: Interaction entries made at a time for the local penetrations of the tips left out.
WIDEN_ENTRIES = 1 << 20


def reaching(provider, tips, z, laws, loading: Loading) -> np.ndarray | None:
    """Indices of the tips with ``d - z_k > 0``, or None where the macro step keeps every
    tip: load control (the approach is unknown), a body whose surface can rise, every tip
    or none reaching, or inputs the macro step's checks refuse (it then says why)."""
    if loading.total_load is not None or loading.penetration is None or getattr(provider, "surface_rises", True):
        return None
    tips, z = np.asarray(tips, dtype=float), np.asarray(z, dtype=float)
    shaped = tips.ndim == 2 and tips.shape[1] == 2 and z.shape == (tips.shape[0],)
    if not (shaped and np.all(np.isfinite(tips)) and np.all(np.isfinite(z)) and np.isfinite(loading.penetration)):
        return None
    if not isinstance(laws, AsperityLaw) and len(laws) != len(z):
        return None
    keep = np.flatnonzero(float(loading.penetration) - z > 0.0)
    return keep if 0 < keep.size < z.size else None


def among(laws, keep: np.ndarray):
    """The laws of the tips ``keep`` (one law for all stays one law)."""
    return laws if isinstance(laws, AsperityLaw) else [laws[k] for k in keep]


def widened(result: MacroResult, keep: np.ndarray, provider, tips, z, penetration: float) -> MacroResult:
    """The macro step among the tips ``keep`` as one over every tip: no force elsewhere, and
    there the local penetration ``d - z_k - sum_l T_kl P_l`` over the loaded tips ``l``."""
    tips, z = np.asarray(tips, dtype=float), np.asarray(z, dtype=float)
    forces = np.zeros(z.size)
    forces[keep] = result.forces
    local = float(penetration) - z
    local[keep] = result.local_penetrations
    out = np.setdiff1d(np.arange(z.size), keep, assume_unique=True)
    loaded = keep[np.asarray(result.forces) > 0.0]
    rows = max(1, WIDEN_ENTRIES // max(loaded.size, 1))
    for a in range(0, out.size if loaded.size else 0, rows):
        part = out[a : a + rows]
        G = np.asarray(provider.point_compliance(tips[part], tips[loaded]), dtype=float)
        if not np.all(np.isfinite(G)):
            raise ValueError("a tip left out coincides with a loaded tip or the compliance is not finite")
        local[part] -= G @ forces[loaded]
    return replace(result, forces=forces, local_penetrations=local, in_contact=local > 0.0)
