"""A long run split into chunks of consecutive positions, rolled in parallel by Dask.

**Elastic.** A body without memory makes every position a static solve, so chunks are
independent. Each chunk is a run of its own (the same scene with the chunk's first and last
shift), warm-started within the chunk; its first position starts cold. The answers are the
sequential run's to the solver's tolerance (only the starts differ).

**Viscoelastic.** A position depends on the history, so each chunk starts earlier, by a
*warm-up* of ``w`` positions rolled and then dropped: the chunk's body starts at rest
(the ramp of :func:`twoscale.viscoelastic.moving.solve_moving`) where the sequential run's
body carries the memory of everything before. With the creep compliance
``J(t) = J_inf - sum_j c_j exp(-t / lambda_j)`` (Kelvin-Voigt units of compliance ``c_j``
and retardation time ``lambda_j``), unit ``j``'s strain in the sequential run at the
warm-up's start ``t_a`` (s from the run's first position) is at most ``c_j p (1 -
exp(-t_a / lambda_j))`` for a pressure ``p`` (the creep it can have built since the run
began); from there both runs see the same road, and the difference decays as
``exp(-T_w / lambda_j)`` over the warm-up's duration ``T_w``. The warm-up is the fewest
positions for which

    B = sum_j (c_j / J(0)) (1 - exp(-t_a / lambda_j)) exp(-T_w / lambda_j) <= warmup_tol,

the units' strains left from the chunk's different start, relative to the glassy strain
``J(0) p`` (:func:`warmup_bound`); a chunk whose bound cannot be met starts at the run's
first position (it is then the sequential run's own start). Branches far slower than the
run build almost no strain (``t_a / lambda_j`` small); those of about the run's time set
the warm-up, up to the whole run before the chunk (no speed-up, but the right answer).
Times, stone numbers and the energies (dissipated per step, stored) are the whole run's.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import time
import uuid
from collections.abc import Iterator

import numpy as np

from .result import SIGNALS, RollingResult, StoneSignals
from .run import RollingOptions, roll

#: The environment variables that set a worker process's BLAS/OpenMP threads.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
#: Default bound on the memory a viscoelastic chunk's start leaves after its warm-up
#: (relative to the glassy strain, module docstring).
WARMUP_TOL = 1e-4


def chunk_bounds(n: int, chunks: int) -> list[tuple[int, int]]:
    """``chunks`` contiguous ranges ``[i0, i1)`` of ``n`` positions, as equal as they come."""
    if isinstance(chunks, bool) or not isinstance(chunks, int) or chunks < 1:
        raise ValueError(f"chunks must be an integer >= 1, got {chunks!r}")
    edges = np.linspace(0, n, min(chunks, n) + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def warmup_bound(material, t_a: float, T_w: float) -> float:
    """``B`` of the module docstring: the Kelvin-Voigt strains a chunk's start at rest leaves
    after a warm-up of ``T_w`` s begun ``t_a`` s after the run's first position, relative to
    the glassy strain (0 for an elastic material)."""
    if not material.viscoelastic:
        return 0.0
    from ..viscoelastic.prony import creep_compliance

    J = creep_compliance(material)
    lam, c = np.asarray(J.lambdas), np.asarray(J.c)
    return float(np.sum(c / J.J0 * -np.expm1(-t_a / lam) * np.exp(-T_w / lam)))


def warmup_positions(material, times: np.ndarray, i0: int, tol: float = WARMUP_TOL) -> int:
    """The fewest positions before ``i0`` (times ``times``, s) a chunk starting there must
    roll and drop for :func:`warmup_bound` <= ``tol``; ``i0`` (from the run's start) when
    none is enough."""
    for w in range(i0 + 1):
        if w == i0 or warmup_bound(material, float(times[i0 - w] - times[0]), float(times[i0] - times[i0 - w])) <= tol:
            return w
    return i0


def _roll_chunk(scene, start: float, end: float, options: RollingOptions, warmup: int) -> RollingResult:
    """One chunk, on a worker: ``scene`` rolled from shift ``start`` to ``end`` (mm), its first
    ``warmup`` positions dropped."""
    spec = dataclasses.replace(scene.rolling, start=start, end=end)
    return trim(roll(dataclasses.replace(scene, rolling=spec), options=options), warmup)


def plan(track, chunks: int, warmup_tol: float = WARMUP_TOL) -> list[tuple[int, int, int]]:
    """The chunks of ``track``'s run: ``(i0, i1, w)``, positions ``[i0, i1)`` rolled after a
    warm-up of ``w`` positions (0 on an elastic body)."""
    material = track.scene.material
    return [
        (a, b, warmup_positions(material, track.times, a, warmup_tol) if material.viscoelastic else 0)
        for a, b in chunk_bounds(len(track.shifts), chunks)
    ]


def roll_chunks(
    scene,
    *,
    chunks: int = 2,
    options: RollingOptions | None = None,
    scheduler="processes",
    warmup_tol: float = WARMUP_TOL,
) -> RollingResult:
    """Roll ``scene`` (with ``rolling``) in ``chunks`` chunks of consecutive positions on Dask
    (``dask.compute`` with ``scheduler``: "processes", "threads", "synchronous", or a
    ``distributed.Client``); one :class:`RollingResult` for the whole run. A viscoelastic
    body's chunks start ``warmup_tol``'s warm-up earlier (module docstring); the positions
    rolled for the warm-ups and dropped are counted in ``timings_s["warmup_positions"]``."""
    import dask
    from .track import prepare

    t0 = time.perf_counter()
    options = options or RollingOptions()
    track = prepare(scene, h=options.h)
    shifts = track.shifts
    parts_plan = plan(track, chunks, warmup_tol)
    scene_key = _shared(track.scene, scheduler)
    jobs = [
        dask.delayed(_roll_chunk)(scene_key, float(shifts[a - w]), float(shifts[b - 1]), options, w)
        for a, b, w in parts_plan
    ]
    with _one_thread_each(scheduler):
        parts = dask.compute(*jobs, scheduler=scheduler)
    out = join(list(parts), track, time.perf_counter() - t0)
    timings = dict(out.timings_s, warmup_positions=float(sum(w for _, _, w in parts_plan)), warmup_tol=warmup_tol)
    return dataclasses.replace(out, timings_s=timings)


@contextlib.contextmanager
def _one_thread_each(scheduler) -> Iterator[None]:
    """Worker processes that Dask spawns for this run (``scheduler="processes"``) with one
    BLAS/OpenMP thread each unless the caller set the counts: they read them from the
    environment as they start, and two workers on two cores each running OpenBLAS's default
    threads spent 2.5 times the CPU of one thread (measured: 9 positions of the example, 2.4-2.5
    s against 1.0 s, the threads waiting in turn on a loaded machine). A ``distributed``
    cluster's nannies set them to 1 themselves."""
    if scheduler != "processes":
        yield
        return
    saved = {k: os.environ.get(k) for k in THREAD_VARIABLES}
    for k in THREAD_VARIABLES:
        os.environ.setdefault(k, "1")
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)


def _shared(scene, scheduler):
    """The scene as every chunk reads it: the strip and its stones (about 10 MB on the
    example) sent once, not pickled into each chunk's task. On a ``distributed.Client`` it is
    scattered to every worker: a key held by one worker draws every chunk to that worker (the
    scheduler prefers the data's holder; measured: two chunks on one of two workers)."""
    import dask

    if hasattr(scheduler, "scatter"):
        return scheduler.scatter(scene, broadcast=True, hash=False)
    return dask.delayed(scene, name=f"twoscale-rolling-scene-{uuid.uuid4().hex}", traverse=False)


def trim(result: RollingResult, first: int) -> RollingResult:
    """``result`` without its first ``first`` positions (a chunk's warm-up)."""
    if first == 0:
        return result
    keep = slice(first, None)
    a = result.asperities
    rows = a.position >= first
    per = {name: getattr(result, name)[keep] for name in SIGNALS}
    energy = {name: getattr(result, name)[keep] for name in ("dissipated", "stored") if getattr(result, name).size}
    line = result.line_load[keep] if result.line_load.shape[0] else result.line_load
    return dataclasses.replace(
        result,
        **per,
        **energy,
        messages=result.messages[first:],
        line_load=line,
        asperities=StoneSignals(a.position[rows] - first, a.stone[rows], a.force[rows], a.contact_area[rows]),
    )


def join(parts: list, track, seconds: float) -> RollingResult:
    """The chunks' results as one run (times from the first shift of the whole run)."""
    offsets = np.cumsum([0] + [len(p.shifts) for p in parts])
    cat = lambda name: np.concatenate([getattr(p, name) for p in parts])
    stones = StoneSignals(
        np.concatenate([p.asperities.position + o for p, o in zip(parts, offsets)]),
        cat_stones(parts, "stone"),
        cat_stones(parts, "force"),
        cat_stones(parts, "contact_area"),
    )
    shifts = cat("shifts")
    line_x, line = _join_lines(parts, offsets, len(shifts))
    first = parts[0]
    energy = {name: cat(name) for name in ("dissipated", "stored") if all(getattr(p, name).size for p in parts)}
    return RollingResult(
        spec=track.spec,
        method=first.method,
        control=first.control,
        h=first.h,
        times=(shifts - shifts[0]) / track.spec.speed_mm_s,
        shifts=shifts,
        total_load=cat("total_load"),
        penetration=cat("penetration"),
        contact_area=cat("contact_area"),
        drag=cat("drag"),
        converged=cat("converged"),
        seconds=cat("seconds"),
        cpu_seconds=cat("cpu_seconds"),
        stones=cat("stones"),
        iterations=cat("iterations"),
        messages=tuple(m for p in parts for m in p.messages),
        asperities=stones,
        line_x=line_x,
        line_load=line,
        **energy,
        timings_s={
            "chunks": len(parts),
            "segment": track.segment_seconds,
            "total": seconds,
            "positions": float(sum(p.timings_s.get("positions", 0.0) for p in parts)),
        },
        body=first.body,
        step_check=track.step_check,
    )


def _join_lines(parts: list, offsets: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The chunks' line loads on one lattice of columns (empty when no chunk has one)."""
    used = [p for p in parts if p.line_x.size]
    if not used:
        return np.zeros(0), np.zeros((0, 0))
    h = parts[0].h
    lo = min(int(round(p.line_x[0] / h)) for p in used)
    hi = max(int(round(p.line_x[-1] / h)) + 1 for p in used)
    line = np.zeros((n, hi - lo))
    for p, o in zip(parts, offsets):
        if p.line_x.size:
            i = int(round(p.line_x[0] / h)) - lo
            line[o : o + len(p.shifts), i : i + p.line_x.size] = p.line_load
    return (lo + np.arange(hi - lo)) * h, line


def cat_stones(parts: list, name: str) -> np.ndarray:
    return np.concatenate([getattr(p.asperities, name) for p in parts])
