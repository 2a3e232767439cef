"""The reference solver on a scene: one grid covering every place contact can reach.

:func:`reference_grid` sizes the grid from an upper bound on the approach
(:func:`approach_bound`) and each tip's reach, sampled by the union box's sampler
(:func:`twoscale.micro.sampling.box_surface`: by tiles or windows where every indenter on
every cell would cost more; the same heights and owners to the bit; 4,722 spheres on 2.7 M
cells 35 s of CPU every tip on every cell, 1.1 s so); :func:`solve_reference_scene` solves on it
(:func:`twoscale.reference.solve_reference`, dense or CG) and enlarges the grid while
pressure reaches its edge. ``twoscale.solve(scene, method="reference")`` calls it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..analytic import hertz
from ..grid import Grid
from ..indenters import surface_on
from ..micro.sampling import box_surface
from ..results import ContactResult
from ..scene import Scene


def approach_bound(scene: Scene) -> float:
    """Upper bound on the rigid approach d, mm.

    Penetration control: d itself. Load control: ``z_min + delta_H(W) + W / (pi E* r_min)``,
    where delta_H(W) is the Hertz penetration of the whole load on the lowest asperity
    (on the smallest radius among the lowest tips) and the last term bounds the
    displacement the other asperities add at its tip (r_min = smallest tip distance;
    Boussinesq). On the half-space without tilt, no contact extends beyond
    ``Asperity.reach(bound - z_k)``; otherwise the reference solve checks its edges.
    """
    if scene.penetration is not None:
        return scene.penetration
    W, E_star = scene.total_load, scene.material.E_star
    z = np.array([a.z for a in scene.asperities])
    lowest = [a for a in scene.asperities if a.z <= z.min()]
    r_low = min(a.R for a in lowest)
    bound = z.min() + float(hertz.penetration(r_low, W, E_star))
    if len(scene.asperities) > 1:
        tips = scene.tips
        from scipy.spatial import cKDTree

        r_min = float(cKDTree(tips).query(tips, k=2)[0][:, 1].min())  # nearest other tip
        bound += W / (math.pi * E_star * r_min)
    return float(bound)


def reference_grid(scene: Scene, h: float, *, grow: float = 1.0, rise: float = 0.0) -> Grid:
    """Grid of cell size ``h`` covering every place contact can reach, plus a margin
    of ``3 h + 5 %`` of each reach; ``grow`` scales the reach and margin (used when a
    solve finds pressure on the grid edge). Cell centres lie on the lattice h Z^2
    (a tip at the origin sits on a cell centre). ``rise`` (mm) raises the approach bound
    by how far the body's surface may rise beside its contacts (a bonded block's bulge,
    :mod:`twoscale.bulge`), so that the tips it lifts are covered."""
    bound = approach_bound(scene) + rise
    # a free tilt can bring any tip down to the lowest one's level: every tip is reached
    lowest = min(a.z for a in scene.asperities) if scene.tilt else None
    boxes = []
    for a in scene.asperities:
        reach = a.reach(bound - (a.z if lowest is None else lowest))
        if reach <= 0:
            continue
        r = grow * (1.05 * reach + 3.0 * h)
        boxes.append((a.x - r, a.x + r, a.y - r, a.y + r))
    b = np.array(boxes)
    return Grid.covering(b[:, 0].min(), b[:, 1].max(), b[:, 2].min(), b[:, 3].max(), h)


def pressure_on_edge(result: ContactResult) -> bool:
    """True if any field of ``result`` has positive pressure on its outermost cells."""
    for f in result.fields:
        p = f.pressure
        if np.any(p[0, :] > 0) or np.any(p[-1, :] > 0) or np.any(p[:, 0] > 0) or np.any(p[:, -1] > 0):
            return True
    return False


def solve_reference_scene(
    scene: Scene, provider, h: float, *, solver: str = "auto", max_enlargements: int = 3, rise: float = 0.0, **options
) -> ContactResult:
    """The full-grid reference solver on ``scene``: one grid of cell ``h`` (mm) covering every
    place contact can reach (:func:`reference_grid`), enlarged by half while
    pressure reaches its edge.

    Parameters
    ----------
    solver : {"auto", "dense", "cg"}, default "auto"
        :func:`twoscale.reference.solve_reference`'s choice.
    max_enlargements : int, default 3
        After that many, the result is returned with ``converged=False`` and a message
        saying the answer may be clipped.
    rise : float, default 0
        How far (mm) the body's surface may rise beside its contacts: the grid covers the
        tips it lifts (:func:`reference_grid`). On a body whose surface rises, tips the
        solved surface reaches beyond the grid (:func:`twoscale.bulge.lifted_tips`) are
        covered by solving again with twice their rise, up to ``SETTLE_ROUNDS`` times.

    Returns
    -------
    ContactResult
        ``method="reference"``; ``details.grid_enlargements`` says how often the grid grew.
    """
    from . import solve_reference

    if scene.surface is not None:  # a height map: the full grid is the whole map (beyond it, no surface)
        return solve_reference(
            provider,
            surface_on(scene.surface.hmap.grid, scene.asperities),
            method=solver,
            penetration=scene.penetration,
            total_load=scene.total_load,
            tilt=scene.tilt,
            pivot=scene.pivot,
            **options,
        )
    result = _on_growing_grid(scene, provider, h, solver, max_enlargements, rise, options)
    if not getattr(provider, "surface_rises", False):
        return result
    from ..bulge import SETTLE_ROUNDS, lifted_tips, warn_of

    for _ in range(SETTLE_ROUNDS):  # a block's bulge may lift tips beyond the grid: cover them
        lifted = lifted_tips(scene, provider, result)
        if lifted is None:
            return result
        rise = max(2.0 * rise, 2.0 * lifted.rise)
        result = _on_growing_grid(scene, provider, h, solver, max_enlargements, rise, options)
    if (lifted := lifted_tips(scene, provider, result)) is not None:  # still lifted after the rounds
        warn_of(scene.asperities, lifted)
    return result


def _on_growing_grid(scene: Scene, provider, h: float, solver: str, max_enlargements: int, rise: float, options: dict):
    """The tips' reference solve on :func:`reference_grid`, enlarged by half while pressure
    reaches its edge (at most ``max_enlargements`` times)."""
    from . import solve_reference

    grow = 1.0
    for attempt in range(max_enlargements + 1):
        grid = reference_grid(scene, h, grow=grow, rise=rise)
        result = solve_reference(
            provider,
            box_surface(grid, scene.asperities),
            method=solver,
            penetration=scene.penetration,
            total_load=scene.total_load,
            tilt=scene.tilt,
            pivot=scene.pivot,
            **options,
        )
        if not pressure_on_edge(result):
            return dataclasses.replace(result, details=dataclasses.replace(result.details, grid_enlargements=attempt))
        grow *= 1.5
    msg = (
        f"pressure still reaches the edge of the reference grid after {max_enlargements} "
        f"enlargements (grid {grid.nx} x {grid.ny} cells); the answer may be clipped"
    )
    return dataclasses.replace(
        result,
        converged=False,
        message=f"{result.message}; {msg}" if result.message else msg,
        details=dataclasses.replace(result.details, grid_enlargements=max_enlargements),
    )


__all__ = ["approach_bound", "reference_grid", "pressure_on_edge", "solve_reference_scene"]
