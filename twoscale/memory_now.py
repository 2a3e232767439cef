"""Memory available now, and whether the union CG a far-field attempt falls back to fits in it.

The estimate made before a solve (:mod:`twoscale.resources`) counts the routes that run.
One fallback needs far more than the route before it and has not been seen to run on the
sweep's scenes: the union CG over the patches' bounding box after a far-field two-level
attempt that did not converge, on patches covering at least ``UNION_MIN_COVERAGE`` of the
box (:func:`twoscale.micro.driver._order`; the 88 such attempts of the sweep records, on
75 scenes of seeds 1 and 5-9, all converged). Counted up front it put the estimate at up
to 9x the measured peak (seed 8's #74: 3.5 GB counted, 0.41 GB held; 0.45 GB counted
without it) and would refuse scenes that fit. It is checked instead when it is about to
start (:func:`union_box_fits`), against the memory available then: where the box does not
fit, block Gauss-Seidel with the attempt's far field runs (the fallback where the patches
cover less of their box), whose memory is the attempt's. Bytes.
"""

from __future__ import annotations

import math
import os

from .memory_costs import DEFAULT_FRACTION, FFT_WORK_BYTES_PER_CELL, GRID_BYTES_PER_CELL

#: What the union CG allocates over :func:`union_box_bytes`, at the most: 240-420 bytes a
#: box cell on the sweep's union CG runs with their patches (fresh-process peaks over the
#: interpreter's), 1.06-1.20x on lattices of 144-576 spheres at 0.33-0.37 M cells (its run's
#: traced peak over what was live at its start, the coarse correction built on one).
UNION_BOX_SPREAD = 1.4


def available_memory() -> float:
    """Memory available to a new allocation, bytes: ``MemAvailable`` of /proc/meminfo, else
    the free physical pages (``os.sysconf``); ``inf`` when neither can be read."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0  # kB
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES")) * float(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return math.inf


def union_box_bytes(cells: int) -> float:
    """What the union CG allocates for a box of ``cells`` cells, bytes: its grid's arrays
    and FFT work (``GRID_BYTES_PER_CELL + FFT_WORK_BYTES_PER_CELL``, 300 a cell; measured
    240-420 on the sweep's union CG runs, the patches included)."""
    return (GRID_BYTES_PER_CELL + FFT_WORK_BYTES_PER_CELL) * float(cells)


def union_box_fits(cells: int, available: float | None = None) -> bool:
    """Whether the union CG on a box of ``cells`` cells, :func:`union_box_bytes` times
    :data:`UNION_BOX_SPREAD`, fits in ``DEFAULT_FRACTION`` (80 %) of the memory ``available``
    (bytes; None: :func:`available_memory`, read now, after the attempt before it gave its
    memory back), as a solve's estimate is checked before it starts."""
    room = available_memory() if available is None else float(available)
    return UNION_BOX_SPREAD * union_box_bytes(cells) <= DEFAULT_FRACTION * room
