"""
The full pressure map over a scene (recipe)
===========================================

A result holds the pressure on the small grids the solver used (one patch per contact,
``result.fields``). For one array over the whole scene, as a pressure sensor or an image
analysis wants it, assemble the patches onto a grid aligned with them:
:meth:`~twoscale.ContactResult.pressure_on`. Here on the shipped synthetic road.
"""

import sys
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import twoscale
from twoscale.grid import Grid
from twoscale.io import read_scene

# the repository's examples/ folder (an installed twoscale does not ship it): found from
# the folder the script runs in (the documentation build runs it in docs/examples) or from
# the script's own place in the repository
places = [Path.cwd(), *Path.cwd().parents, *(Path(__file__).resolve().parents if "__file__" in globals() else ())]
ROOT = next((p for p in places if (p / "examples" / "road" / "road.toml").is_file()), None)
if ROOT is None:
    sys.exit("this example reads examples/road/road.toml: run it in a clone of the twoscale repository")
scene = read_scene(ROOT / "examples" / "road" / "road.toml")
with warnings.catch_warnings():  # stones cut by the map's edge: a warning the CLI prints
    warnings.simplefilter("ignore")
    result = twoscale.solve(scene)
print(result)

# %%
# A grid of the solver's cell size h (``result.fields[0].grid.h``) covering every patch:
# ``Grid.covering`` snaps to the same lattice, so each cell of a patch is one cell of
# the map.
h = result.fields[0].grid.h
b = np.array([f.grid.bounds for f in result.fields])
grid = Grid.covering(b[:, 0].min(), b[:, 1].max(), b[:, 2].min(), b[:, 3].max(), h)
P = result.pressure_on(grid)  # (ny, nx) MPa, zero where no contact
print(
    f"map {P.shape[1]} x {P.shape[0]} cells of {h:g} mm; "
    f"force {P.sum() * h * h:.4g} N (result: {result.total_load:.4g} N)"
)

# %%
# Plot it with a colour scale that the stones cut by the map's edge (a punch corner's
# peak) do not flatten: :func:`twoscale.plot.robust_scale` ends it at the 99th
# percentile of the loaded cells and keeps the peak.
from twoscale.plot import robust_scale

scale = robust_scale(P)
fig, ax = plt.subplots(figsize=(6.4, 5.2), layout="constrained")
im = ax.imshow(np.ma.masked_equal(P, 0), extent=grid.bounds, origin="lower", norm=scale.norm())
fig.colorbar(im, ax=ax, extend=scale.extend, label=scale.label("pressure", "MPa"))
ax.set(xlabel="x (mm)", ylabel="y (mm)", title="road on the half-space: the full pressure map")
plt.show()
