"""Constrained conjugate gradient with FFT products (Polonsky & Keer 1999).

Minimises ``1/2 p.A p + z.p`` over ``p >= 0`` subject to the load constraints
``h^2 B^T p = target`` (:mod:`twoscale.reference._problem`): conjugate gradient on the
cells that carry pressure, where the gradient (the gap) is projected orthogonally to the
constraint basis ``B`` (Polonsky & Keer subtract its mean for load control; with tilt the
least-squares plane ``d - beta x - alpha y`` is subtracted), cells whose gap turns
negative re-enter, and the constraints are restored after each step by multiplying ``p``
with a constant (load control: Polonsky & Keer's rescaling) or, with tilt, with a plane
``c0 + c1 (x - px) + c2 (y - py)`` fitted so that the load and both moments are exact.

Every product ``A p`` goes through ``provider.grid_operator(grid)``: for the
half-space a zero-padded real FFT convolution of size ``next_fast_len(2 ny - 1) x
next_fast_len(2 nx - 1)``. The cost is one product per iteration while the contact set
is unchanged (``A p`` then follows from ``A t``) and two when it changes; the iterations
grow slowly with the cells across the contact (Hertz at tol 1e-8: about 60 for 2a/h = 64
and 128): keep the grid tight. With penetration control the solver crops the grid itself
to the box of cells with ``z < d`` (no other cell can touch); cells with ``inf`` height
inside the box are free but still pay for the FFT.

The iteration is :func:`twoscale.pk.pk_solve` (one row, stopped by the KKT residual); this
module prepares the problem (start, cropping, precision stages) and builds the result."""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from ..indenters import Surface
from ..influence.base import InfluenceProvider
from ..influence.precorrected import cheap_products
from ..details import ReferenceDetails
from ..pk.compact import Part
from ..pk.plane import PlaneBasis
from ..pk.products import Anchored, OneRow
from ..pk.kernel import STALL_ITERATIONS, Constraint, Products, Start, Tolerance, pk_solve
from ..options import settings_from
from ..results import ContactResult
from ._problem import ContactProblem, Outcome, build_result, make_problem, trivial_result
from ._precondition import _preconditioner
from ._stop import on_window, row_stop
from ._start import cropped, initial_pressure, line_search, scaled_start, start_on


@dataclass(frozen=True)
class CGSettings:
    """How :func:`solve_cg` iterates (its keywords ``tol``, ``max_iter``, ``precision``,
    ``precondition``, ``monitor``, ``keep_conjugacy``; documented there)."""

    tol: float = 1e-8
    max_iter: int = 20_000
    precision: str = "double"
    precondition: bool = False
    monitor: Callable | None = None
    keep_conjugacy: float = 0.0
    preconditioner: Callable | None = None
    reach: np.ndarray | None = None
    plane_sums: bool = False
    rough_start: bool = False
    crop_below: float = 1.0
    half_products: bool = False
    step_model: bool = False
    precorrected: bool = False
    coarse: bool = False
    stop: Callable | None = None


def solve_cg(
    provider: InfluenceProvider,
    surface: Surface,
    *,
    penetration: float | None = None,
    total_load: float | None = None,
    tilt: bool = False,
    pivot=(0.0, 0.0),
    start: np.ndarray | None = None,
    **settings,
) -> ContactResult:
    """Full-grid contact by Polonsky & Keer's constrained conjugate gradient.

    Parameters
    ----------
    provider : InfluenceProvider
        The elastic body; only ``grid_operator`` is used (one operator per call).
    surface : Surface
        Indenter heights on the grid (mm); ``inf`` cells never touch.
    penetration : float, optional
        Rigid approach d, mm (penetration control).
    total_load : float, optional
        Total load W >= 0, N (load control). Exactly one of the two.
    tilt : bool, default False
        With ``total_load``: also solve the tilt angles (alpha about x, beta about y,
        rad) of a ball-and-socket joint at ``pivot`` so that both moments vanish.
    pivot : (float, float), default (0, 0)
        Joint position, mm.
    start : (ny, nx) array or None, default None
        Warm start, MPa, on ``surface.grid`` (negative entries and cells without material
        are ignored; it is rescaled to the load, or by a line search on the energy under
        penetration control). None: the geometric interference.
    **settings
        The iteration's settings (:class:`CGSettings`), below; an unknown one is refused
        by name.
    tol : float, default 1e-8
        Stop when the gap on the loaded cells and the interpenetration elsewhere are
        both below ``tol`` times the largest displacement (1e-8 leaves the pressure
        within about 2e-7 relative of the exact discrete solution; each factor 10
        costs about 10 more iterations).
    max_iter : int, default 20000
        Most CG iterations.
    precision : {"double", "mixed", "single-directions"}, default "double"
        ``"mixed"``: iterate first with the operator's single-precision products
        (:meth:`~twoscale.influence.base.GridOperator.single_precision`; on the half-space
        float32 FFTs, about 2.5x cheaper) to ``SINGLE_TOL`` (or ``tol`` if looser), then
        finish in double precision from that pressure (about 20 more iterations to 1e-8
        instead of 70-100 from scratch): the displacement is one double-precision product
        of that pressure plus single-precision products of the change since. The answer
        meets ``tol`` in double precision either way. ``"single-directions"``: one stage,
        the pressure, displacement and residual in double precision, the search
        directions' products in single precision while the KKT residual is above
        :data:`~twoscale.pk.products.FAST_RESIDUAL`, and the displacement after a step
        that clipped or let in a few cells corrected by the kernel's columns instead of
        a product: no restart between the stages, fewer products (warm-started
        rolling positions replayed, ``keep_conjugacy=0.005``: 0.30 against 0.49 s with
        ``"mixed"``). The reference keeps ``"double"``.
    precondition : bool, default False
        Precondition the search directions with the operator's approximate inverse
        (:meth:`~twoscale.influence.base.GridOperator.preconditioner`, on the half-space the
        inverse of the kernel wrapped on the grid's torus, restricted to the loaded cells
        and projected on the constraints): about half the iterations for one unpadded FFT
        pair more each (300 merged tips on 0.92 M cells: 61 against 117 iterations to 1e-8
        in double precision). Operators without one run unpreconditioned; the reference: off.
    monitor : callable, optional
        ``monitor(iteration, residual)`` every :data:`~twoscale.pk.kernel.MONITOR_EVERY` iterations.
    keep_conjugacy : float, default 0
        Keep the conjugate directions after a step where at most this fraction of the loaded
        cells entered (:class:`~twoscale.pk.products.Products`), in both stages of ``"mixed"``.
    preconditioner : callable, optional
        With ``precondition``: ``preconditioner(surface)`` for the surface the CG runs on
        (the given one, or its crop under penetration control) returns an object whose
        ``apply(gap, on)`` (``(ny, nx)`` arrays: the projected gap, mm, and the loaded cells)
        is an approximate inverse on the loaded cells, used instead of the operator's
        (e.g. :class:`twoscale.rolling.blocks.StoneBlocks`).
    reach : (ny, nx) bool array, optional
        The cells the iteration runs on (:class:`twoscale.pk.compact.Part`), for a caller
        that knows where the contact can be (a rolling position: the cells near the last
        one's contact); the others stay unloaded and are checked on the answer's
        displacement, and the whole grid is solved from the answer when one would touch.
        The answer meets ``tol`` on the whole grid either way. None (the reference): all.
    plane_sums : bool, default False
        With ``tilt``: the constraints' fits and restoring by the basis's separable form
        (:class:`~twoscale.pk.plane.PlaneBasis`: sums along the grid's rows, no (3, n)
        temporaries). The reference keeps the general algebra.
    rough_start : bool, default False
        ``start`` is a rough guess (e.g. the macro step's interference): under penetration
        control its line search takes the fast product if any, on the ``reach`` part when
        given (that product then the kernel's first). A start near the answer keeps the
        exact line search (a float32 scale: an iteration more).
    crop_below : float, default 1
        Penetration control crops the grid to the cells that can touch when that keeps
        fewer than this fraction of its cells (:func:`~._start.cropped`: a second operator
        and a float64 product of the whole grid).
    half_products : bool, default False
        The search directions' fast products (on the part, or every cell) in two halves where
        they have them (:class:`~twoscale.influence.on_cells.CellProduct`): the step length
        by Parseval, the transforms back only where the step uses ``A t``. The reference: off.
    step_model : bool, default False
        With ``half_products``: their step length by the preconditioner's torus where valid
        (``_PartRow.modelled``), the product only where the step uses ``A t``.
    precorrected : bool, default False
        On a small ``reach`` part, the search directions' products by a precorrected FFT
        (:func:`~twoscale.influence.precorrected.cheap_products`), re-anchored by exact
        products (:class:`~twoscale.pk.products.Cheap`). The reference: off.
    coarse : bool, default False
        With ``precondition`` (the operator's torus inverse): its coarse correction over
        squares of the grid once the contact has nearly settled
        (:class:`~twoscale.pk.coarse.SquaresCorrection`), on operators with a
        ``coarse_table`` (the half-space's offset table, also the bonded block's coarse
        kernel). The reference: off.
    stop : callable with ``cells``, optional
        The caller's own test before each step, True ends the CG unconverged (e.g. to
        enlarge the grid): :class:`~._stop.CellsStop`. The reference: none.

    Returns
    -------
    ContactResult
        ``method="reference"``, ``solver="cg"``; ``iterations={"cg": n, "products": grid products}``
        (and ``"precorrected"``: the precorrected products, when taken);
        ``residuals={"gap": history}`` (relative KKT residual per iteration); ``details`` a
        :class:`~twoscale.details.ReferenceDetails` (working grid, single-precision iterations).
    """
    t0 = time.perf_counter()
    cg = settings_from(CGSettings, settings, "solve_cg")
    tol, max_iter, precision, monitor = cg.tol, cg.max_iter, cg.precision, cg.monitor
    problem = make_problem(surface, penetration=penetration, total_load=total_load, tilt=tilt, pivot=pivot)
    trivial = trivial_result(problem, "cg", {"total": time.perf_counter() - t0})
    if trivial is not None:
        return trivial
    reach = cg.reach
    if reach is not None and np.shape(reach) != problem.grid.shape:
        raise ValueError(f"reach must be a bool array of shape {problem.grid.shape}, got shape {np.shape(reach)}")
    # the box of the cells below the approach bounds the contact only where no pressure lifts
    # the surface (a bonded block's bulge can reach beyond it)
    work = problem if getattr(provider, "surface_rises", False) else cropped(problem, cg.crop_below)
    start = start_on(start, problem, work)
    if reach is not None and work is not problem:
        reach = reach[work.grid.window_in(problem.grid)]
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {PRECISIONS}, got {precision!r}")
    op = provider.grid_operator(work.grid)
    custom = cg.preconditioner(work.surface) if cg.precondition and cg.preconditioner is not None else None
    t_op = time.perf_counter()
    it0 = products0 = 0
    hist0: list = []
    fast = None
    if precision == "single-directions":
        fast = op.single_precision()
    elif precision == "mixed" and tol < SINGLE_TOL:
        start, op, fast, (it0, products0, hist0) = _single_stage(
            work, op, provider.material.E_star, start, cg, custom, reach
        )
    offset = it0 + 1 if it0 or hist0 else 0
    stop = on_window(cg.stop, work.grid.window_in(problem.grid)) if work is not problem else cg.stop
    p, u, m, it, n_products, hist, converged, message, cheap = _iterate(
        work,
        op,
        provider.material.E_star,
        tol,
        max_iter,
        start,
        monitor=None if monitor is None else (lambda k, r: monitor(offset + k, r)),
        pc=_preconditioner(cg, custom, fast or op, getattr(op, "coarse_table", None) if cg.coarse else None),
        fast=fast,
        keep_conjugacy=cg.keep_conjugacy,
        reach=reach,
        plane_sums=cg.plane_sums,
        rough_start=cg.rough_start and not (it0 or hist0),
        halves=("modelled" if cg.step_model else "halves") if cg.half_products else None,
        precorrected=cg.precorrected,
        stop=stop,
    )
    it, n_products, hist = it + it0, n_products + products0, hist0 + hist
    p, u = p.reshape(work.grid.shape), u.reshape(work.grid.shape)
    if work is not problem:
        p = work.grid.embed_in(p, problem.grid)
        u = provider.grid_operator(problem.grid, work.grid).apply(p[work.grid.window_in(problem.grid)])
        n_products += 1
    d, tilt_angles = problem.rigid_motion(m)
    t_end = time.perf_counter()
    timings = {"operator": t_op - t0, "solve": t_end - t_op, "total": t_end - t0}
    details = ReferenceDetails("cg", working_grid=(work.grid.nx, work.grid.ny), single_precision_iterations=it0)
    return build_result(
        problem,
        "cg",
        p,
        u,
        d,
        tilt_angles,
        Outcome(converged, message, {"cg": it, "products": n_products, **cheap}, {"gap": hist}, timings, details),
    )


def _single_stage(work, op, e_star: float, start, cg: CGSettings, custom, reach):
    """``"mixed"``'s first stage: the CG in single-precision products to ``SINGLE_TOL``.
    Returns the pressure it reached (the second stage's start), the second stage's
    operator (exact products about that pressure) and fast operator, and the stage's
    iterations, products and residual history."""
    single = op.single_precision()
    p1, _, _, it0, products0, hist0, _, _, _ = _iterate(
        work,
        single,
        e_star,
        SINGLE_TOL,
        cg.max_iter,
        start,
        stall=SINGLE_STALL,
        monitor=cg.monitor,
        pc=_preconditioner(cg, custom, single),
        keep_conjugacy=cg.keep_conjugacy,
        reach=reach,
        plane_sums=cg.plane_sums,
        rough_start=cg.rough_start,
    )
    start = p1.reshape(work.grid.shape)
    fast = None
    if single is not op:  # the double-precision stage in float32 products about an exact anchor
        op, fast = Anchored(op, single, start), single
        products0 += 1
    return start, op, fast, (it0, products0, hist0)


PRECISIONS = ("double", "mixed", "single-directions")
#: KKT residual at which the single-precision stage of ``precision="mixed"`` hands over
#: (float32 products carry ~1e-7 relative rounding: near 1e-6 its steps stall). The second
#: stage costs the same per iteration (float32 products about its anchor), so it takes
#: over earlier than the 1e-6 of a float64 second stage: 200 dense spheres under load 35
#: -> 28 iterations, the 100 mm road 28 -> 27.
SINGLE_TOL = 3e-6
#: The single-precision stage stops when its residual has not halved in this many iterations.
SINGLE_STALL = 30


def _iterate(
    problem: ContactProblem,
    op,
    E_star: float,
    tol: float,
    max_iter: int,
    start=None,
    stall: int = STALL_ITERATIONS,
    monitor=None,
    pc=None,
    fast=None,
    keep_conjugacy: float = 0.0,
    reach: np.ndarray | None = None,
    plane_sums: bool = False,
    rough_start: bool = False,
    halves: str | None = None,
    precorrected: bool = False,
    stop: Callable | None = None,
):
    """The Polonsky-Keer kernel (:func:`twoscale.pk.pk_solve`) on the whole grid, one row, or
    on the candidates in ``reach`` (then checked on the whole grid, and solved on it from
    the answer when a cell off them would touch): ``(p, u, multipliers, iterations, products,
    residual history, converged, message, {"precorrected": its products} or {})``."""
    shape = problem.grid.shape
    cand = problem.candidates.ravel()
    z = np.where(cand, problem.surface.height.ravel(), 0.0)
    # a rough start's line search by the fast product, on the part if any (CGSettings)
    later = rough_start and fast is not None and reach is not None and problem.mode == "penetration"
    p = initial_pressure(problem, (fast or op) if rough_start else op, z, E_star, start, scaled=not later)
    z -= problem.penetration if problem.mode == "penetration" else 0.0
    given = op  # (the whole grid's solve after a part's: an anchor of its own)
    if fast is not None and fast is not op and not isinstance(op, Anchored):
        op = Anchored(op, fast)  # the exact products after the first in float32 about it
    exact = lambda v: op.apply(v[0])[None]  # noqa: E731
    products = Products(
        exact,
        None if fast is None else OneRow(fast),
        None if fast is None else op.columns(),
        keep_conjugacy,
    )
    part = None if reach is None else Part(np.flatnonzero(reach.ravel() & cand), shape)
    if part is not None and (part.cells.size == cand.sum() or not np.any(p[part.cells] > 0)):
        part = None  # (the part is every candidate, or carries none of the start)
    if later and part is None:
        num, den = line_search(p, fast.apply(p.reshape(shape)).ravel(), z)
        p = p * num / den
    run, dims, u0 = (z, p, cand, problem.basis(), products, pc), shape, None
    if part is not None:
        run, dims = part.inputs(*run, None if fast is None else op.columns(part.cells)), (part.cells.size,)
        run = (*run[:4], *cheap_products(run[4], given, part, pc, run[5])) if precorrected and fast else run
        if later:  # (the start's product by the cheapest: the kernel counts it as one of them)
            p_part, u0 = scaled_start(run[1], (run[4].cheap or run[4].fast)(run[1][None])[0], run[0])
            run = (run[0], p_part, *run[2:])
    if halves and fast is not None:  # the fast product in two halves where it has them (the part's, or every cell's)
        rows = run[4].fast if part is not None else OneRow(fast).on_part(None)
        run = (*run[:4], replace(run[4], halves=getattr(rows, halves, None)), run[5])
    out = pk_solve(
        run[4],
        run[0].reshape(1, *dims),
        run[1].reshape(1, *dims) if u0 is None else Start(run[1].reshape(1, *dims), u0.reshape(1, *dims)),
        None if run[2].all() else run[2].reshape(1, *dims),
        Tolerance(residual=tol, max_iter=max_iter, stall=stall, stop=None if stop is None else row_stop(stop, part)),
        constraint=Constraint(
            run[3],
            problem.target()[None],
            PlaneBasis.on(problem.grid, problem.pivot)
            if plane_sums and problem.mode == "tilt" and part is None
            else None,
        ),
        precondition=run[5],
        monitor=monitor,
    )
    p, u = out.pressure[0].ravel(), out.displacement[0].ravel()
    counts = (int(out.iterations[0]), out.products, list(out.history))
    cheap = getattr(run[4].cheap, "__self__", None)  # (the precorrected product, if taken: its count)
    cheap = {} if cheap is None else {"precorrected": cheap.products}
    if part is not None:
        p, u, touching = part.answer(out, exact, z, cand, problem.basis(), tol)
        if touching:  # a cell off the part would touch: the whole grid from this answer
            whole = _iterate(
                problem,
                given,
                E_star,
                tol,
                max_iter,
                p.reshape(shape),
                stall,
                monitor,
                pc,
                fast,
                keep_conjugacy,
                plane_sums=plane_sums,
                stop=stop,
            )
            return (*whole[:3], whole[3] + counts[0], whole[4] + counts[1], counts[2] + whole[5], *whole[6:8], cheap)
    return (p, u, out.multipliers[0], *counts, bool(out.converged[0]), out.message(0), cheap)
