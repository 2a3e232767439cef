"""e_M and e_m between two stored solves (``twoscale indicators RUN_DIR REF_DIR``).

``RUN_DIR`` and ``REF_DIR`` are output folders of ``twoscale solve --out`` (``result.json``
and ``fields.vtm``), e.g. the same scene on two bodies, with two methods or two cell sizes.
The indicators of docs/method.md section 5, in percent, with the reference in the denominator:

* ``e_M = 100 sum_k (P_k - Pref_k)^2 / sum_k Pref_k^2`` on the per-asperity forces of
  ``result.json`` (the two runs must have as many asperities, in the same order);
* ``e_m``: the same on the pressures of ``fields.vtm`` averaged onto the sensor cells
  (default the paper's 44 x 44 cells of 1.9 mm centred on the origin; ``--sensor NX NY
  CELL``, ``--sensor-centre X Y``), over the cells loaded in either map; ``null`` when the
  reference map is zero on every cell.

Prints both; ``--json FILE`` also writes them with the two folders, the sensor, the program
version and the units. Bad input (missing or foreign files, different asperity counts, bad
sensor values): one ``error:`` line, exit code 2, nothing written.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .._version import __version__
from ..comparison import folder_indicators
from ..io.atomic import atomic_output
from ..io.result_json import UNITS
from .options import add_sensor_arguments, sensor_from_args


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``twoscale indicators``."""
    parser.add_argument("run", metavar="RUN_DIR", help="output folder of twoscale solve (judged)")
    parser.add_argument("reference", metavar="REF_DIR", help="output folder of twoscale solve (reference)")
    add_sensor_arguments(parser)
    parser.add_argument("--json", metavar="FILE", default=None, help="also write the indicators as JSON")


def run(args: argparse.Namespace) -> int:
    """Run ``twoscale indicators`` (:func:`twoscale.comparison.folder_indicators`); returns the exit code."""
    try:
        sensor = sensor_from_args(args)
        out = folder_indicators(Path(args.run), Path(args.reference), sensor)
        if args.json is not None and Path(args.json).is_dir():
            raise ValueError(f"--json must name a file, got the folder {args.json!r}")
    except ValueError as exc:  # SceneError included
        print(f"error: {exc}", file=sys.stderr)
        return 2
    e_m_text = "n/a (reference map zero on every sensor cell)" if out["e_m"] is None else f"{out['e_m']:.4g} %"
    print(
        f"e_M = {out['e_M']:.4g} %  (forces of {args.run} against {args.reference}; a ratio of squared "
        f"norms, 100 sum|P - P~|^2 / sum|P~|^2: one tip of seven 7 % off gives about 0.07 %)"
    )
    print(
        f"e_m = {e_m_text}  (squared norms likewise; sensor {sensor.nx} x {sensor.ny} cells of {sensor.cell:g} mm "
        f"at ({sensor.centre[0]:g}, {sensor.centre[1]:g}) mm)"
    )
    if args.json is not None:
        record = {
            "e_M_percent": out["e_M"],
            "e_m_percent": out["e_m"],
            "run": str(args.run),
            "reference": str(args.reference),
            "sensor": {"nx": sensor.nx, "ny": sensor.ny, "cell": sensor.cell, "centre": list(sensor.centre)},
            "version": __version__,
            "units": dict(UNITS),
        }
        with atomic_output(Path(args.json)) as tmp:
            tmp.write_text(json.dumps(record, indent=2) + "\n", encoding="utf-8")
    return 0
