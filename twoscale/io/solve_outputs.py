"""The files a solve writes beside result.json: micro-grid fields and two figures.

* ``fields.vtu``: pressure, gap, owning asperity and indenter height on the solver's
  grid(s) (:func:`twoscale.io.vtk.write_vtk`; open in ParaView);
* ``pressure.png``: pressure map with the tips (:func:`twoscale.plot.pressure_map`);
* ``forces.png``: force per asperity, beside the macro-step forces when the method has
  them (:func:`twoscale.plot.force_bars`).

Each records the program version, the units and the scene.
"""
from __future__ import annotations

from pathlib import Path

from ..results import ContactResult
from ..scene import Scene
from .scene_file import scene_to_dict

FIELDS_NAME = "fields.vtm"
PRESSURE_NAME = "pressure.png"
FORCES_NAME = "forces.png"


def write_fields_and_figures(result: ContactResult, scene: Scene, out_dir, *, vtk: bool = True,
                             figures: bool = True) -> list[Path]:
    """Write ``fields.vtu``, ``pressure.png`` and ``forces.png`` into ``out_dir``.

    Parameters
    ----------
    result : ContactResult
    scene : Scene
        The scene solved (tips, pivot, and the record in every file).
    out_dir : path-like
        Directory, created if needed.
    vtk : bool, default True
        Write ``fields.vtu`` (needs meshio).
    figures : bool, default True
        Write the two PNG figures (needs matplotlib).

    Returns
    -------
    list of Path written, in the order above.
    """
    out = Path(out_dir)
    record = scene_to_dict(scene)
    written = []
    if vtk:
        from .vtk import write_vtk

        written.append(write_vtk(result, out / FIELDS_NAME, asperities=scene.asperities,
                                 pivot=scene.pivot, scene=record))
    if figures:
        from ..plot import force_bars, pressure_map

        written.append(pressure_map(result, out / PRESSURE_NAME, tips=scene.asperities, scene=record))
        written.append(force_bars(result, out / FORCES_NAME, macro_forces=result.extra.get("macro_forces"),
                                  scene=record))
    return written
