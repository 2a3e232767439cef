"""One time step as an elastic contact problem, solved by the full-grid reference or by
the two-scale method.

A step asks for ``p`` with ``K (J_eff p + H) = d - z`` on the contact (``p >= 0``, no
overlap elsewhere; :mod:`twoscale.viscoelastic.memory`). With the body's provider built at
the relaxed modulus ``E0`` (cell matrix ``A0 = K / E0``) this is the elastic problem of that
provider for the pressure ``p0 = E0 J_eff p`` on the indenter heights ``z + u_H``,
``u_H = K H = E0 A0 H``, under the load ``E0 J_eff W`` (or the same approach ``d``): every
elastic solver of the project runs it unchanged, and the answer is scaled back
(:func:`scaled`). On a finite block with constant nu the same holds, its compliance being
proportional to ``1 / E``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..grid import Grid
from ..indenters import Asperity, Surface
from ..influence.cached import with_caches
from ..results import ContactResult, summarise
from ..warm_start import WarmStart, warm_start

#: The micro iteration of a warm-started two-scale step (None: the policy's, as cold).
WARM_ITERATION = "two-level"
#: The far-field coupling of a warm-started two-scale step where the policy chose exact
#: coupling for the cold solve: from a near start the sweeps are as many either way, and
#: the far field (patches apart by more than their sizes over sqrt(WARM_FAR_TOL) coupled by
#: their resultants) makes each one cheaper; tighter than the policy's 0.3 for large scenes,
#: so that the history stays within the block tests' 1e-5 of the reference.
WARM_FAR_TOL = 0.1
#: Options that fix the micro iteration: given by the caller, they are kept.
WARM_FIXED = frozenset({"iteration", "far_tol", "coarse"})


def scaled(result: ContactResult, factor: float) -> ContactResult:
    """``result`` with every pressure, force and load multiplied by ``factor`` (the gap,
    approach and tilt are unchanged: they are the physical ones)."""
    fields = tuple(dataclasses.replace(f, pressure=f.pressure * factor) for f in result.fields)
    details = result.details
    macro = getattr(details, "macro", None)
    if macro is not None:  # the macro forces too: a start from this result then has one scale
        details = dataclasses.replace(details, macro=dataclasses.replace(macro, forces=macro.forces * factor))
    return dataclasses.replace(
        result,
        fields=fields,
        total_load=result.total_load * factor,
        asperities=summarise(fields, result.n_asperities),
        details=details,
    )


@dataclass(frozen=True)
class StepProblem:
    """What a step solver needs: the control value (N or mm, physical), the factor
    ``E0 J_eff`` and the history displacement ``u_H`` on the memory grid (mm); ``start``
    the previous step's answer and ``start_tips`` the tips it was solved for ((N, 2) mm;
    None: this step's own, the tips not having moved); ``tol`` the two-scale micro
    tolerance of this step (None: the solver's own)."""

    value: float
    factor: float
    u_H: np.ndarray
    start: ContactResult | None
    start_tips: np.ndarray | None = None
    tol: float | None = None


class ReferenceStep:
    """Steps by the full-grid reference (:func:`twoscale.reference.solve_reference`) on the
    memory grid, warm-started (CG) from the previous step's pressure."""

    name = "reference"

    def __init__(self, provider, surface: Surface, *, kind: str, tilt: bool, pivot, solver: str = "auto", options=None):
        self.provider, self.surface, self.kind = provider, surface, kind
        self.tilt, self.pivot, self.solver = tilt, pivot, solver
        self.options = dict(options or {})

    def solve(self, step: StepProblem) -> ContactResult:
        from ..reference import AUTO_DENSE_CELLS, solve_reference

        s = self.surface
        surf = Surface(s.grid, s.height + step.u_H, s.owner, s.n_asperities)
        load = {"penetration": step.value} if self.kind == "penetration" else {"total_load": step.value * step.factor}
        solver = self.solver
        if solver == "auto":
            solver = "dense" if np.count_nonzero(np.isfinite(s.height)) <= AUTO_DENSE_CELLS else "cg"
        opts = dict(self.options)
        if solver == "cg" and step.start is not None:
            opts["start"] = step.start.pressure_on(s.grid) * step.factor
        result = solve_reference(self.provider, surf, method=solver, tilt=self.tilt, pivot=self.pivot, **load, **opts)
        return scaled(result, 1.0 / step.factor)


@dataclass(frozen=True)
class HistoryAsperity(Asperity):
    """An asperity whose height includes the history displacement ``u_H`` (looked up on
    the memory grid): ``z`` is its tip's recess plus ``u_H`` at the tip (what the macro
    step sees), ``height`` adds ``u_H`` at every cell (what the micro step sees)."""

    lift: float = 0.0
    lookup: object = dataclasses.field(default=None, compare=False, repr=False)

    def height(self, X, Y):
        base = super().height(X, Y) - self.lift
        return base + self.lookup(X, Y)


class LiftedBasins:
    """The basins of a height map (:class:`twoscale.surface.indenter.BasinMap`) with the
    history displacement ``u_H`` added to every recess they give, so that the micro step
    sees it on a map's cells as :class:`HistoryAsperity` gives it on a tip's (the map's
    asperities are sampled together through their shared basins)."""

    def __init__(self, basins, lookup: GridLookup):
        self.basins, self.lift = basins, lookup
        self.grid, self.labels, self.book = basins.grid, basins.labels, basins.book

    @property
    def n_labels(self) -> int:
        return self.basins.n_labels

    def lookup(self, X, Y, label: int) -> np.ndarray:
        return self.basins.lookup(X, Y, label) + self.lift(X, Y)

    def union_on(self, X, Y, index: dict):
        height, owner = self.basins.union_on(X, Y, index)
        return np.where(owner >= 0, height + self.lift(X, Y), np.inf), owner


class GridLookup:
    """``u_H`` at cell centres of the memory grid's lattice (cells beyond it take the
    nearest edge cell: no contact reaches there)."""

    def __init__(self, grid: Grid, u: np.ndarray):
        self.grid, self.u = grid, u

    def __call__(self, X, Y):
        g = self.grid
        i = np.clip(np.rint((np.asarray(X) - g.x0) / g.h).astype(np.int64), 0, g.nx - 1)
        j = np.clip(np.rint((np.asarray(Y) - g.y0) / g.h).astype(np.int64), 0, g.ny - 1)
        return self.u[j, i]


class TwoScaleStep:
    """Steps by the two-scale method (:func:`twoscale.driver.solve_twoscale`): the macro
    step sees each tip lowered by ``u_H`` there, the micro step ``u_H`` on every patch
    cell; each step starts from the previous step's answer (:mod:`twoscale.warm_start`: its
    macro forces, approach and tilt, and its pressure around each tip)."""

    name = "twoscale"

    def __init__(self, provider, asperities, grid: Grid, *, h: float, kind: str, tilt: bool, pivot, options=None):
        # the body through caches kept for every step (tables, operators between patches)
        self.provider, self.asperities, self.grid, self.h = with_caches(provider), tuple(asperities), grid, h
        self.kind, self.tilt, self.pivot = kind, tilt, pivot
        self.options = dict(options or {})
        self._reference = None
        self._far_tol = None  # the far-field tolerance the policy last chose

    def _wrapped(self, u_H: np.ndarray):
        if not np.any(u_H):
            return self.asperities
        look = GridLookup(self.grid, u_H)
        x = np.array([a.x for a in self.asperities])
        y = np.array([a.y for a in self.asperities])
        lift = look(x, y)
        lifted: dict = {}  # a height map's basins, lifted once for all its asperities
        out = []
        for a, l in zip(self.asperities, lift):
            basins = getattr(a, "basins", None)
            if basins is None:
                out.append(HistoryAsperity(a.x, a.y, a.z + float(l), a.R, a.shape, lift=float(l), lookup=look))
                continue
            if id(basins) not in lifted:
                lifted[id(basins)] = LiftedBasins(basins, look)
            out.append(dataclasses.replace(a, z=a.z + float(l), basins=lifted[id(basins)]))
        return tuple(out)

    def solve(self, step: StepProblem) -> ContactResult:
        from ..driver import solve_twoscale

        load = {"penetration": step.value} if self.kind == "penetration" else {"total_load": step.value * step.factor}
        if self.kind == "total" and step.value <= 0:  # nothing to carry: the reference's trivial answer
            return self._trivial(step)
        start = None
        if step.start is not None and step.start.method == "twoscale" and step.start.total_load > 0:
            # the previous step's answer starts both steps: macro forces, and the pressure
            # around each tip, moved with it when the tips moved (rolling)
            tips = np.array([[a.x, a.y] for a in self.asperities], dtype=float).reshape(-1, 2)
            before = tips if step.start_tips is None else step.start_tips
            start = warm_start(scaled(step.start, step.factor), before, len(tips), self.h)
            start = own_rigid(start, step.start) if self.tilt else start
        options = dict(self.options)
        if step.tol is not None:
            options["tol"] = step.tol
        asperities = self._wrapped(step.u_H)

        def run(**extra) -> ContactResult:
            return solve_twoscale(
                self.provider,
                asperities,
                h=self.h,
                tilt=self.tilt,
                pivot=self.pivot,
                anchor=(self.grid.x0, self.grid.y0),
                start=start,
                **load,
                **options,
                **extra,
            )

        warm = self._warm_choice(start, options)
        result = run(**warm) if warm else run()
        if warm and not result.converged:  # the policy decides again
            result = run()
        choice = getattr(getattr(result.details, "micro", None), "choice", None)
        if choice is not None and not choice.by_caller:
            self._far_tol = choice.far_tol
        return scaled(result, 1.0 / step.factor)

    def _warm_choice(self, start, options) -> dict:
        """The micro iteration of a warm-started step: from a near start the two-level
        iteration needs a few sweeps, where the policy, costing a cold solve, may pick the
        union CG; it keeps the far-field coupling the policy last chose, or takes
        :data:`WARM_FAR_TOL` (None: exact)."""
        if start is None or not WARM_ITERATION or WARM_FIXED.intersection(options):
            return {}
        far_tol = self._far_tol if self._far_tol is not None else WARM_FAR_TOL
        return {"far_tol": far_tol} if far_tol is not None else {"iteration": WARM_ITERATION}

    def _trivial(self, step: StepProblem) -> ContactResult:
        from ..indenters import surface_on

        if self._reference is None:
            self._reference = ReferenceStep(
                self.provider, surface_on(self.grid, self.asperities), kind=self.kind, tilt=self.tilt, pivot=self.pivot
            )
        return self._reference.solve(step)


def own_rigid(start: WarmStart, previous: ContactResult) -> WarmStart:
    """``start`` from the previous macro step's own approach (not the micro step's) and the
    micro step's tilt, its micro step from this macro step's answer (not moved by the last
    micro correction). Under a free tilt the two approaches differ where the face turns
    far: four spheres (R 5 mm) askew by 0.2 rad, the micro approach 0.1 mm below the macro
    one (a sphere's nearest point to the turned face lies about ``R theta^2 / 2`` below its
    apex, which the point tips do not see). The micro approach left every tip off the body
    (Newton had no contact to step on), and, as the micro step's start, sized patches only
    for the low tips (the union box then held no cells about the pivot).

    The tilt is the micro step's: where the tips the macro step loads lie on a line through
    the pivot, their point forces have no moment about that line, so the macro step keeps
    whatever turn about it it starts from, and the micro step sets it from the contacts'
    widths. Four spheres, one raised 0.4 mm and one 4 mm: the last macro tilt lay 0.07-0.08
    rad from the micro one about the loaded diagonal; started there, the warm micro step
    failed at every step and the policy's solve took 30-50 sweeps (72-80 s of CPU in all);
    from the micro tilt the warm step takes 4-8 sweeps."""
    macro = getattr(getattr(previous, "details", None), "macro", None)
    if start.macro is None or macro is None or getattr(macro, "penetration", None) is None:
        return start
    rigid = dataclasses.replace(start.macro, penetration=float(macro.penetration))
    micro = None if start.micro is None else dataclasses.replace(start.micro, theta_offset=(0.0, 0.0, 0.0))
    return dataclasses.replace(start, macro=rigid, micro=micro)


def pressure_on(result: ContactResult, grid: Grid) -> np.ndarray:
    """The result's pressure on the memory grid (MPa), as a flat field."""
    return result.pressure_on(grid).ravel()


__all__ = [
    "HistoryAsperity",
    "LiftedBasins",
    "ReferenceStep",
    "StepProblem",
    "TwoScaleStep",
    "own_rigid",
    "pressure_on",
    "scaled",
]
