"""Where a ball-and-socket pivot can balance the moments of the contact pressure.

Under a free tilt the body turns about the pivot until both moments vanish: the centre of
the contact pressure must lie on the pivot, so the pivot must lie in the convex hull of the
cells where the indenters have material (a positive pressure's centre lies inside its
support). The tilt moves each tip's contact along its flank, by about ``R`` times the
angle, so a pivot somewhat outside the tips' own hull still has an answer: the contact sits
off the apexes. Two consequences, both decided before any solve:

* :func:`check_pivot_reach` refuses a pivot outside the material of the grid the full-grid
  reference would use (no solver can answer it);
* :func:`pivot_route` sends a pivot farther outside the tips' hull than a contact radius to
  the full grid: the two-scale patches are centred on the apexes, where that contact is not.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from .errors import SceneError, TiltWarning, user_stacklevel

#: Largest tilt angle (rad) the linear tilt is trusted at. The model turns the face by
#: adding ``beta x + alpha y`` to its heights; a rigid turn also moves each point sideways by
#: its lever times ``angle^2 / 2`` and turns the pressure off the vertical by the angle:
#: terms of relative size ``angle^2 / 2``, 0.5 % at 0.1 rad (the force tolerance the
#: solvers are checked to against their reference).
SMALL_ANGLE = 0.1

#: Corners of the polygon circumscribing a sphere's material disc in the hull of the material.
DISC_CORNERS = 32


def hull_distance(points: np.ndarray, p) -> float:
    """Distance (mm) from ``p`` to the convex hull of ``points`` (n x 2); 0 inside."""
    from scipy.optimize import nnls

    corners = hull_corners(np.asarray(points, dtype=float))
    p = np.asarray(p, dtype=float)
    if len(corners) == 1:
        return float(np.hypot(*(corners[0] - p)))
    # the hull's nearest point is sum w_i x_i with w >= 0, sum w = 1: non-negative least
    # squares with the sum held by a heavy row
    weight = 1e6 * max(float(np.ptp(corners, axis=0).max()), 1.0)
    A = np.vstack([corners.T, np.full(len(corners), weight)])
    w, _ = nnls(A, np.concatenate([p, [weight]]))
    return float(np.hypot(*(corners.T @ w - p)))


def hull_corners(points: np.ndarray) -> np.ndarray:
    """The corners of the convex hull of ``points`` (n x 2): the ends of the segment when
    they are collinear, the point when they coincide."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):  # fewer than 3 points, or all on one line
        axis = points[np.argmax(np.linalg.norm(points - points[0], axis=1))] - points[0]
        along = (points - points[0]) @ axis
        return points[[int(np.argmin(along)), int(np.argmax(along))]]


def material_points(scene, h: float) -> np.ndarray:
    """Points whose convex hull holds every cell with material on the reference's grid:
    the grid's corners for a paraboloid (material everywhere), each sphere's disc of radius
    ``R`` as a circumscribed polygon clamped to the grid."""
    from .reference.on_scene import reference_grid

    grid = reference_grid(scene, h)
    x0, x1 = grid.x0 - 0.5 * h, grid.x0 + (grid.nx - 0.5) * h
    y0, y1 = grid.y0 - 0.5 * h, grid.y0 + (grid.ny - 0.5) * h
    spheres = np.array([(a.x, a.y, a.R) for a in scene.asperities if a.shape == "sphere"], dtype=float)
    if len(spheres) < len(scene.asperities):
        return np.array([(x0, y0), (x1, y0), (x0, y1), (x1, y1)])
    angle = np.linspace(0.0, 2.0 * math.pi, DISC_CORNERS, endpoint=False)
    r = spheres[:, 2:3] / math.cos(math.pi / DISC_CORNERS)
    px = np.clip(spheres[:, 0:1] + r * np.cos(angle), x0, x1)
    py = np.clip(spheres[:, 1:2] + r * np.sin(angle), y0, y1)
    return np.column_stack([px.ravel(), py.ravel()])


def check_pivot_reach(scene, h: float) -> None:
    """Raise :class:`SceneError` when the pivot of a free tilt lies outside the material
    of the reference's grid at cell size ``h`` (more than a cell away): no tilt balances
    the moments there."""
    if not scene.tilt or scene.surface is not None:
        return
    outside = hull_distance(material_points(scene, h), scene.pivot)
    if outside > h:
        raise SceneError(
            f"load.pivot = {list(scene.pivot)!r} mm lies {outside:.3g} mm outside every place the "
            "tips have material within the reach of the load (the grid contact can reach): no tilt "
            "balances the moments; put the pivot among the tips"
        )


def warn_large_tilt(tilt) -> None:
    """Warn (:class:`~twoscale.errors.TiltWarning`) when a solved tilt ``(alpha, beta)``
    (rad) exceeds :data:`SMALL_ANGLE`: the answer is that of the linear model, whose
    dropped terms are then over 0.5 % of the forces and levers."""
    if tilt is None:
        return
    worst = max(abs(float(a)) for a in tilt)
    if worst <= SMALL_ANGLE:
        return
    warnings.warn(
        TiltWarning(
            f"tilt (alpha {tilt[0]:.3g}, beta {tilt[1]:.3g}) rad exceeds the small angles the "
            f"linear tilt assumes (|angle| <= {SMALL_ANGLE:g} rad): the terms it drops are "
            f"about {100 * worst**2 / 2:.2g} % of the forces and levers; check the tips' heights "
            "and the pivot (load.pivot)"
        ),
        stacklevel=user_stacklevel(),
    )


def pivot_route(scene) -> str | None:
    """Why a tilted tip scene runs on its full grid, or None: the pivot lies farther outside
    the tips' hull than the widest expected contact radius (each tip alone at its expected
    approach), so the contacts must move along the flanks beyond their apexes' patches."""
    if not scene.tilt or scene.surface is not None:
        return None
    from .resolution import expected_contact_radii

    outside = hull_distance(scene.tips, scene.pivot)
    if outside <= float(np.max(expected_contact_radii(scene))):
        return None
    return (
        f"the pivot lies {outside:.3g} mm outside the tips' convex hull, beyond their contact "
        "radii: the tilt moves the contact onto the tips' flanks, away from the patches around the apexes"
    )
