"""The BLAS and OpenMP threads of the command line: one each, unless the user set a count.

The solvers' work is FFTs (single-threaded) and array passes; the BLAS calls are dense
blocks of a few hundred cells and reductions, too small to gain from threads. OpenBLAS's
default (a thread per core) then costs CPU without saving time: its idle threads spin
beside the FFTs between calls. Measured with ``twoscale solve`` on a shared 2-core machine
(load 4-8; user CPU seconds, default threads against ``OPENBLAS_NUM_THREADS=1``): the
rolling example (``examples/rolling/tyre.toml``) 8.0-8.1 s against 3.8-3.9 s before its
long dot product left BLAS, the paper's S2 scene 2.6-2.8 s against 1.95 s (wall 6.5-7.4 s
against 5.2 s). The limit is set at run time (:mod:`threadpoolctl`: the libraries are
loaded before the command line parses its arguments); a count the user set in the
environment (:data:`USER_THREAD_SETTINGS`) is left alone.
"""

from __future__ import annotations

import contextlib
import os
from typing import Mapping

#: Any of these in the environment: the user chose the thread counts, and they are kept.
USER_THREAD_SETTINGS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS")


def command_threads(environ: Mapping[str, str] = os.environ):
    """A context in which the BLAS and OpenMP libraries run one thread each, unless one of
    :data:`USER_THREAD_SETTINGS` is set in ``environ`` (then nothing changes)."""
    if any(name in environ for name in USER_THREAD_SETTINGS):
        return contextlib.nullcontext()
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1)
