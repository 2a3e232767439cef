"""Memory a failed micro attempt freed, given back before the next (twoscale.micro.release)."""

from __future__ import annotations

import sys

import pytest

from twoscale.micro.release import release_freed_memory


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc_trim")
def test_the_heap_is_trimmed_on_linux():
    import numpy as np

    def resident() -> int:
        with open("/proc/self/status") as fh:
            return next(int(line.split()[1]) for line in fh if line.startswith("VmRSS:"))

    # 50 MB in blocks below glibc's mmap threshold stay in its heap when freed ...
    blocks = [np.ones(8_000) for _ in range(6_000)]
    del blocks[::2]  # every other block: the heap's top cannot shrink by itself
    before = resident()
    del blocks
    assert release_freed_memory()
    assert resident() < before - 10_000  # ... and are given back (kB)
