"""A solve's work without the garbage collector's walks over the process's old objects.

CPython's cyclic collector walks every tracked object of the process at a full pass (its
oldest generation). A solve makes tracked objects (patches, laws, results) and a rolling run
a few thousand a position, enough for full passes that walk everything the process holds:
the imported libraries (~60,000 objects), a road's stones. Measured: the 1 m rolling
benchmark's tyre (``benchmarks/rolling_tail.py``, host load ~10) paid 8 full passes over
1,000 positions at 56-112 ms of CPU each, a third to a half of a position (the run's
slowest positions); a static solve of 8,807 tips (seed 6 #147 of the scene-space sweep) or
a bonded block's 1,000 (#139) one pass of ~70 ms in a fresh process, 2 % of the solve
(`gc.callbacks`, counted in the solve's process).

:func:`frozen_objects` moves the objects alive when the work starts to the collector's
permanent generation (:func:`gc.freeze`), which its passes skip, and gives them back when it
ends (:func:`gc.unfreeze`): the work's own objects are collected as before, the old ones
cannot be garbage of its making. A caller that froze objects itself, or that turned the
collector off, is left as it is.
"""

from __future__ import annotations

import contextlib
import gc


@contextlib.contextmanager
def frozen_objects():
    """The objects alive at entry left out of the collector's passes until exit (module
    docstring); nothing done when some are frozen already or the collector is off."""
    if gc.get_freeze_count() or not gc.isenabled():
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()
