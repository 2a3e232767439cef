"""Make road.npz: a synthetic road texture, 50 x 50 mm at 0.1 mm (500 x 500 samples).

Packed chippings (half-ellipsoids of 4-8 mm, protruding 1-2.5 mm from a flat binder) with
a self-affine micro-roughness (rms 20 um, Hurst exponent 0.8, wavelengths 0.3-5 mm);
seeded, so the file is the same on every machine. Heights are stored in um as 16-bit
integers (the file says so: ``units = "um"``, ``spacing = 0.1`` mm) to keep it small.

    python examples/road/make_road.py            # rewrites examples/road/road.npz
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

SEED = 2026
SIZE, SPACING = 50.0, 0.1  # mm


def make(path: Path) -> Path:
    from twoscale.surface.texture import road

    heights_um = np.round(road(SIZE, SPACING, seed=SEED) * 1e3).astype(np.int16)
    np.savez_compressed(path, heights=heights_um, spacing=SPACING, units="um")
    return path


if __name__ == "__main__":
    target = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("road.npz")
    print(f"wrote {make(target)}")
