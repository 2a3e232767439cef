"""Memory a failed micro attempt freed, given back to the system before the next one.

glibc keeps the small and medium blocks a process frees in its heap for reuse, and a
strategy that follows a failed one (the union CG after a far-field two-level trial) asks for
arrays of other sizes, so what the first freed stays resident beside them: 1,000
paraboloids, two-level trial stopped after one sweep, 1,119 MB resident before the union CG
with 407 MB of it in live arrays, and a peak of 2,271 MB against 1,384 MB for the union CG
alone; with the heap trimmed there, 508 MB resident and a peak of 1,758 MB. The memory
estimate (:mod:`twoscale.memory_parts`) counts the fallback with this trim made.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys


def release_freed_memory() -> bool:
    """``malloc_trim(0)``: the heap's free pages back to the system; True when made (glibc
    on Linux), False elsewhere (nothing to do or no such call)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        trim = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
    except (OSError, AttributeError):  # not glibc (musl has no malloc_trim)
        return False
    trim.argtypes, trim.restype = (ctypes.c_size_t,), ctypes.c_int
    trim(0)
    return True
