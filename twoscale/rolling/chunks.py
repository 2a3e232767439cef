"""A long elastic run split into chunks of consecutive positions, rolled in parallel by Dask.

An elastic body has no memory: every position is a static solve, so chunks are
independent. Each chunk is a run of its own (the same scene with the chunk's first and last
shift), warm-started within the chunk; its first position starts cold. The answers are the
sequential run's to the solver's tolerance (only the starts differ); times stay those of
the whole run (measured from its first position).

A viscoelastic body needs its history: its chunks would have to overlap by a warm-up length
over which the memory decays, which this module does not do (it refuses such a scene).
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..errors import SceneError
from .result import RollingResult, StoneSignals
from .run import RollingOptions, roll


def chunk_bounds(n: int, chunks: int) -> list[tuple[int, int]]:
    """``chunks`` contiguous ranges ``[i0, i1)`` of ``n`` positions, as equal as they come."""
    if isinstance(chunks, bool) or not isinstance(chunks, int) or chunks < 1:
        raise ValueError(f"chunks must be an integer >= 1, got {chunks!r}")
    edges = np.linspace(0, n, min(chunks, n) + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def _chunk_scene(scene, shifts: np.ndarray, i0: int, i1: int):
    spec = dataclasses.replace(scene.rolling, start=float(shifts[i0]), end=float(shifts[i1 - 1]))
    return dataclasses.replace(scene, rolling=spec)


def _roll_chunk(scene, options: RollingOptions) -> RollingResult:
    return roll(scene, options=options)


def roll_chunks(scene, *, chunks: int = 2, options: RollingOptions | None = None,
                scheduler: str = "processes") -> RollingResult:
    """Roll ``scene`` (elastic, with ``rolling``) in ``chunks`` chunks of consecutive positions
    on Dask (``dask.compute`` with ``scheduler``: "processes", "threads", "synchronous", or
    a distributed client's address through Dask's configuration); one :class:`RollingResult`
    for the whole run."""
    import dask
    from .track import prepare

    if scene.material.viscoelastic:
        raise SceneError("material.prony: a viscoelastic run cannot be split into independent chunks "
                         "(its memory crosses them); roll it in one piece")
    t0 = time.perf_counter()
    options = options or RollingOptions()
    track = prepare(scene, h=options.h)
    shifts = track.shifts
    scenes = [_chunk_scene(track.scene, shifts, a, b) for a, b in chunk_bounds(len(shifts), chunks)]
    parts = dask.compute(*[dask.delayed(_roll_chunk)(s, options) for s in scenes], scheduler=scheduler)
    return join(list(parts), track, time.perf_counter() - t0)


def join(parts: list, track, seconds: float) -> RollingResult:
    """The chunks' results as one run (times from the first shift of the whole run)."""
    offsets = np.cumsum([0] + [len(p.shifts) for p in parts])
    cat = (lambda name: np.concatenate([getattr(p, name) for p in parts]))
    stones = StoneSignals(np.concatenate([p.asperities.position + o for p, o in zip(parts, offsets)]),
                          cat_stones(parts, "stone"), cat_stones(parts, "force"), cat_stones(parts, "contact_area"))
    shifts = cat("shifts")
    h = parts[0].h
    lo = min(int(round(p.line_x[0] / h)) for p in parts if p.line_x.size) if any(p.line_x.size for p in parts) else 0
    hi = max(int(round(p.line_x[-1] / h)) + 1 for p in parts if p.line_x.size) if any(p.line_x.size for p in parts) else 0
    line = np.zeros((len(shifts), hi - lo))
    for p, o in zip(parts, offsets):
        if p.line_x.size:
            i = int(round(p.line_x[0] / h)) - lo
            line[o:o + len(p.shifts), i:i + p.line_x.size] = p.line_load
    first = parts[0]
    return RollingResult(
        spec=track.spec, method=first.method, control=first.control, h=h,
        times=(shifts - shifts[0]) / track.spec.speed_mm_s, shifts=shifts, total_load=cat("total_load"),
        penetration=cat("penetration"), contact_area=cat("contact_area"), drag=cat("drag"),
        converged=cat("converged"), seconds=cat("seconds"), stones=cat("stones"), iterations=cat("iterations"),
        messages=tuple(m for p in parts for m in p.messages), asperities=stones,
        line_x=(lo + np.arange(hi - lo)) * h, line_load=line,
        timings_s={"chunks": len(parts), "total": seconds,
                   "positions": float(sum(p.timings_s.get("positions", 0.0) for p in parts))},
        body=first.body)


def cat_stones(parts: list, name: str) -> np.ndarray:
    return np.concatenate([getattr(p.asperities, name) for p in parts])
