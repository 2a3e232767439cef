"""Reading height maps from files.

Plain formats are read here: ``.npy`` (a 2-D array), ``.npz`` (the array ``heights``, or
the only array; optional scalars ``spacing`` in mm and ``units``), text grids (``.txt``,
``.csv``, ``.asc``, ``.dat``: whitespace or comma separated rows, ``#`` comments) and
x-y-z point lists (``.xyz``: one point a line on a regular lattice, any order).
Everything else goes to SurfaceTopography's readers (ISO 25178 X3P, Digital Surf SUR,
Wyko OPD, Sensofar PLU, Zygo DATX, Keyence VK, Gwyddion GWY, ...), the optional extra
``pip install ".[surfaces]"`` in the repository; no instrument format is parsed by hand here.

A plain array's rows are y and its columns x. Heights are returned in the file's units
(converted by :mod:`.conditioning`); the point list's x and y share the heights' units.
"""

from __future__ import annotations

import os
import warnings
import zipfile
import zlib
from dataclasses import dataclass

import numpy as np

from .heightmap import SurfaceError

TEXT_SUFFIXES = (".txt", ".csv", ".asc", ".dat")
POINT_SUFFIXES = (".xyz",)
#: Smallest map accepted, samples per side (a summit and its basin need a few cells).
MIN_SIDE = 3
#: What numpy's readers raise on a damaged file: a truncated ``.npz`` is no zip archive
#: (``BadZipFile``) or a member fails its checksum or decompression, an empty ``.npy``
#: ends before its header (``EOFError``).
DAMAGED_FILE_ERRORS = (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error)


@dataclass(frozen=True, eq=False)
class RawMap:
    """Heights as read, before conditioning: what a file holds, or a height map given in
    Python (``RawMap(heights, spacing=0.1, units="um")``, then
    :func:`twoscale.surface.build_surface` and :func:`twoscale.solve`).

    Attributes
    ----------
    heights : (ny, nx) array, in ``units`` (NaN where missing); rows are y, columns x.
    spacing : float or None
        Sample spacing when known: in mm (files with ``spacing``, or given here), or in
        ``units`` when ``spacing_units == "heights"`` (point lists, instrument formats);
        None: given by :class:`~twoscale.surface.SurfaceOptions` (``spacing``).
    units : str or None
        Height units the file (or caller) declares ("mm", "um", "nm", "m"), None if
        nothing says; then ``SurfaceOptions.units``, and without it the heights are taken
        as mm only when their relief is plausible in mm (:mod:`.conditioning`).
    spacing_units : str or None
        Units of ``spacing`` (None: mm).
    source : str
        The file name, or ``"array"`` for heights given in Python.

    Raises
    ------
    SurfaceError
        Heights that are not a 2-D numeric grid, smaller than ``MIN_SIDE`` per side, or
        all missing (the message names ``source``).
    """

    heights: np.ndarray
    spacing: float | None = None
    units: str | None = None
    spacing_units: str | None = None
    source: str = "array"

    def __post_init__(self) -> None:
        object.__setattr__(self, "heights", _checked_heights(self.source, self.heights))
        sp = self.spacing
        if sp is not None and not (
            isinstance(sp, (int, float, np.integer, np.floating)) and np.isfinite(sp) and sp > 0
        ):
            what = "RawMap spacing" if self.source == "array" else "the file's spacing"
            unit = " (mm)" if self.source == "array" and self.spacing_units is None else ""
            raise SurfaceError(f"{self.source}: {what} must be a number > 0{unit}, got {sp!r}")


def read_heightmap(path: str | os.PathLike) -> RawMap:
    """Read a height map file; see the module docstring for the formats.

    Raises
    ------
    SurfaceError
        Missing or unreadable file, unknown format, not a 2-D grid, all NaN, or smaller
        than ``MIN_SIDE`` samples per side; the message starts with the file name.
    """
    name = os.fspath(path)
    if not os.path.isfile(name):
        raise SurfaceError(f"{name}: height map file not found")
    suffix = os.path.splitext(name)[1].lower()
    try:
        if suffix == ".npy":
            raw = RawMap(np.load(name, allow_pickle=False), None, None, None, name)
        elif suffix == ".npz":
            raw = _read_npz(name)
        elif suffix in TEXT_SUFFIXES:
            raw = RawMap(_read_text_grid(name), None, None, None, name)
        elif suffix in POINT_SUFFIXES:
            raw = _read_points(name)
        else:
            raw = _read_instrument(name)
    except SurfaceError:
        raise
    except DAMAGED_FILE_ERRORS as exc:
        raise SurfaceError(f"{name}: cannot read the height map ({_first_line(exc)})") from None
    return raw


def _first_line(exc: Exception) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def _checked_heights(source: str, heights) -> np.ndarray:
    """``heights`` as a float array with NaN where missing, or a one-line SurfaceError."""
    z = np.asarray(heights)
    if z.ndim != 2 or not (np.issubdtype(z.dtype, np.integer) or np.issubdtype(z.dtype, np.floating)):
        raise SurfaceError(f"{source}: heights must be a 2-D numeric grid, got shape {z.shape} of {z.dtype}")
    z = np.array(z, dtype=float)
    if min(z.shape) < MIN_SIDE:
        raise SurfaceError(
            f"{source}: height map too small ({z.shape[0]} x {z.shape[1]} samples; at least {MIN_SIDE} x {MIN_SIDE})"
        )
    if not np.isfinite(z).any():
        kind = "NaN" if np.all(np.isnan(z)) else "NaN or infinite"
        raise SurfaceError(f"{source}: every height is missing (all {kind})")
    z[~np.isfinite(z)] = np.nan
    return z


def _read_npz(name: str) -> RawMap:
    with np.load(name, allow_pickle=False) as data:
        keys = list(data.keys())
        if "heights" in keys:
            z = data["heights"]
        elif len([k for k in keys if data[k].ndim == 2]) == 1:
            z = next(data[k] for k in keys if data[k].ndim == 2)
        else:
            raise SurfaceError(f"{name}: no array 'heights' among {keys}")
        try:
            spacing = float(data["spacing"]) if "spacing" in keys else None
        except (TypeError, ValueError):  # not one number (an array, a string)
            raise SurfaceError(f"{name}: 'spacing' must be one number, got {data['spacing']!r}") from None
        units = str(data["units"]) if "units" in keys else None
    return RawMap(z, spacing, units, None, name)


def _data_rows(name: str) -> tuple[list[str], str | None]:
    """The file's non-comment, non-blank lines (read once) and its delimiter (comma or
    whitespace)."""
    with open(name, encoding="utf-8") as fh:
        text = fh.read()
    rows = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    return rows, ("," if "," in text else None)


def _read_text_grid(name: str) -> np.ndarray:
    rows, delimiter = _data_rows(name)
    widths = {len(ln.split(delimiter)) for ln in rows}
    if len(widths) > 1:
        first = len(rows[0].split(delimiter))
        k = next(i for i, ln in enumerate(rows) if len(ln.split(delimiter)) != first)
        raise SurfaceError(
            f"{name}: a text grid needs the same number of values on every row; data row {k + 1} "
            f"has {len(rows[k].split(delimiter))}, the first has {first}"
        )
    return np.loadtxt(rows, delimiter=delimiter, ndmin=2)


def _read_points(name: str) -> RawMap:
    """x y z points on a regular lattice (any order, missing points allowed)."""
    rows, delimiter = _data_rows(name)
    pts = np.loadtxt(rows, delimiter=delimiter, ndmin=2)
    if pts.shape[1] != 3:
        raise SurfaceError(f"{name}: a point list needs 3 columns x y z, got {pts.shape[1]}")
    xs, ys = np.unique(pts[:, 0]), np.unique(pts[:, 1])
    if xs.size < MIN_SIDE or ys.size < MIN_SIDE:
        raise SurfaceError(f"{name}: height map too small ({ys.size} x {xs.size} distinct y, x values)")
    step = float(np.min(np.diff(xs)))
    for axis, vals in (("x", xs), ("y", ys)):
        k = (vals - vals[0]) / step
        if not np.allclose(k, np.round(k), atol=1e-6):
            raise SurfaceError(f"{name}: the {axis} values are not on a regular lattice of step {step!r}")
    i = np.round((pts[:, 0] - xs[0]) / step).astype(int)
    j = np.round((pts[:, 1] - ys[0]) / step).astype(int)
    z = np.full((j.max() + 1, i.max() + 1), np.nan)
    z[j, i] = pts[:, 2]
    return RawMap(z, step, None, "heights", name)


#: SurfaceTopography's unit names, as :mod:`.conditioning` spells them.
_ST_UNITS = {"m": "m", "mm": "mm", "µm": "um", "um": "um", "μm": "um", "nm": "nm"}


def _read_instrument(name: str) -> RawMap:
    try:
        from SurfaceTopography import read_topography
        from SurfaceTopography.Exceptions import CannotDetectFileFormat
    except ImportError:
        raise SurfaceError(
            f"{name}: not a plain format (.npy, .npz, text grid, .xyz); instrument formats "
            f'need the optional extra: pip install ".[surfaces]" in the repository'
        ) from None
    try:
        with warnings.catch_warnings():  # its netCDF reader warns about its own memory map
            warnings.simplefilter("ignore", RuntimeWarning)
            topo = read_topography(name)
            z = topo.heights()
    except CannotDetectFileFormat:
        raise SurfaceError(f"{name}: unknown height map format") from None
    except Exception as exc:  # the library's readers raise many kinds: report the first line
        raise SurfaceError(f"{name}: cannot read the height map ({_first_line(exc)})") from None
    z = np.ma.filled(np.ma.asarray(z, dtype=float), np.nan) if np.ma.isMaskedArray(z) else np.asarray(z, float)
    if z.ndim != 2:
        raise SurfaceError(f"{name}: a line scan (1-D), not a height map")
    units = _ST_UNITS.get(str(topo.unit)) if topo.unit is not None else None
    spacing = None
    try:
        sizes = topo.physical_sizes
    except Exception:  # formats without physical sizes raise when asked
        sizes = None
    if sizes is not None and units is not None:
        spacing = float(sizes[0]) / z.shape[0]
    # SurfaceTopography indexes [x, y]; here rows are y
    return RawMap(z.T, spacing, units, "heights" if spacing is not None else None, name)
