"""Small helpers shared by the benchmark scripts: timing and table printing."""

from __future__ import annotations

import os
import time
from typing import Callable

# Single-threaded comparisons unless the caller asks otherwise: the machines these run on
# are shared, and every code then gets the same single core.
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")


#: The finite block's modules, which both solvers import on their first block scene (the
#: provider by ``twoscale.influence.registry``, its mesh's scikit-fem): 143 modules compiled
#: in the timed call, 0.07-0.08 s of CPU of seed 0's #45 on each side.
BODY_MODULES = ("twoscale.influence.registry", "fem_influence", "meshes.block", "skfem")
#: The solvers' own modules (the two-scale path's macro step and laws, the reference's
#: optimiser: 40-50 ms on one tip) and the body's, imported before a timed solve.
SOLVER_MODULES = (
    "twoscale",
    "twoscale.micro.driver",
    "twoscale.reference.on_scene",
    "twoscale.full_grid",
    "twoscale.driver",
    "scipy.interpolate",
    "scipy.optimize",
    *BODY_MODULES,
)


def import_solver_modules() -> None:
    """:data:`SOLVER_MODULES` imported, as every benchmark does before it starts a solve's
    clock: without a bytecode cache their compilation in the timed call adds 0.2-0.35 s of
    CPU to a road's default and reference alike (pulling their ratio towards 1). A module a
    tree keeps elsewhere, or scikit-fem where it is not installed, is skipped."""
    import importlib

    for name in SOLVER_MODULES:
        try:
            importlib.import_module(name)
        except ImportError:
            pass


def best_time(fn: Callable[[], object], repeat: int = 3, budget_s: float = 5.0) -> tuple[object, float]:
    """Run ``fn`` up to ``repeat`` times; return its last result and the best wall time, s.

    The minimum is the least disturbed run on a shared machine (other processes only
    ever add time). Runs stop early once ``budget_s`` seconds have been spent, so slow
    codes (the dense solver) run once."""
    best, result, spent = float("inf"), None, 0.0
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        result = fn()
        dt = time.perf_counter() - t0
        best, spent = min(best, dt), spent + dt
        if spent >= budget_s:
            break
    return result, best


def progress(total: int, label: str, quiet: bool = False):
    """A progress bar on stderr for a benchmark's loop (drawn on a terminal after 2 s;
    nothing with ``quiet``): :class:`twoscale.progress.Progress`."""
    from twoscale.progress import Progress

    return Progress(total, label=label, quiet=quiet)


def add_quiet(parser) -> None:
    """The ``--quiet`` option every benchmark takes (no progress bar)."""
    parser.add_argument("--quiet", action="store_true", help="no progress bar on stderr")


def print_table(rows: list[dict], columns: list[tuple[str, str, str]]) -> None:
    """Print ``rows`` as a fixed-width table; columns are (key, header, format)."""
    widths = [max(len(h), 10) for _, h, _ in columns]
    print("  ".join(h.rjust(w) for (_, h, _), w in zip(columns, widths)))
    for row in rows:
        cells = []
        for (key, _, fmt), w in zip(columns, widths):
            v = row.get(key)
            cells.append(("-" if v is None else format(v, fmt)).rjust(w))
        print("  ".join(cells))
