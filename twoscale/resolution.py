"""The cell size a scene needs: the contacts expected before solving and the default h.

Before anything is solved, each asperity's contact is estimated from Hertz at the
approach the scene gives (or, under load control, the approach at which independent Hertz
asperities carry the load); :func:`default_h` puts :data:`CELLS_ACROSS` cells across the
smallest contact that matters, coarsened while the patches would exceed
:data:`CELL_BUDGET` cells.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Sequence

import numpy as np

from .analytic import hertz
from .errors import ResolutionWarning, SceneError, user_stacklevel
from .indenters import Asperity

if TYPE_CHECKING:
    from .scene import Scene

#: Cells across the smallest expected contact diameter chosen by :func:`default_h`.
CELLS_ACROSS = 32
#: Asperities expected to carry less than this fraction of the largest expected tip force
#: are not resolved by :func:`default_h` (their contact would force a needlessly fine
#: grid). Relative to the largest force, not the total, so the rule keeps the most loaded
#: tips whatever their number (with 200 similar tips none carries 1 % of the total).
MIN_FORCE_FRACTION = 0.01
#: Cells the patches of a default cell size may carry at most (estimated from the scene
#: before solving, :func:`patch_cells`). Where 32 cells across the smallest contact that
#: matters would carry more (light loads on many tips whose heights spread: 300 spheres at
#: 0.1 N each on 60 x 60 mm asked for h = 0.0072 mm and 8 M cells), the default h is
#: coarsened until the patches fit: the two-level iteration carries about 1 M cells in
#: 15 s on one core, so the default solve stays well within a minute, and the smallest
#: contact that matters keeps fewer cells (a :class:`~twoscale.api.ResolutionWarning` below 4).
CELL_BUDGET = 1_500_000


def _hertz_level(scene: Scene) -> float:
    """Rigid approach d (mm) at which independent Hertz asperities (no interaction)
    carry the scene's total load: the root of ``sum_k P_H(R_k, d - z_k) = W``.

    A pure function of the frozen scene's material, tips and load, asked for by the cell
    size, the memory estimate, the resolution check and the nominal area of one solve:
    solved once per scene object and kept with it, as a cached property would be."""
    level = scene.__dict__.get("_hertz_level")
    if level is None:
        level = _solve_hertz_level(scene)
        scene.__dict__["_hertz_level"] = level  # not a field: equality, hash and repr ignore it
    return level


def _solve_hertz_level(scene: Scene) -> float:
    """:func:`_hertz_level` solved (Brent's method on the load's excess)."""
    from scipy.optimize import brentq

    E_star = scene.material.E_star
    R = np.array([a.R for a in scene.asperities])
    z = np.array([a.z for a in scene.asperities])
    W = scene.total_load
    assert W is not None  # every caller passes a scene under load control

    def excess(d: float) -> float:
        return float(np.sum(hertz.load(R, d - z, E_star))) - W

    lo = float(z.min())
    # the lowest asperity alone, with the smallest radius, carries W at this level
    hi = lo + float(hertz.penetration(R.min(), W, E_star)) * (1 + 1e-9) + 1e-300
    try:
        return brentq(excess, lo, hi, xtol=1e-14 * max(1.0, abs(hi)), rtol=1e-12)
    except (RuntimeError, ValueError):  # no finite level: a modulus or load outside floating point
        raise SceneError(
            f"load.total = {W!r} N cannot be carried at any finite approach on material.E = "
            f"{scene.material.E!r} MPa (the Hertz level does not converge): check the units"
        ) from None


def expected_approaches(scene: Scene) -> np.ndarray:
    """Estimated local approach of each asperity, mm, shape (N,): ``max(d - z_k, 0)``
    with d the given penetration or, under load control, the level at which
    independent Hertz asperities carry the load (tilt and interaction ignored;
    interaction only lowers the approach, so these are upper estimates)."""
    d = scene.penetration if scene.penetration is not None else _hertz_level(scene)
    z = np.array([a.z for a in scene.asperities])
    return np.maximum(d - z, 0.0)


def expected_contact_radii(scene: Scene) -> np.ndarray:
    """Contact radius of each asperity alone at its expected approach, mm: Hertz
    ``sqrt(R delta)`` for paraboloids, the exact-sphere (Segedin) radius for spheres."""
    return _contact_radii(scene.asperities, expected_approaches(scene))


def expected_contacts(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Hertz force (N) and contact radius (mm) of each asperity alone at its expected
    approach (:func:`expected_approaches`, estimated once)."""
    delta = expected_approaches(scene)
    R = np.array([a.R for a in scene.asperities], dtype=float)
    return hertz.load(R, delta, scene.material.E_star), _contact_radii(scene.asperities, delta)


def _contact_radii(asperities: Sequence[Asperity], delta: np.ndarray) -> np.ndarray:
    R = np.array([a.R for a in asperities], dtype=float)
    sphere = np.array([a.shape == "sphere" for a in asperities], dtype=bool)
    return np.where(sphere, hertz.sphere_contact_radius(R, delta), hertz.contact_radius(R, delta))


def default_h(
    scene: Scene,
    *,
    cells_across: int = CELLS_ACROSS,
    min_force_fraction: float = MIN_FORCE_FRACTION,
    cell_budget: float | None = CELL_BUDGET,
) -> float:
    """Cell size (mm) chosen from the scene.

    Rule: estimate each asperity's approach (:func:`expected_approaches`) and its
    contact radius alone (:func:`expected_contact_radii`); among the asperities whose
    Hertz force at that approach is at least ``min_force_fraction`` of the largest such
    force, take the smallest contact diameter 2a and divide it by ``cells_across``;
    round down to two significant digits: that estimated contact gets 32-35 cells
    across. The approach estimate ignores interaction, which lowers it, so the real
    contact is smaller (24-32 cells on the examples; fewer where tips crowd). The
    threshold is relative to the largest tip force, not to the total load, so it works for
    any number of asperities (a force ratio of 1 % is an approach ratio of about 5 % and a
    contact radius ratio of about 20 %). Where the patches would then carry more than
    ``cell_budget`` cells, h is coarsened until they fit (:data:`CELL_BUDGET`).

    Parameters
    ----------
    scene : Scene
    cells_across : int, default 32
        Cells across the smallest resolved contact diameter.
    min_force_fraction : float, default 0.01
        Asperities expected to carry less than this fraction of the largest expected
        tip force are not used to choose h (they still get cells; only coarser).
    cell_budget : float or None, default CELL_BUDGET
        Largest number of cells the patches may carry (:func:`patch_cells`); where the
        rule's h would carry more, h is coarsened (rounded up to two digits) until they
        fit. None: no budget.

    Returns
    -------
    float
        h, mm (> 0).

    Raises
    ------
    SceneError
        When no asperity is expected to carry load (nothing to size the cells on).
    """
    if scene.h is not None:
        return scene.h
    force, radius = expected_contacts(scene)
    keep = (force > 0) & (force >= min_force_fraction * force.max())
    if not np.any(keep):
        raise SceneError(
            f"grid.h: no asperity is expected to carry load (largest Hertz estimate "
            f"{force.max()!r} N), so no default cell size can be chosen; give [grid] h"
        )
    diameter = 2.0 * radius[keep].min()
    if not (math.isfinite(diameter) and diameter > 0):
        raise SceneError(
            f"grid.h: the smallest expected contact diameter is {diameter!r} mm, so no "
            f"default cell size can be chosen; give [grid] h"
        )
    h = _round_down(diameter / cells_across, digits=2)
    cells = patch_cells(radius, h)
    if cell_budget is None or cells <= cell_budget:
        return h
    while cells > cell_budget:  # cells fall about as 1 / h^2
        h *= max(1.02, 0.99 * math.sqrt(cells / cell_budget))
        cells = patch_cells(radius, h)
    return round_up(h, digits=2)


#: Patch half-width over the contact radius (the two-scale solver's default ``margin``).
PATCH_MARGIN = 1.3


def patch_cells(radii: np.ndarray, h: float, *, margin: float = PATCH_MARGIN) -> float:
    """Cells the patches of contacts of radii ``radii`` (mm; 0: no contact) carry at cell
    size ``h``: squares of half-width ``margin a + 2 h`` (an upper estimate: interaction
    only shrinks contacts)."""
    a = np.asarray(radii, dtype=float)
    a = a[a > 0]
    return float(np.sum((np.floor(2.0 * (margin * a + 2.0 * h) / h) + 1.0) ** 2))


def round_up(x: float, *, digits: int) -> float:
    """``x`` rounded up to ``digits`` significant digits."""
    e = math.floor(math.log10(x)) - (digits - 1)
    return float(f"{math.ceil(x / 10.0**e * (1 - 1e-12)) * 10.0**e:.{digits + 1}g}")


def _round_down(x: float, *, digits: int) -> float:
    """``x`` rounded down to ``digits`` significant digits (so a readable h never
    gives fewer cells than asked)."""
    e = math.floor(math.log10(x)) - (digits - 1)
    scale = 10.0**e
    q = math.floor(x / scale * (1 + 1e-12))
    return float(f"{q * scale:.{digits}g}") if q > 0 else x


# ---------------------------------------------------------------- solving


#: Fewest cells across an expected contact before a :class:`ResolutionWarning` (about 10 %
#: on a Hertz force at 4 cells across, 1-2 % at 8).
MIN_CELLS_ACROSS = 4


def check_resolution(
    scene: Scene,
    h: float,
    *,
    forces: np.ndarray | None = None,
    radii: np.ndarray | None = None,
    context: str = "",
    advice: str | None = None,
) -> None:
    """Refuse a cell size coarser than every expected contact, and warn when a contact
    that matters (expected force >= 1 % of the largest) gets fewer than
    :data:`MIN_CELLS_ACROSS` cells across; both name the default rule's ``h``.
    ``forces``, ``radii``: :func:`~twoscale.scene.expected_contacts`, when already known.
    ``context`` (e.g. "at the glassy modulus, "): only warn, the message starting with it;
    ``advice``: the cell size to suggest in place of the default rule's."""
    import warnings

    force, a = expected_contacts(scene) if forces is None or radii is None else (forces, radii)
    if not np.any(force > 0):
        return
    across = 2.0 * a / h
    if across.max() < 1.0:
        rule = advice or f"the default rule gives {default_h(dataclasses.replace(scene, h=None)):g} mm"
        message = (
            f"{context}cell size h = {h:g} mm is coarser than every expected contact (the largest "
            f"about {2 * a.max():.2g} mm across): use a smaller h ({rule})"
        )
        if not context:
            raise SceneError(message)
        warnings.warn(ResolutionWarning(message), stacklevel=user_stacklevel())
        return
    matters = force >= MIN_FORCE_FRACTION * force.max()
    k = int(np.argmin(np.where(matters, across, np.inf)))
    if across[k] < MIN_CELLS_ACROSS:
        warnings.warn(
            ResolutionWarning(
                f"{context}cell size h = {h:g} mm gives asperity {k + 1}'s expected contact (about {2 * a[k]:.2g} "
                f"mm across) only {across[k]:.1f} cells across: its force may be off by 10 % or more "
                f"({advice or _default_rule_text(scene)})"
            ),
            stacklevel=user_stacklevel(),
        )


def _default_rule_text(scene: Scene) -> str:
    """What the default rule gives for ``scene``, and whether the cell budget coarsened it."""
    free = dataclasses.replace(scene, h=None)
    h, rule = default_h(free), default_h(free, cell_budget=None)
    if h == rule:
        return f"the default rule gives h = {h:g} mm"
    return (
        f"the default h = {h:g} mm is the rule's {rule:g} mm coarsened to keep the patches within "
        f"{CELL_BUDGET / 1e6:g} M cells; give h = {rule:g} mm to resolve every contact that matters"
    )
