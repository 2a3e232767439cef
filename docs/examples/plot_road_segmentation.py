"""
A height map cut into asperities
================================

The shipped synthetic road (50 x 50 mm at 0.1 mm) segmented into one asperity per stone
(summits and watershed basins), as ``twoscale surface`` draws it: the ten highest summits
carry the numbers they have in ``asperities.csv``.
"""

import sys
from pathlib import Path

import matplotlib.pyplot as plt

from twoscale.io import read_scene
from twoscale.surface.figure import plot_segmentation

# the repository's examples/ folder (an installed twoscale does not ship it): found from
# the folder the script runs in (the documentation build runs it in docs/examples) or from
# the script's own place in the repository
places = [Path.cwd(), *Path.cwd().parents, *(Path(__file__).resolve().parents if "__file__" in globals() else ())]
ROOT = next((p for p in places if (p / "examples" / "road" / "road.toml").is_file()), None)
if ROOT is None:
    sys.exit("this example reads examples/road/road.toml: run it in a clone of the twoscale repository")
scene = read_scene(ROOT / "examples" / "road" / "road.toml")
fig, ax = plt.subplots(figsize=(7, 6), layout="constrained")
plot_segmentation(scene.surface, ax=ax)
plt.show()
