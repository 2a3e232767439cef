"""
The paper's seven spheres: pressure map and forces in one figure
================================================================

Read a scene file, solve it on the elastic half-space and draw the pressure map and the
force per asperity side by side, into Axes of our own (as in a notebook).
"""

import sys
from pathlib import Path

import matplotlib.pyplot as plt

import twoscale
from twoscale.io import read_scene
from twoscale.plot import Caption, plot_forces, plot_pressure_map

# the repository's examples/ folder (an installed twoscale does not ship it): found from
# the folder the script runs in (the documentation build runs it in docs/examples) or from
# the script's own place in the repository
places = [Path.cwd(), *Path.cwd().parents, *(Path(__file__).resolve().parents if "__file__" in globals() else ())]
ROOT = next((p for p in places if (p / "examples" / "paper_seven_spheres.toml").is_file()), None)
if ROOT is None:
    sys.exit("this example reads examples/paper_seven_spheres.toml: run it in a clone of the twoscale repository")
scene = read_scene(ROOT / "examples" / "paper_seven_spheres.toml")
result = twoscale.solve(scene)
print(result)

# %%
# One call per panel; ``name`` is the scene's name in the title, the body comes from the
# scene. Tips are numbered from 1, as in every table the command line writes.
fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.6), layout="constrained")
plot_pressure_map(result, ax=left, tips=scene.asperities, caption=Caption(scene=scene, name="paper_seven_spheres"))
plot_forces({"macro step": result.macro_forces, "final pressure": result}, ax=right, title="force per asperity")
plt.show()

# %%
# The numbers behind the figure: force (N), contact area (mm^2) and peak pressure (MPa)
# of each tip, in scene order (0-based in Python, numbered from 1 in files).
for k, (f, a, p) in enumerate(
    zip(result.forces, result.asperities.contact_areas, result.asperities.max_pressures), start=1
):
    print(f"tip {k}: {f:7.3f} N  {a:6.2f} mm^2  {p:5.3f} MPa")
