"""The discrete contact problem shared by the reference solvers, and their result.

On a grid of square cells of side ``h`` with indenter heights ``z`` (``inf`` where no
indenter has material: such cells never touch), find ``p >= 0`` (MPa) and the rigid
motion so that the gap

    g = z + beta (x - px) + alpha (y - py) + A p - d

is ``>= 0`` everywhere and ``0`` wherever ``p > 0`` (Johnson 1985, ch. 5;
docs/method.md section 3). ``A`` is the provider's cell matrix (mm/MPa).

Three load modes, one algebra: the unknown rigid motion ``m`` multiplies the columns of
a *constraint basis* ``B`` and the pressure must satisfy ``h^2 B^T p = target``:

* penetration control: ``d`` given, ``B`` has no column;
* load control: ``B = [1]``, ``m = [d]``, ``target = [W]``;
* tilt (ball-and-socket joint): ``B = [1, x - px, y - py]``, ``m = [d, -beta, -alpha]``,
  ``target = [W, 0, 0]`` (total load and both moments about the pivot, paper eq. 11-12).

With this notation the contact condition is ``A p + z - B m = 0`` on the contact, i.e.
the KKT conditions of ``min 1/2 p.A p + z.p`` subject to ``p >= 0`` and the constraints,
with ``m`` their Lagrange multipliers.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..control import check_control
from ..indenters import Surface
from ..details import ReferenceDetails
from ..errors import SceneError
from ..results import ContactResult, PressureField, summarise


def _finite_number(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return value


@dataclass(frozen=True)
class ContactProblem:
    """A validated contact problem on one grid (see the module docstring).

    Attributes
    ----------
    surface : Surface
    mode : {"penetration", "load", "tilt"}
    penetration : float or None
        Given rigid approach d, mm (penetration control only).
    total_load : float or None
        Given total load W, N (load control and tilt).
    pivot : (float, float)
        Joint position (px, py), mm (used with tilt only).
    """

    surface: Surface
    mode: str
    penetration: float | None
    total_load: float | None
    pivot: tuple[float, float]

    @property
    def grid(self):
        return self.surface.grid

    @functools.cached_property
    def candidates(self) -> np.ndarray:
        """Cells where an indenter has material, (ny, nx) bool (read-only: made once, a
        solve asks for it three times)."""
        cand = np.isfinite(self.surface.height)
        cand.setflags(write=False)
        return cand

    def basis(self) -> np.ndarray:
        """Constraint basis ``B`` on the whole grid, shape (ny*nx, k), k = 0, 1 or 3."""
        n = self.grid.size
        if self.mode == "penetration":
            return np.zeros((n, 0))
        if self.mode == "load":
            return np.ones((n, 1))
        X, Y = self.grid.centres()
        return np.column_stack([np.ones(n), X.ravel() - self.pivot[0], Y.ravel() - self.pivot[1]])

    def target(self) -> np.ndarray:
        """Right-hand side of ``B^T p = target`` divided by h^2, MPa (k,)."""
        if self.mode == "penetration":
            return np.zeros(0)
        t = np.zeros(1 if self.mode == "load" else 3)
        t[0] = self.total_load / self.grid.h**2
        return t

    def rigid_motion(self, m: np.ndarray) -> tuple[float, tuple[float, float] | None]:
        """Penetration d (mm) and tilt (alpha, beta) (rad, or None) from multipliers ``m``."""
        if self.mode == "penetration":
            return self.penetration, None
        if self.mode == "load":
            return float(m[0]), None
        return float(m[0]), (float(-m[2]), float(-m[1]))


def make_problem(
    surface: Surface, *, penetration=None, total_load=None, tilt: bool = False, pivot=(0.0, 0.0)
) -> ContactProblem:
    """Validate the load keywords and return a :class:`ContactProblem`.

    Raises
    ------
    ValueError
        Naming the bad value: both or neither of ``penetration`` / ``total_load``,
        ``tilt`` without ``total_load``, NaN or infinite values, a negative load,
        NaN heights.
    """
    if not isinstance(surface, Surface):
        raise ValueError(f"surface must be a twoscale.indenters.Surface, got {type(surface).__name__}")
    if np.any(np.isnan(surface.height)):
        raise ValueError("surface.height contains NaN")
    check_control(penetration, total_load)
    if not isinstance(tilt, (bool, np.bool_)):
        raise ValueError(f"tilt must be True or False, got {tilt!r}")
    if tilt and total_load is None:
        raise ValueError(f"tilt=True needs total_load (N), got penetration={penetration!r}")
    try:
        px, py = pivot
    except (TypeError, ValueError):
        raise ValueError(f"pivot must be a pair (px, py) in mm, got {pivot!r}") from None
    pivot = (_finite_number("pivot[0]", px), _finite_number("pivot[1]", py))
    if penetration is not None:
        d = _finite_number("penetration", penetration)
        return ContactProblem(surface, "penetration", d, None, pivot)
    W = _finite_number("total_load", total_load)
    if W < 0:
        raise ValueError(f"total_load must be >= 0 (N), got {total_load!r}")
    if tilt and W > 0:
        _check_pivot_inside(surface, pivot)
    return ContactProblem(surface, "tilt" if tilt else "load", None, W, pivot)


def _check_pivot_inside(surface: Surface, pivot: tuple[float, float]) -> None:
    """With tilt, both moments can vanish only if the pivot lies in the convex hull of
    the cells with material (a positive pressure's centre lies inside its support)."""
    from scipy.spatial import ConvexHull, QhullError

    cand = np.isfinite(surface.height)
    # the hull of a grid's cells is the hull of each row's first and last cell with
    # material (a million cells: 2,000 points instead of a million)
    rows = np.flatnonzero(cand.any(axis=1))
    first = np.argmax(cand[rows], axis=1)
    last = cand.shape[1] - 1 - np.argmax(cand[rows, ::-1], axis=1)
    x, y = surface.grid.x, surface.grid.y
    pts = np.column_stack([x[np.concatenate([first, last])], np.concatenate([y[rows], y[rows]])])
    try:
        hull = ConvexHull(pts)
    except (QhullError, ValueError):  # fewer than 3 cells or all on one line
        inside = False
    else:
        tol = 1e-9 * surface.grid.h
        inside = bool(np.all(hull.equations[:, :2] @ np.asarray(pivot) + hull.equations[:, 2] <= tol))
    if not inside:
        raise SceneError(
            f"pivot {pivot!r} (mm) lies outside the cells with indenter material: no tilt balances the moments"
        )


def heights_with_tilt(problem: ContactProblem, tilt) -> np.ndarray:
    """Indenter heights on the grid including the tilt, mm (inf where no material)."""
    z = problem.surface.height
    if tilt is None:
        return z
    alpha, beta = tilt
    X, Y = problem.grid.centres()
    with np.errstate(invalid="ignore"):
        return z + beta * (X - problem.pivot[0]) + alpha * (Y - problem.pivot[1])


def trivial_result(problem: ContactProblem, method: str, timings: dict) -> ContactResult | None:
    """The result when nothing can touch (zero pressure), else None.

    Penetration control: no cell has ``z < d``. Load control: ``W = 0`` (the surface
    just touches: d = lowest height, tilt zero) or no cell with material at all.
    """
    z = problem.surface.height
    cand = np.isfinite(z)
    if problem.mode == "penetration":
        if np.any(z[cand] < problem.penetration):
            return None
        return build_result(
            problem,
            method,
            np.zeros(problem.grid.shape),
            np.zeros(problem.grid.shape),
            problem.penetration,
            None,
            Outcome(True, "no cell reaches the indenter: zero pressure", {"outer": 0}, {}, timings),
        )
    if not np.any(cand):
        raise ValueError("surface has no cell with indenter material: total_load cannot be carried")
    if problem.total_load > 0:
        return None
    tilt = (0.0, 0.0) if problem.mode == "tilt" else None
    return build_result(
        problem,
        method,
        np.zeros(problem.grid.shape),
        np.zeros(problem.grid.shape),
        float(np.min(z[cand])),
        tilt,
        Outcome(True, "total_load = 0: zero pressure", {"outer": 0}, {}, timings),
    )


@dataclass(frozen=True)
class Outcome:
    """How a reference solve ended: converged, its message, iteration counts, residual
    histories, timings (s) and the solver's details."""

    converged: bool
    message: str
    iterations: dict
    residuals: dict
    timings: dict
    details: ReferenceDetails | None = None


def build_result(
    problem: ContactProblem,
    method: str,
    pressure: np.ndarray,
    displacement: np.ndarray,
    d: float,
    tilt,
    outcome: Outcome,
) -> ContactResult:
    """Assemble the :class:`ContactResult` from the pressure and displacement (ny, nx),
    the approach ``d`` (mm) and ``tilt``; ``method`` is the solver that ran ("dense" or
    "cg"), recorded as ``result.solver`` (``result.method`` is "reference")."""
    converged, message, iterations = outcome.converged, outcome.message, outcome.iterations
    residuals, timings, details = outcome.residuals, outcome.timings, outcome.details
    surface = problem.surface
    with np.errstate(invalid="ignore"):  # (in place: the same values, two grid passes less)
        gap = np.add(heights_with_tilt(problem, tilt), displacement, dtype=float)
        gap -= d
    gap[~np.isfinite(surface.height)] = np.inf
    field = PressureField(problem.grid, pressure, surface.owner, gap)
    total = float(problem.grid.h**2 * pressure.sum())
    return ContactResult(
        method="reference",
        solver=method,
        fields=(field,),
        penetration=float(d),
        tilt=tilt,
        total_load=total,
        asperities=summarise((field,), surface.n_asperities),
        converged=bool(converged),
        message=message,
        iterations=dict(iterations),
        residuals={k: tuple(float(x) for x in v) for k, v in residuals.items()},
        timings_s=dict(timings),
        details=details or ReferenceDetails(method),
    )


def initial_active_set(problem: ContactProblem, E_star: float) -> np.ndarray:
    """A first guess of the contact, (ny, nx) bool.

    Penetration control: each indenter's Hertz contact ``z < (d + z_tip) / 2``, with
    ``z_tip`` the lowest height of the cells it owns (interaction only shrinks
    contacts, so this is close to and mostly larger than the contact). Load control: the cells below ``min z + delta`` with the smallest
    ``delta`` at which a flat punch of the same area pressed by ``delta`` would carry W
    (``2 E* a delta >= W``); for a Hertz sphere this is about 1.1 times the contact radius.
    """
    z = problem.surface.height
    cand = np.isfinite(z)
    if problem.mode == "penetration":
        # Hertz: the contact is where an indenter is within half its local approach of
        # the level, z < (d + z_tip) / 2 (a^2 = R d against the overlap 2 R d)
        tips = np.full(problem.surface.n_asperities + 1, np.inf)
        own = problem.surface.owner
        np.minimum.at(tips, own[cand], z[cand])
        z_tip = np.where(cand, tips[own], np.inf)
        first = cand & (z < 0.5 * (problem.penetration + z_tip))
        return first if np.any(first) else cand & (z < problem.penetration)
    zs = np.sort(z[cand])
    delta = zs - zs[0]
    area = problem.grid.h**2 * np.arange(1, zs.size + 1)
    carried = 2.0 * E_star * np.sqrt(area / np.pi) * delta
    k = int(np.searchsorted(carried, problem.total_load))
    level = zs[min(max(k, 3 if problem.mode == "tilt" else 0), zs.size - 1)]
    return cand & (z <= level)
