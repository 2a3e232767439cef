"""The BLAS and OpenMP threads of a solve: one each, unless the user set a count.

The solvers' work is FFTs (single-threaded) and array passes; the BLAS calls are dense
blocks of a few hundred cells, factorisations of at most a few thousand, and reductions,
too small to gain from threads. OpenBLAS's default (a thread per core) then costs CPU
without saving time: its idle threads spin beside the FFTs between calls, and on a loaded
machine a small factorisation waits for threads that are not scheduled. Measured on a
shared 2-core machine (load 4-8; CPU seconds, default threads against
``OPENBLAS_NUM_THREADS=1``): ``twoscale solve`` of the rolling example
(``examples/rolling/tyre.toml``) 8.0-8.1 s against 3.8-3.9 s before its long dot product
left BLAS, the paper's S2 scene 2.6-2.8 s against 1.95 s (wall 6.5-7.4 s against 5.2 s);
``twoscale.solve`` from Python of two paraboloids whose default route is the dense solve
on 841 cells (load 3.7, median of 5): 0.163 s of CPU and 0.285 s of wall against 0.0059 s
and 0.0102 s.

So the command line and the Python entry points (:func:`twoscale.solve`,
:meth:`twoscale.ContactSolver.solve`, :func:`twoscale.rolling.roll`) run their work with one thread each, and give the
user's counts back when they return. A count the user set in the environment
(:data:`USER_THREAD_SETTINGS`) leaves every count alone: to run a solve on more threads, set
one (e.g. ``OPENBLAS_NUM_THREADS=2``, before or after numpy is imported) and choose the counts
with ``threadpoolctl.threadpool_limits`` around the call. The
limit is set at run time (:mod:`threadpoolctl`: the libraries are loaded before a solve
starts); finding them costs ~1.4 ms a call, which a :class:`~threadpoolctl.ThreadpoolController`
kept by a solver object saves (0.01 ms a call).
"""

from __future__ import annotations

import contextlib
import os
from typing import Any, Mapping

#: Any of these in the environment: the user chose the thread counts, and they are kept.
USER_THREAD_SETTINGS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS")


def user_set_threads(environ: Mapping[str, str] = os.environ) -> bool:
    """Whether one of :data:`USER_THREAD_SETTINGS` is set in ``environ``."""
    return any(name in environ for name in USER_THREAD_SETTINGS)


def thread_controller(environ: Mapping[str, str] = os.environ) -> Any:
    """A :class:`threadpoolctl.ThreadpoolController` of the libraries loaded now, for a
    solver object to keep (None when the user set the counts)."""
    if user_set_threads(environ):
        return None
    from threadpoolctl import ThreadpoolController

    return ThreadpoolController()


def single_threads(environ: Mapping[str, str] = os.environ, controller: Any = None):
    """A context in which the BLAS and OpenMP libraries run one thread each, unless one of
    :data:`USER_THREAD_SETTINGS` is set in ``environ`` (then nothing changes).
    ``controller``: a kept :func:`thread_controller` (the libraries are not looked up again)."""
    if user_set_threads(environ):
        return contextlib.nullcontext()
    if controller is not None:
        return controller.limit(limits=1)
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1)
