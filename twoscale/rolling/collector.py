"""A rolling run's positions without the garbage collector's walks over the process's old
objects.

CPython's cyclic collector walks every tracked object of the process at a full pass (its
oldest generation). A position makes a few thousand short-lived tracked objects (the
stones within reach, the results), enough for a full pass about every 130 positions; each
walks what the process holds: the imported libraries and the road's stones, ~60,000 objects
for a 100 mm strip, more for a longer one. Measured on the 1 m benchmark's tyre
(``benchmarks/rolling_tail.py``, host load ~10): 8 full passes over 1,000 positions at
56-112 ms of CPU each, a third to a half of a position (the run's slowest positions), and
45 ms for one pass over a 100 mm section's process.

:func:`frozen_objects` moves the objects alive when a run starts to the collector's permanent
generation (:func:`gc.freeze`), which its passes skip, and gives them back when the run ends
(:func:`gc.unfreeze`): the run's own objects are collected as before, the old ones cannot
be garbage of the run's making. A caller that froze objects itself, or that turned the
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
