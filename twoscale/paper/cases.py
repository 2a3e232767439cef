"""The paper's cases: identical spheres at one height on a half-space (docs/method.md section 4).

E = 10 MPa, nu = 0.5, R = 10 mm. Two spheres: tips ``d_c = 2R s`` apart on the y axis,
approach 0.05 R, cells 0.0125 R. Seven spheres: one at the origin and six on a hexagon of
radius ``d_c`` (one vertex on +y), approach 0.1 R, cells 0.025 R. The indenters are exact
spherical caps (the paper's "spherical caps"; ``shape="sphere"``), with the exact-sphere law
in the macro step; at these approaches it is within 0.5-1 % of Hertz's (paper eq. 10).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..grid import Grid
from ..indenters import Asperity, Surface, surface_on
from ..material import Material

#: d/2R values of the paper's figures 5-6, per layout.
PAPER_SPACINGS = {"two": (0.1, 0.15, 0.25, 1.0, 5.0), "seven": (0.1, 0.2, 0.3, 0.5, 1.0, 5.0)}
#: d/2R values whose pressure maps the paper shows (figs. 3 and 4).
MAP_SPACINGS = {"two": (0.1, 0.25, 1.0), "seven": (0.2, 1.0)}
_APPROACH = {"two": 0.05, "seven": 0.1}  # d / R
_CELL = {"two": 0.0125, "seven": 0.025}  # h / R


@dataclass(frozen=True)
class PaperCase:
    """One configuration of the study.

    Attributes
    ----------
    layout : {"two", "seven"}
    spacing : float
        d/2R: tip distance over the sphere diameter.
    asperities : tuple of Asperity
    penetration : float, mm
    h : float, mm
    material : Material
    R : float, mm
    upper : int
        Index of the upper asperity (largest y), whose vertical line fig. 5 shows.
    """

    layout: str
    spacing: float
    asperities: tuple
    penetration: float
    h: float
    material: Material
    R: float
    upper: int


def paper_case(
    layout: str,
    spacing: float,
    *,
    R: float = 10.0,
    E: float = 10.0,
    nu: float = 0.5,
    cell_factor: float = 1.0,
    shape: str = "sphere",
) -> PaperCase:
    """The case ``layout`` at d/2R = ``spacing``; ``cell_factor`` scales the paper's cell size
    (2 = twice coarser, for quick runs)."""
    if layout not in PAPER_SPACINGS:
        raise ValueError(f"layout must be one of {tuple(PAPER_SPACINGS)}, got {layout!r}")
    if not (isinstance(spacing, (int, float)) and math.isfinite(spacing) and spacing > 0):
        raise ValueError(f"spacing d/2R must be a finite number > 0, got {spacing!r}")
    if not (math.isfinite(cell_factor) and cell_factor > 0):
        raise ValueError(f"cell_factor must be > 0, got {cell_factor!r}")
    dc = 2.0 * R * spacing
    if layout == "two":
        tips = [(0.0, 0.5 * dc), (0.0, -0.5 * dc)]
    else:
        angles = math.pi / 2 + np.arange(6) * math.pi / 3
        tips = [(0.0, 0.0)] + [(dc * math.cos(t), dc * math.sin(t)) for t in angles]
    asps = tuple(Asperity(float(x), float(y), 0.0, R, shape) for x, y in tips)
    upper = int(np.argmax([a.y for a in asps]))
    return PaperCase(
        layout, float(spacing), asps, _APPROACH[layout] * R, _CELL[layout] * R * cell_factor, Material(E, nu), R, upper
    )


def paper_cases(layout: str, *, spacings=None, **kwargs) -> list[PaperCase]:
    """All cases of one layout (the paper's d/2R values by default)."""
    return [paper_case(layout, s, **kwargs) for s in (PAPER_SPACINGS[layout] if spacings is None else spacings)]


def reference_surface(case: PaperCase, *, margin_cells: int = 3) -> Surface:
    """The reference solver's problem on the two-scale's lattice (anchor at the origin):
    a grid covering every cell an indenter reaches at the approach, with the cells it cannot
    reach (height >= d; displacements are into the body) marked as having no material."""
    d, h = case.penetration, case.h
    r = max(a.reach(d - a.z) for a in case.asperities) + margin_cells * h
    xs = [a.x for a in case.asperities]
    ys = [a.y for a in case.asperities]
    grid = Grid.covering(min(xs) - r, max(xs) + r, min(ys) - r, max(ys) + r, h)
    s = surface_on(grid, case.asperities)
    reach = s.height < d
    return Surface(grid, np.where(reach, s.height, np.inf), np.where(reach, s.owner, -1), s.n_asperities)
