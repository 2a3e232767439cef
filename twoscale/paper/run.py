"""Solve the paper's cases with the two-scale method and the reference solver (fig. 6)."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..grid import Grid
from ..influence import HalfSpace
from ..reference import solve_reference
from ..results import ContactResult
from ..driver import solve_twoscale
from .cases import PAPER_SPACINGS, PaperCase, paper_cases, reference_surface


@dataclass(frozen=True)
class CaseResult:
    """One case of the study, both solvers on the same lattice.

    Attributes
    ----------
    case : PaperCase
    grid : Grid
        The reference grid; the maps below live on it.
    pressure : (ny, nx) array, MPa — two-scale final pressure p.
    initial : (ny, nx) array, MPa — eq. 7 pressure p0.
    reference : (ny, nx) array, MPa — reference pressure p_r.
    err_p0_percent, err_p_percent : float
        ``100 ||p0 - p_r|| / ||p_r||`` and ``100 ||p - p_r|| / ||p_r||``.
    mean_pressure : float, MPa
        p_m = total load / contact area (two-scale).
    twoscale : ContactResult
    ref : ContactResult
    reference_cells : (ny, nx) bool array — cells the reference solver carries (reachable).
    owner : (ny, nx) int array — owning asperity of each cell (-1: none reaches it).
    reference_seconds : float
        Wall time of the reference solve measured around it (set-up included), s.
    """

    case: PaperCase
    grid: Grid
    pressure: np.ndarray
    initial: np.ndarray
    reference: np.ndarray
    err_p0_percent: float
    err_p_percent: float
    mean_pressure: float
    twoscale: ContactResult
    ref: ContactResult
    reference_cells: np.ndarray
    owner: np.ndarray
    reference_seconds: float = float("nan")

    @property
    def sweeps(self) -> int:
        return int(self.twoscale.iterations["micro"])

    def profile(self, *, half_width: float = 0.4) -> tuple[np.ndarray, np.ndarray]:
        """Fig. 5: ``(r/R, p/p_m)`` along the vertical line x = x_k through the upper tip,
        ``|r| <= half_width R``, on the cells the upper asperity owns (others' pressure is 0)."""
        a = self.case.asperities[self.case.upper]
        g = self.grid
        i = int(round((a.x - g.x0) / g.h))
        r = (g.y - a.y) / self.case.R
        keep = np.abs(r) <= half_width
        p = np.where(self.owner[:, i] == self.case.upper, self.pressure[:, i], 0.0)
        return r[keep], p[keep] / self.mean_pressure


@dataclass(frozen=True)
class StudyResult:
    """All cases of both layouts: ``cases[layout]`` is a list of CaseResult."""

    cases: dict
    quick: bool
    reference_method: str


def assemble(grids, arrays, target: Grid) -> np.ndarray:
    """Patch arrays on aligned grids, summed onto ``target``."""
    out = np.zeros(target.shape)
    for g, a in zip(grids, arrays):
        di, dj = g.offset_in(target)
        i0, j0 = max(di, 0), max(dj, 0)
        i1, j1 = min(di + g.nx, target.nx), min(dj + g.ny, target.ny)
        if i1 > i0 and j1 > j0:
            out[j0:j1, i0:i1] += a[j0 - dj : j1 - dj, i0 - di : i1 - di]
    return out


def _rel_percent(a: np.ndarray, b: np.ndarray) -> float:
    return 100.0 * float(np.linalg.norm(a - b) / np.linalg.norm(b))


def run_case(case: PaperCase, *, tol: float = 1e-6, reference_method: str = "cg") -> CaseResult:
    """Two-scale and reference solves of one case; errors on the reference grid.

    Parameters
    ----------
    case : PaperCase
    tol : float, default 1e-6
        Eq. 9 tolerance of the two-scale sweeps.
    reference_method : {"cg", "dense", "auto"}, default "cg"
        The reference solver (Polonsky-Keer CG solves the same discrete problem as
        Johnson's dense inversion, to 1e-10, and fits the sparse cases in memory).
    """
    provider = HalfSpace(case.material)
    # the paper's iteration (block Gauss-Seidel from eq. 7), whose p0 the study reports
    ts = solve_twoscale(
        provider, case.asperities, h=case.h, penetration=case.penetration, tol=tol, iteration="block-gs"
    )
    surf = reference_surface(case)
    t0 = time.perf_counter()
    ref = solve_reference(provider, surf, method=reference_method, penetration=case.penetration)
    t_ref = time.perf_counter() - t0
    grids = [f.grid for f in ts.fields]
    p = assemble(grids, [f.pressure for f in ts.fields], surf.grid)
    p0 = assemble(grids, ts.details.micro.p0, surf.grid)
    pr = ref.pressure_on(surf.grid)
    area = float(np.count_nonzero(p > 0)) * case.h**2
    return CaseResult(
        case,
        surf.grid,
        p,
        p0,
        pr,
        _rel_percent(p0, pr),
        _rel_percent(p, pr),
        ts.total_load / area if area > 0 else float("nan"),
        ts,
        ref,
        np.isfinite(surf.height),
        surf.owner,
        t_ref,
    )


def run_study(
    *, quick: bool = False, tol: float = 1e-6, reference_method: str = "cg", layouts=("two", "seven"), progress=None
) -> StudyResult:
    """Every case of the study.

    Parameters
    ----------
    quick : bool, default False
        Cells twice as large as the paper's (four times fewer), same d/2R values.
    tol : float, default 1e-6
    reference_method : str, default "cg"
    layouts : tuple, default ("two", "seven")
    progress : callable, optional
        ``progress(text)`` after each case.
    """
    factor = 2.0 if quick else 1.0
    out = {}
    for layout in layouts:
        out[layout] = []
        for case in paper_cases(layout, cell_factor=factor):
            res = run_case(case, tol=tol, reference_method=reference_method)
            out[layout].append(res)
            if progress is not None:
                progress(
                    f"{layout} d/2R={case.spacing:g}: p0 {res.err_p0_percent:.3f} %, "
                    f"p {res.err_p_percent:.2e} %, {res.sweeps} sweeps"
                )
    return StudyResult(out, quick, reference_method)


__all__ = ["CaseResult", "StudyResult", "run_case", "run_study", "assemble", "PAPER_SPACINGS"]
