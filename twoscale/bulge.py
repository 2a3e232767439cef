"""Tips a finite body's rising surface touches although the solve never reached them.

Both solvers take a tip into the solve only where its apex lies below the approach bound
(its reach ``Asperity.reach(d - z)`` is positive): under a pressure that is nowhere
negative the half-space's surface only sinks, so a tip above the approach never touches.
A bonded, nearly incompressible block breaks that rule: its surface rises beside a
contact (about 20 um, 6 mm from a sphere pressed 0.5 mm into a 5 mm layer), and a tip whose
apex lies a little above the approach can touch there. :func:`lifted_tips` checks each
unreached tip's apex against the solved pressure's displacement. Both solvers then take
such tips in: the full-grid reference is solved again on a grid that covers them
(:func:`twoscale.reference.on_scene.solve_reference_scene`), the two-scale solve's micro
step again with patches for them (:mod:`twoscale.bulge_rounds`); a contact still left out
after their rounds is named (:func:`warn_lifted_tips`) instead of answered without.

Only bodies whose surface may rise (``InfluenceProvider.surface_rises``) are checked, and
only without a free tilt (the tilt moves every apex's approach). The displacement at the
apexes is the solved pressure's: the loaded cells of the tips near an apex act as uniform
squares (``InfluenceProvider.cell_block``), the others by their resultants; a body's smooth
low-rank part (the block's correction, ``InfluenceProvider.split``) is summed from every
loaded cell at once (one evaluation at all the apexes, not one an apex).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .influence.base import InfluenceProvider
    from .results import ContactResult

from .errors import BulgeWarning, user_stacklevel

#: Contact radii (the largest tip's) within which a tip's pressure acts cell by cell on an
#: apex; beyond, as its resultant at its centre.
NEAR = 6.0


@dataclass(frozen=True)
class LiftedTips:
    """Unreached tips whose apex the solved surface reaches: ``tips`` (0-based scene
    indices), ``gaps`` (mm, ``z + u - d`` at each apex, negative), deepest first, and
    ``rise`` (mm): the most the surface rises (``-u``) at their apexes."""

    tips: np.ndarray
    gaps: np.ndarray
    rise: float


def _loads(result: ContactResult):
    """The loaded cells of every field, sorted by owning tip: centres (n, 2), pressure,
    owner, and the cell size (one per solve)."""
    parts = []
    for f in result.fields:
        on = f.pressure > 0
        X, Y = f.grid.centres()
        parts.append((np.column_stack([X[on], Y[on]]), f.pressure[on], f.owner[on]))
    cells, p, own = (np.concatenate([q[i] for q in parts]) for i in range(3))
    order = np.argsort(own, kind="stable")
    return cells[order], p[order], own[order], float(result.fields[0].grid.h)


def _apex_displacement(provider: InfluenceProvider, result: ContactResult, apexes: np.ndarray) -> np.ndarray:
    """Displacement (mm) at ``apexes`` (M, 2) of the result's pressure: a tip's loaded cells
    as uniform squares within :data:`NEAR` contact radii (plus two cells) of an apex, its
    resultant at its pressure's centre beyond (a point force: relative error about
    ``(a / r)^2 / 8``, under 1 % there). A body with a smooth low-rank part
    (:meth:`~twoscale.influence.base.InfluenceProvider.split`) has that part summed from
    every loaded cell at once, and only its base kernel taken near and far as above."""
    from scipy.spatial import cKDTree

    cells, p, own, h = _loads(result)
    if p.size == 0:
        return np.zeros(len(apexes))
    base, smooth = _smooth_part(provider, result, apexes)
    _, first = np.unique(own, return_index=True)
    bounds = np.append(first, own.size)
    w = p * h * h
    force = np.add.reduceat(w, first)
    centres = np.column_stack([np.add.reduceat(w * cells[:, i], first) for i in (0, 1)]) / force[:, None]
    reach = NEAR * float(np.sqrt(np.max(result.asperities.contact_areas) / np.pi)) + 2.0 * h
    close = cKDTree(centres).query_ball_point(apexes, reach)
    near = _near_sums(base, apexes, close, bounds, cells, p, h)
    return smooth + near + _far_sums(base, apexes, close, centres, force)


def _smooth_part(provider: InfluenceProvider, result: ContactResult, apexes: np.ndarray):
    """``(base, u)``: the body's base kernel and its low-rank part's displacement (mm) at
    ``apexes`` from every field's pressure; ``(provider, 0)`` for a body without one, or
    whose part has no value at points (``LowRankCorrection.at_points``)."""
    base, correction = provider.split()
    if correction is None:
        return provider, 0.0
    parts = [correction.coefficients(f.grid, f.pressure) for f in result.fields]
    c = np.zeros(max(len(q) for q in parts))
    for q in parts:  # a later field's vector may be longer (the node space grew)
        c[: len(q)] += q
    u = correction.at_points(apexes, c)
    return (provider, 0.0) if u is None else (base, u)


def _near_sums(base, apexes: np.ndarray, close: list, bounds: np.ndarray, cells, p, h: float) -> np.ndarray:
    """Each apex's displacement from the loaded cells of the tips ``close`` to it, as uniform
    squares (``base.cell_block``): on a body whose kernel depends on offsets only, one call
    for every (apex, cell) pair (from the origin to ``cell - apex``), else one an apex."""
    rows = [np.concatenate([np.arange(bounds[j], bounds[j + 1]) for j in near]) if near else [] for near in close]
    u = np.zeros(len(apexes))
    if not getattr(base, "translation_invariant", False):
        for k, r in enumerate(rows):
            if len(r):
                u[k] = base.cell_block(apexes[k : k + 1], cells[r], h)[0] @ p[r]
        return u
    ends = np.cumsum([len(r) for r in rows])
    lo = 0
    while lo < len(apexes):  # blocks of apexes with at most NEAR_PAIRS pairs (or one apex)
        start = int(ends[lo - 1]) if lo else 0
        hi = max(lo + 1, int(np.searchsorted(ends, start + NEAR_PAIRS, side="right")))
        if ends[hi - 1] > start:
            r = np.concatenate([np.asarray(q, dtype=np.intp) for q in rows[lo:hi]])
            apex = np.repeat(np.arange(lo, hi), np.diff(ends[lo:hi], prepend=start))
            kernel = base.cell_block(np.zeros((1, 2)), cells[r] - apexes[apex], h)[0]
            u += np.bincount(apex, weights=kernel * p[r], minlength=len(apexes))
        lo = hi
    return u


#: Largest number of (apex, cell) pairs whose cell blocks are made at once.
NEAR_PAIRS = 2_000_000
#: Largest apexes x tips block of point compliances made at once (8 bytes each).
FAR_BLOCK = 4_000_000


def _far_sums(base, apexes: np.ndarray, close: list, centres: np.ndarray, force: np.ndarray) -> np.ndarray:
    """Each apex's displacement from the resultants of the tips not ``close`` to it (point
    forces at their centres), in blocks of at most :data:`FAR_BLOCK` pairs."""
    u = np.zeros(len(apexes))
    step = max(1, FAR_BLOCK // max(1, len(centres)))
    for lo in range(0, len(apexes), step):
        far = base.point_compliance(apexes[lo : lo + step], centres) * force
        for k, near in enumerate(close[lo : lo + step]):
            far[k, near] = 0.0
        u[lo : lo + step] = far.sum(axis=1)
    return u


def lifted_tips(scene, provider: InfluenceProvider, result: ContactResult) -> LiftedTips | None:
    """The tips ``result`` left out whose apex its surface reaches, or None (none, a body
    whose surface only sinks, a free tilt, or a result without fields)."""
    if scene.tilt:
        return None
    return lifted_among(scene.asperities, provider, result)


def lifted_among(asperities, provider: InfluenceProvider, result: ContactResult) -> LiftedTips | None:
    """:func:`lifted_tips` of the tips ``asperities`` solved without a free tilt."""
    if not getattr(provider, "surface_rises", False) or not result.fields:
        return None
    z = np.array([a.z for a in asperities], dtype=float)
    out = np.flatnonzero((z > result.penetration) & (result.forces == 0.0))
    if out.size == 0:
        return None
    apexes = np.array([[asperities[k].x, asperities[k].y] for k in out], dtype=float)
    u = _apex_displacement(provider, result, apexes)
    gap = z[out] + u - result.penetration
    tol = 1e-6 * max(abs(result.penetration), float(result.fields[0].grid.h))
    hit = gap < -tol
    if not np.any(hit):
        return None
    order = np.argsort(gap[hit])
    return LiftedTips(out[hit][order], gap[hit][order], float(np.max(-u[hit])))


#: Solves again before the lifted tips are left to the warning: the reference's on a grid
#: grown by the surface's rise (:func:`twoscale.reference.on_scene.solve_reference_scene`),
#: the two-scale micro step's with patches for them (:func:`twoscale.bulge_rounds.settle`).
SETTLE_ROUNDS = 3


def warn_lifted_tips(scene, provider: InfluenceProvider, result: ContactResult) -> LiftedTips | None:
    """:func:`lifted_tips`, and a :class:`~twoscale.errors.BulgeWarning` naming them. A
    result that checked itself is not checked again: a two-scale result's ``details.bulge``
    (:func:`twoscale.bulge_rounds.settle`) names the tips it left; the reference's scene
    solve warns of its own (:func:`twoscale.reference.on_scene.solve_reference_scene`)."""
    if result.method == "reference":
        return None
    checked = getattr(result.details, "bulge", None)
    if checked is not None:
        lifted = (
            LiftedTips(np.array(checked.left, dtype=int), np.array(checked.left_gaps), 0.0) if checked.left else None
        )
    else:
        lifted = lifted_tips(scene, provider, result)
    if lifted is not None:
        warn_of(scene.asperities, lifted)
    return lifted


def warn_of(asperities, lifted: LiftedTips) -> None:
    """A :class:`~twoscale.errors.BulgeWarning` naming the ``lifted`` tips of ``asperities``."""
    k, g = int(lifted.tips[0]), float(lifted.gaps[0])
    a = asperities[k]
    warnings.warn(
        f"{lifted.tips.size} tip(s) above the approach touch the body's rising surface but were "
        f"left out of the solve (the deepest: tip {k + 1} at ({a.x:.4g}, {a.y:.4g}) mm, its apex "
        f"{-g * 1e3:.3g} um into the solved surface): the answer lacks their contact; a finite "
        "block bulges beside its contacts",
        BulgeWarning,
        stacklevel=user_stacklevel(),
    )


__all__ = ["LiftedTips", "NEAR", "SETTLE_ROUNDS", "lifted_among", "lifted_tips", "warn_lifted_tips", "warn_of"]
