"""Per-asperity load-penetration laws from single-asperity micro-scale solves.

The law of asperity ``k`` is tabulated by pressing its basin alone (the height map on
its own samples, nothing elsewhere) into the elastic half-space at ``levels``
penetrations ``delta_max 2^-(levels-1) ... delta_max/2, delta_max`` below its summit,
each a full contact solve (Polonsky and Keer's constrained CG,
:func:`twoscale.reference.solve_cg`) on the samples the basin can reach at that depth.
The table, starting at (0, 0), becomes a :class:`twoscale.laws.TabulatedLaw` (monotone
PCHIP, power-law continuation beyond ``delta_max``): the paper's "any monotone law" for
shapes that are not spheres.

The law is the half-space's one on every body: on the finite block the macro step adds
the block's smooth self-compliance at the tip (:class:`twoscale.laws.CompliantLaw`), as
it does for spheres. The laws depend on the surface, ``E*`` and the cell size ``h``;
:class:`twoscale.surface.lawcache.LawCache` keeps them on disk under that key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..grid import Grid
from ..indenters import surface_on
from ..laws import HertzLaw, TabulatedLaw
from ..reference import solve_cg

#: Half-widths of the single-asperity grids are multiples of this many cells.
SNAP_CELLS = 4
#: Penetrations tabulated per asperity (halving from delta_max).
LEVELS = 5
#: Tolerance of each single-asperity CG solve (relative gap; 1e-6 leaves the force within
#: about 1e-5 of the exact discrete one, far below what the macro step needs).
SOLVE_TOL = 1e-6


@dataclass(frozen=True, eq=False)
class LawTable:
    """Tabulated laws of the asperities of one surface.

    Attributes
    ----------
    delta : (N, levels + 1) array, mm
        Penetrations below each summit, starting at 0.
    P : (N, levels + 1) array, N
        Force of each asperity alone on the half-space at those penetrations.
    E_star : float
        Plane-strain modulus of the solves, MPa.
    h : float
        Cell size of the solves, mm.
    converged : bool
        Every single-asperity solve met its tolerance.
    """

    delta: np.ndarray
    P: np.ndarray
    E_star: float
    h: float
    converged: bool = True

    def law(self, k: int) -> TabulatedLaw:
        """The law of asperity ``k``."""
        return TabulatedLaw(self.delta[k], self.P[k])

    def exponents(self) -> np.ndarray:
        """Exponent ``m`` of ``P ~ delta^m`` over the last two tabulated penetrations
        (Hertz: 1.5; a flat punch: 1)."""
        d, P = self.delta[:, -2:], self.P[:, -2:]
        return np.log(P[:, 1] / P[:, 0]) / np.log(d[:, 1] / d[:, 0])


def tabulate_law(
    asperity, provider, *, h: float, delta_max: float, levels: int = LEVELS, tol: float = SOLVE_TOL
) -> LawTable:
    """The law of one map asperity from single-asperity solves on the half-space
    ``provider`` (see the module docstring): a one-row :class:`LawTable`.

    Parameters
    ----------
    asperity : MapAsperity
    provider : HalfSpace
        The body (only ``E*`` matters).
    h : float
        Cell size, mm (the map's spacing after conditioning).
    delta_max : float
        Deepest tabulated penetration, mm (> 0).
    levels : int, default 5
        Penetrations tabulated (halving down from ``delta_max``).
    tol : float, default 1e-6
        CG tolerance of each solve.
    """
    if not (isinstance(levels, int) and levels >= 1):
        raise ValueError(f"levels must be an integer >= 1, got {levels!r}")
    if not (np.isfinite(delta_max) and delta_max > 0):
        raise ValueError(f"delta_max must be finite and > 0 (mm), got {delta_max!r}")
    delta = np.zeros((1, levels + 1))
    delta[0, 1:] = delta_max * 2.0 ** -np.arange(levels - 1, -1, -1, dtype=float)
    P = np.zeros_like(delta)
    P[0, 1:], ok = _single_asperity(provider, asperity, delta[0, 1:], h, tol)
    _check_increasing(delta, P)
    return LawTable(delta, P, float(provider.material.E_star), float(h), bool(ok))


def _law_grid(a, d: float, h: float) -> Grid:
    """The grid of asperity ``a``'s solve at depth ``d``: its reach plus two cells, the
    half-width rounded up to ``SNAP_CELLS`` cells (grids of few shapes, whose kernels the
    stacked solves and the provider share)."""
    cells = SNAP_CELLS * math.ceil((a.reach(d) / h + 2.0) / SNAP_CELLS)
    r = cells * h
    return Grid.covering(a.x - r, a.x + r, a.y - r, a.y + r, h, anchor=(a.basins.grid.x0, a.basins.grid.y0))


def stack_tables(rows) -> LawTable:
    """One :class:`LawTable` of the rows of several (same ``E*`` and ``h``)."""
    return LawTable(
        np.concatenate([r.delta for r in rows]),
        np.concatenate([r.P for r in rows]),
        rows[0].E_star,
        rows[0].h,
        all(r.converged for r in rows),
    )


def _single_asperity(provider, a, depths: np.ndarray, h: float, tol: float):
    """Force (N) of asperity ``a`` alone at each penetration ``depths`` (increasing, mm);
    each solve starts from the previous one's pressure."""
    forces = np.empty(depths.size)
    ok, previous = True, None
    for i, d in enumerate(depths):
        grid = _law_grid(a, d, h)
        start = None if previous is None else previous.grid.embed_in(previous.pressure, grid)
        res = solve_cg(provider, surface_on(grid, [a]), penetration=a.z + d, tol=tol, start=start)
        previous = res.fields[0]
        forces[i] = res.total_load
        ok &= bool(res.converged)
    return forces, ok


def _check_increasing(delta: np.ndarray, P: np.ndarray) -> None:
    """Check every row is strictly increasing (a contact's force grows with its depth)."""
    bad = np.flatnonzero(np.any(np.diff(P, axis=1) <= 0, axis=1))
    if bad.size:
        k = int(bad[0])
        raise ValueError(
            f"asperity {k}: its single-asperity forces {P[k].tolist()!r} N are not increasing "
            f"at penetrations {delta[k].tolist()!r} mm"
        )


@dataclass(frozen=True)
class SphereLawError:
    """What the equivalent spheres' Hertz laws miss against the tabulated laws.

    Attributes
    ----------
    per_asperity : (N,) array
        Largest relative force error ``|P_Hertz - P_tab| / P_tab`` over each table.
    median, largest : float
        Over the asperities.
    """

    per_asperity: np.ndarray
    median: float
    largest: float


def sphere_law_error(table: LawTable, asperities) -> SphereLawError:
    """Error of the equivalent-sphere laws over the tabulated points (penetration > 0)."""
    err = np.empty(len(asperities))
    for k, a in enumerate(asperities):
        d, p = table.delta[k, 1:], table.P[k, 1:]
        ph = HertzLaw(a.R, table.E_star).force(d)
        err[k] = float(np.max(np.abs(ph - p) / p))
    return SphereLawError(err, float(np.median(err)) if err.size else 0.0, float(err.max(initial=0.0)))
