"""The ``[surface]`` table of a scene file: a height map instead of ``[[asperity]]`` tables.

Keys (units mm; every one but ``file`` optional):

==================  ===============================================================
``file``            the height map, relative to the scene file (:mod:`.reading`)
``spacing``         sample spacing, mm, for files that do not carry it
``units``           of the heights: "mm" (default unless the file says), "um", "nm", "m"
``invert``          false (default): larger heights are closer to the body
``fill``            missing samples: "nearest" (default) or "mask" (never in contact)
``detrend``         subtract the least-squares plane (default false)
``crop``            [xmin, xmax, ymin, ymax], mm from the first sample
``min_distance``    between summits, mm (default 2)
``prominence``      of a summit, mm (default 0.1)
``cap_depth``       of the equivalent-sphere fit, mm (default 0.1)
``law``             "auto" (default: the tabulated law where it is already cached,
                    else the equivalent sphere's), "tabulated" (single-asperity
                    solves, cached) or "sphere" (Hertz law of the equivalent sphere)
``law_depth``       deepest tabulated penetration, mm (default 0.5)
``law_levels``      penetrations per asperity (default 5)
``law_cache``       folder of the on-disk law cache, relative to the scene file, or
                    false for none (default: the user's cache folder)
==================  ===============================================================

A plain array's rows are y and its columns x; the map is centred on the scene's origin
(with a sample on it) and ``[grid] h``, when given, resamples it.
"""

from __future__ import annotations

import dataclasses
import os
from typing import Any, Mapping

from ..io.table_checks import check_keys
from ..scene import SceneError, check_number
from .lawcache import LawCache
from .measured import MeasuredSurface, SurfaceOptions, load_surface

SURFACE_KEYS = (
    "file",
    "spacing",
    "units",
    "invert",
    "fill",
    "detrend",
    "crop",
    "min_distance",
    "prominence",
    "cap_depth",
    "law",
    "law_depth",
    "law_levels",
    "law_cache",
)
_NUMBERS = ("spacing", "min_distance", "prominence", "cap_depth", "law_depth")
_FLAGS = ("invert", "detrend")
_WORDS = ("units", "fill", "law")


def surface_from_table(
    table: Mapping[str, Any], *, base_dir: str | None = None, h: Any = None, h_name: str = "grid.h"
) -> MeasuredSurface:
    """Read and build the surface a ``[surface]`` table describes, at the cell size ``h``
    (None: the map's spacing); ``h_name`` names where ``h`` came from in a refusal.

    Raises
    ------
    SceneError
        Unknown or invalid keys (named ``surface.KEY``), or a file that cannot be used
        (:class:`twoscale.surface.SurfaceError`, naming the file).
    """
    check_keys("surface", table, SURFACE_KEYS)
    if "file" not in table:
        raise SceneError("surface.file is missing (required: the height map, relative to the scene file)")
    if not isinstance(table["file"], str) or not table["file"]:
        raise SceneError(f"surface.file must be a file name, got {table['file']!r}")
    options = {k: v for k, v in table.items() if k not in ("file", "law_cache")}
    for key in _NUMBERS:
        if key in options:
            options[key] = check_number(f"surface.{key}", options[key], positive=key != "prominence", unit="mm")
    for key in _WORDS:
        if key in options and not isinstance(options[key], str):
            raise SceneError(f"surface.{key} must be a string, got {options[key]!r}")
    for key in _FLAGS:
        if key in options and not isinstance(options[key], bool):
            raise SceneError(f"surface.{key} must be true or false, got {options[key]!r}")
    if "crop" in options:
        if not isinstance(options["crop"], list) or len(options["crop"]) != 4:
            raise SceneError(f"surface.crop must be [xmin, xmax, ymin, ymax] (mm), got {options['crop']!r}")
        options["crop"] = tuple(check_number(f"surface.crop[{i}]", v, unit="mm") for i, v in enumerate(options["crop"]))
    if h is not None:
        h = check_number(h_name, h, positive=True, unit="mm")
    base = base_dir or os.getcwd()
    cache = _cache(table.get("law_cache"), base)
    try:
        opts = SurfaceOptions(**options)
    except TypeError as exc:  # a key of the wrong type reaching a comparison
        raise SceneError(f"surface: {exc}") from None
    return load_surface(os.path.join(base, table["file"]), opts, h=h, cache=cache, h_name=h_name)


def _cache(value, base: str) -> LawCache | None:
    if value is None:
        return LawCache()
    if value is False:
        return None
    if not isinstance(value, str) or not value:
        raise SceneError(f"surface.law_cache must be a folder name or false, got {value!r}")
    return LawCache(os.path.join(base, value))


def surface_to_table(surface: MeasuredSurface) -> dict:
    """The ``[surface]`` table of ``surface`` (the file's absolute path, the options that
    differ from their defaults), for records such as result.json; heights given in Python
    are recorded as ``array`` (their shape) with their spacing and units."""
    raw = surface.raw
    if os.path.isfile(raw.source):
        out: dict = {"file": os.path.abspath(raw.source)}
    else:  # heights given in Python: what the record can say of them
        ny, nx = raw.heights.shape
        out = {"array": f"{ny} x {nx} heights given in Python"}
        if raw.spacing is not None and raw.spacing_units is None:  # in mm
            out["spacing"] = raw.spacing
        if raw.units is not None:
            out["units"] = raw.units
    defaults = SurfaceOptions()
    for f in dataclasses.fields(SurfaceOptions):
        v = getattr(surface.options, f.name)
        if v != getattr(defaults, f.name):
            out[f.name] = list(v) if isinstance(v, tuple) else v
    if surface.book.cache is None:
        out["law_cache"] = False
    else:
        out["law_cache"] = str(surface.book.cache.directory)
    return out
