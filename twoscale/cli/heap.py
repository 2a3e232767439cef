"""The C heap of a rolling run's process: glibc keeps the arrays it frees for reuse.

A rolling position allocates and frees arrays of 0.2-6 MB dozens of times (the window's
products, the kernel's passes, the stones' blocks). glibc serves each from its own
``mmap`` (above a threshold of 128 kB that only grows when such a block is freed) or trims
the heap top back to the system, and the next array faults its pages in again: 3,000-4,900
minor page faults a position on the 1 m benchmark's tyre, 9-13 ms of system CPU of
~175 ms. With both thresholds raised (:func:`keep_heap`) the faults fall to 60-90 a
position. The process then keeps up to :data:`HEAP_KEEP_BYTES` of freed memory; its peak
is unchanged. Applied by ``twoscale solve`` on a rolling scene and by the rolling
benchmark, not by the library (the setting is the whole process's); a user's own
``MALLOC_MMAP_THRESHOLD_`` or ``MALLOC_TRIM_THRESHOLD_`` in the environment is kept.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
from typing import Mapping

#: Freed memory glibc keeps (trim threshold) and the size up to which arrays come from its
#: heap instead of an ``mmap`` of their own (mmap threshold), bytes.
HEAP_KEEP_BYTES = 256 * 2**20
#: ``mallopt`` parameters (glibc's malloc.h).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: Any of these in the environment: the user chose the heap's settings.
USER_HEAP_SETTINGS = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_")


def keep_heap(environ: Mapping[str, str] = os.environ) -> bool:
    """Raise glibc's trim and mmap thresholds to :data:`HEAP_KEEP_BYTES` (module
    docstring); True when set, False on another C library or when ``environ`` holds one of
    :data:`USER_HEAP_SETTINGS`."""
    if not sys.platform.startswith("linux") or any(name in environ for name in USER_HEAP_SETTINGS):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc (musl has no mallopt)
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return bool(mallopt(_M_TRIM_THRESHOLD, HEAP_KEEP_BYTES) and mallopt(_M_MMAP_THRESHOLD, HEAP_KEEP_BYTES))
