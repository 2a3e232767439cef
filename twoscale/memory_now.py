"""Memory available now, and whether the union CG over the patches' box fits in it.

The estimate made before a solve (:mod:`twoscale.resources`) counts what surely runs. The
union CG over the patches' bounding box needs far more than the block iterations where
the patches cover little of it, and which of them runs is known only after the macro step:

* the policy's choice where the estimate's band of patch sizes has it choose either
  (:func:`twoscale.memory_choice.possible_routes`): counted up front, the box put seed 7's
  #96 and seed 8's #129 at 0.21-0.33 of their measured peaks (a far-field block iteration
  ran); the estimate counts the block iteration and says what the union CG would need;
* the union CG after a far-field two-level attempt that did not converge, on patches
  covering at least ``UNION_MIN_COVERAGE`` of the box (:func:`twoscale.micro.driver._order`;
  the 88 such attempts of the sweep records, on 75 scenes of seeds 1 and 5-9, all
  converged): counted up front, seed 8's #74 read 3.5 GB for 0.41 GB held.

Both are checked when the union CG is about to be chosen or started (:func:`union_box_fits`,
:func:`box_check`), against the memory available then: where the box does not fit, a block
iteration runs instead (whose memory the estimate counted), or, where none can, the solve
stops with a one-line :class:`~twoscale.errors.SceneError` naming a cell size at which the
box fits. Bytes, mm.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

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


@dataclass(frozen=True)
class BoxCheck:
    """The union CG's box against the memory available when the policy takes it.

    Attributes
    ----------
    cells : int
        The box's cells.
    h : float
        Cell size, mm.
    need : float
        What the union CG may allocate there, bytes (``UNION_BOX_SPREAD`` times
        :func:`union_box_bytes`).
    available : float
        The memory available then, bytes (80 % of it may be used).
    fit_h : float
        A cell size at which the same box fits (mm; ``h`` where it fits, ``inf`` where no
        cell size does: under a cell's bytes are available).
    """

    cells: int
    h: float
    need: float
    available: float
    fit_h: float

    @property
    def fits(self) -> bool:
        """Whether ``need`` is within ``DEFAULT_FRACTION`` (80 %) of ``available``."""
        return self.need <= DEFAULT_FRACTION * self.available

    @property
    def text(self) -> str:
        """One clause: the box, what it may need and what is available."""
        return (
            f"the union CG on the patches' box ({self.cells:,} cells at h = {self.h:g} mm) may need "
            f"{self.need / 1e9:.2g} GB, over 80 % of the memory available now ({self.available / 1e9:.2g} GB)"
        )

    @property
    def advice(self) -> str:
        """What to change: the cell size at which the box fits."""
        if math.isinf(self.fit_h):
            return "no cell size makes it fit: too little memory is available"
        return f"try h = {self.fit_h:g} mm or larger"


def box_check(nx: int, ny: int, h: float, available: float | None = None) -> BoxCheck:
    """The union CG on a box of ``nx`` x ``ny`` cells of side ``h`` (mm) against the memory
    ``available`` (bytes; None: :func:`available_memory`, read now), with the cell size at
    which the same region fits by the same count (the box's sides over the new cell size)."""
    room = available_memory() if available is None else float(available)
    cells = int(nx) * int(ny)
    need = UNION_BOX_SPREAD * union_box_bytes(cells)
    fit = float(h)
    if need > DEFAULT_FRACTION * room:
        fit = _fitting_h(int(nx), int(ny), float(h), DEFAULT_FRACTION * room)
    return BoxCheck(cells, float(h), need, room, fit)


def _fitting_h(nx: int, ny: int, h: float, room: float) -> float:
    """The smallest of a few cell sizes, two significant digits rounded up, at which the
    box of ``nx`` x ``ny`` cells of side ``h`` (mm) holds at most ``room`` bytes."""
    width, length = (nx - 1) * h, (ny - 1) * h
    cells = room / (UNION_BOX_SPREAD * union_box_bytes(1))
    if cells < 1.0:
        return math.inf
    trial = h * math.sqrt(nx * ny / cells)
    for _ in range(60):  # 10 % steps: 60 of them cover 300x
        trial = _round_up(trial)
        if (math.floor(width / trial) + 1.0) * (math.floor(length / trial) + 1.0) <= cells:
            return trial
        trial *= 1.1
    return math.inf


def _round_up(x: float) -> float:
    """``x`` rounded up to two significant digits."""
    step = 10.0 ** (math.floor(math.log10(x)) - 1)
    return float(f"{math.ceil(x / step - 1e-9) * step:.3g}")
