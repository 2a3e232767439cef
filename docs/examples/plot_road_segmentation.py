"""
A height map cut into asperities
================================

The shipped synthetic road (50 x 50 mm at 0.1 mm) segmented into one asperity per stone
(summits and watershed basins), as ``twoscale surface`` draws it: the ten highest summits
carry the numbers they have in ``asperities.csv``.
"""

from pathlib import Path

import matplotlib.pyplot as plt

from twoscale.io import read_scene
from twoscale.surface.figure import plot_segmentation

# the repository's examples/ folder: run from the repository (or a folder in it, as the
# documentation build does); an installed twoscale does not ship the examples
ROOT = next(p for p in (Path.cwd(), *Path.cwd().parents) if (p / "examples" / "road" / "road.toml").is_file())
scene = read_scene(ROOT / "examples" / "road" / "road.toml")
fig, ax = plt.subplots(figsize=(7, 6), layout="constrained")
plot_segmentation(scene.surface, ax=ax)
plt.show()
