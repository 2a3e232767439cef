"""Make strip.npz: a synthetic chip-seal road strip, 200 mm along x by 50 mm across, at 0.25 mm.

Packed chippings (half-ellipsoids of 4-8 mm, protruding 1-2.5 mm from a flat binder) with a
self-affine micro-roughness (rms 20 um), laid out on the rectangle by
:func:`twoscale.rolling.road_strip`; seeded, so the file is the same on every machine.
Heights are stored in um as 16-bit integers (the file says so: ``units = "um"``,
``spacing = 0.25`` mm) to keep it small.

    python examples/rolling/make_strip.py        # rewrites examples/rolling/strip.npz
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

SEED = 2026
LENGTH, WIDTH, SPACING = 200.0, 50.0, 0.25  # mm


def make(path: Path) -> Path:
    from twoscale.rolling import road_strip

    heights_um = np.round(road_strip(LENGTH, WIDTH, SPACING, seed=SEED) * 1e3).astype(np.int16)
    np.savez_compressed(path, heights=heights_um, spacing=SPACING, units="um")
    return path


if __name__ == "__main__":
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("strip.npz")
    print(f"wrote {make(target)}")
