"""Command-line options shared by several commands: positive numbers, the cell size
(``--h``), the sensor (``--sensor``, ``--sensor-centre``).

Each parser turns the text given into a value or raises :class:`~twoscale.scene.SceneError`
naming the option and the text (the command prints it as one ``error:`` line, exit 2).
"""

from __future__ import annotations

import argparse
import math

from ..scene import SceneError
from ..sensor import Sensor

#: The paper's pressure sensor, used unless --sensor / --sensor-centre say otherwise.
DEFAULT_SENSOR = Sensor()


def add_sensor_arguments(parser: argparse.ArgumentParser) -> None:
    """``--sensor NX NY CELL`` and ``--sensor-centre X Y``."""
    parser.add_argument(
        "--sensor",
        metavar=("NX", "NY", "CELL"),
        nargs=3,
        default=None,
        help=f"sensor cells along x and y (integers >= 1) and cell side in mm "
        f"(default {DEFAULT_SENSOR.nx} {DEFAULT_SENSOR.ny} {DEFAULT_SENSOR.cell:g})",
    )
    parser.add_argument(
        "--sensor-centre",
        metavar=("X", "Y"),
        nargs=2,
        default=None,
        help="sensor centre in scene coordinates, mm (default 0 0)",
    )


def positive_option(text: str | None, name: str, *, unit: str) -> float | None:
    """A command-line value that must be a finite number > 0 (``None`` passes through).

    Raises
    ------
    SceneError
        Naming the option ``name`` and the text given.
    """
    if text is None:
        return None
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and v > 0):
        raise SceneError(f"{name} must be a finite number > 0 ({unit}), got {text!r}")
    return v


def read_scene_at_h(path, text: str | None):
    """The scene file ``path`` at the cell size ``--h`` gives (the file's without ``--h``). A
    height map is conditioned at that size when read, not first at its own spacing: a map
    too large at its spacing is read at a coarser ``--h``, one too large at ``--h`` is
    refused naming ``--h``, and the map is segmented once."""
    from ..io.scene_file import read_scene

    return read_scene(path, h=positive_option(text, "--h", unit="mm"), h_name="--h")


def int_option(text: str, name: str) -> int:
    """An integer >= 1 given as ``text`` for the option ``name``."""
    try:
        v = int(text)
    except ValueError:
        v = 0
    if v < 1:
        raise SceneError(f"{name} must be an integer >= 1, got {text!r}")
    return v


def finite_option(text: str, name: str, *, unit: str) -> float:
    """A finite number given as ``text`` for the option ``name`` (in ``unit``)."""
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not math.isfinite(v):
        raise SceneError(f"{name} must be a finite number ({unit}), got {text!r}")
    return v


def sensor_from_args(args: argparse.Namespace) -> Sensor:
    """The sensor of ``--sensor NX NY CELL`` and ``--sensor-centre X Y`` (default the paper's)."""
    s = DEFAULT_SENSOR
    nx, ny, cell, centre = s.nx, s.ny, s.cell, s.centre
    if args.sensor is not None:
        nx = int_option(args.sensor[0], "--sensor NX")
        ny = int_option(args.sensor[1], "--sensor NY")
        cell = positive_option(args.sensor[2], "--sensor CELL", unit="mm")
    if args.sensor_centre is not None:
        centre = (
            finite_option(args.sensor_centre[0], "--sensor-centre X", unit="mm"),
            finite_option(args.sensor_centre[1], "--sensor-centre Y", unit="mm"),
        )
    return Sensor(nx, ny, cell, centre)
