"""The files a solve writes beside result.json: fields, the per-asperity table, two figures.

* ``fields.vtm`` (+ ``fields/patch_NNN.vti``): pressure, gap, owning asperity and
  indenter height on the solver's grid(s) as VTK image data
  (:func:`twoscale.io.vtk.write_vtk`; open the ``.vtm`` in ParaView);
* ``asperities.csv``: position, shape, force, contact area, peak and mean pressure per
  asperity, numbered from 1, with ``asperities.csv-metadata.json`` (version, units, scene,
  columns) and, from 1,000 tips and with pyarrow, ``asperities.parquet``
  (:func:`twoscale.io.asperity_csv.write_asperity_csv`);
* ``pressure.png``: pressure map with the tips, numbered when few
  (:func:`twoscale.plot.pressure_map`);
* ``forces.png``: force per asperity (bars when few, histogram and a map of tips
  coloured by force when many), beside the macro-step forces when the method has them
  (:func:`twoscale.plot.force_bars`).

Each records the program version, the units and the scene.
"""

from __future__ import annotations

from pathlib import Path

from ..results import ContactResult
from ..scene import Scene
from .asperity_csv import ASPERITY_CSV_NAME, write_asperity_csv
from .scene_file import scene_to_dict

FIELDS_NAME = "fields.vtm"
PRESSURE_NAME = "pressure.png"
FORCES_NAME = "forces.png"


def write_fields_and_figures(
    result: ContactResult, scene: Scene, out_dir, *, vtk: bool = True, figures: bool = True, source: str = ""
) -> list[Path]:
    """Write ``fields.vtm``, ``asperities.csv``, ``pressure.png`` and ``forces.png`` into ``out_dir``.

    Parameters
    ----------
    result : ContactResult
    scene : Scene
        The scene solved (tips, pivot, and the record in every file).
    out_dir : path-like
        Directory, created if needed.
    vtk : bool, default True
        Write ``fields.vtm`` and its images.
    figures : bool, default True
        Write the two PNG figures (needs matplotlib).
    source : str, default ""
        What was solved (e.g. the scene file's name), in the CSV's first line.

    Returns
    -------
    list of Path written, in the order above (the ``.vtm`` for the fields; the table's
    CSV, metadata and Parquet).
    """
    out = Path(out_dir)
    record = scene_to_dict(scene)
    written = []
    if vtk:
        from .vtk import write_vtk

        written.append(
            write_vtk(result, out / FIELDS_NAME, asperities=scene.asperities, pivot=scene.pivot, scene=record)
        )
    written.extend(
        write_asperity_csv(
            result,
            scene.asperities,
            out / ASPERITY_CSV_NAME,
            scene=record,
            source=f"solve {source}" if source else "solve",
        )
    )
    if figures:
        from ..plot import Caption, force_bars, pressure_map

        name = Path(source).stem if source else None  # the figures' titles name the scene
        caption = Caption(scene=record, name=name)
        written.append(pressure_map(result, out / PRESSURE_NAME, tips=scene.asperities, caption=caption))
        written.append(
            force_bars(
                result, out / FORCES_NAME, tips=scene.asperities, macro_forces=result.macro_forces, caption=caption
            )
        )
    return written
