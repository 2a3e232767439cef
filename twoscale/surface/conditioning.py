"""Conditioning a height map for the solver: units, missing samples, plane detrend, crop,
resampling to the cell size, which side faces the body, and placement on the lattice.

The steps run in that order (:func:`condition`). The result is centred on the scene's
origin with a sample exactly at (0, 0): cell centres are on the lattice ``h Z^2``, the
one the two-scale solver and the reference grid share, so the height map is used as it
is when the cell size equals the spacing.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import ndimage
from scipy.interpolate import RegularGridInterpolator

from .heightmap import HeightMap, SurfaceError
from .reading import MIN_SIDE, RawMap

#: Height units and their size in mm.
UNITS = {"mm": 1.0, "um": 1e-3, "nm": 1e-6, "m": 1e3}
#: Most samples a conditioned map may have (a 200 mm square at 0.04 mm), and the memory
#: one sample costs through segmentation and the solvers' look-ups (an estimate, bytes).
MAX_SAMPLES = 25_000_000
BYTES_PER_SAMPLE = 200
#: How missing samples are treated: "nearest" fills each with the nearest measured
#: height; "mask" leaves them without material (they never touch).
FILL_MODES = ("nearest", "mask")


def condition(raw: RawMap, *, spacing: float | None = None, units: str | None = None, fill: str = "nearest",
              detrend: bool = False, crop=None, h: float | None = None, invert: bool = False) -> HeightMap:
    """The raw map as a :class:`HeightMap` in mm, ready for segmentation.

    Parameters
    ----------
    raw : RawMap
        As read by :func:`twoscale.surface.reading.read_heightmap`.
    spacing : float, optional
        Sample spacing, mm, for files that do not carry it (must agree with the file's
        when both are known).
    units : {"mm", "um", "nm", "m"}, optional
        Units of the heights; default the file's, else "mm".
    fill : {"nearest", "mask"}, default "nearest"
        Missing samples: filled with the nearest measured height, or left without
        material (never in contact). The count is in ``HeightMap.filled`` either way.
    detrend : bool, default False
        Subtract the least-squares plane (scanner tilt).
    crop : (xmin, xmax, ymin, ymax), optional
        Keep the samples in this window, mm, measured from the first sample (before
        centring).
    h : float, optional
        Resample (bilinear) to this spacing, mm; default: keep the spacing.
    invert : bool, default False
        False: larger heights are closer to the body (summits up, as a road scan).
        True: the map is flipped (a scan of the tread side, or of a mould).

    Raises
    ------
    SurfaceError
        Unknown units or fill mode, no spacing, a crop or resampling that leaves too few
        samples.
    """
    src = raw.source or "height map"
    factor = _unit_factor(src, raw.units, units)
    step = _spacing_mm(src, raw, spacing, factor)
    z = raw.heights * factor
    if fill not in FILL_MODES:
        raise SurfaceError(f"{src}: fill must be one of {', '.join(FILL_MODES)}, got {fill!r}")
    missing = np.isnan(z)
    if crop is not None:
        z, missing = _crop(src, z, missing, step, crop)
    if detrend:
        z = z - _plane(z, missing, step)
    if missing.any():
        z = _fill_nearest(z, missing)
    if h is not None and not math.isclose(h, step, rel_tol=1e-9):
        z, missing = _resample(src, z, missing, step, h)
        step = h
    if z.size > MAX_SAMPLES:   # before segmentation allocates its arrays
        raise SurfaceError(f"{src}: {z.shape[0]} x {z.shape[1]} samples at {step:g} mm is more than "
                           f"{MAX_SAMPLES:.0e} (about {BYTES_PER_SAMPLE * z.size / 1e9:.1f} GB to segment "
                           f"and solve); crop the map or give a larger [grid] h")
    _check_relief(src, z, step, assumed_mm=units is None and raw.units is None)
    if invert:
        z = -z
    if fill == "mask":
        z = np.where(missing, np.nan, z)
    ny, nx = z.shape
    return HeightMap(z, step, x0=-(nx // 2) * step, y0=-(ny // 2) * step, source=src,
                     filled=int(missing.sum()))


#: Relief (mm) above which heights taken as mm are suspected to be micrometres.
RELIEF_MM = 20.0


class SurfaceWarning(UserWarning):
    """A height map that reads as implausible (e.g. heights in um taken as mm)."""


def _check_relief(src: str, z: np.ndarray, step: float, *, assumed_mm: bool) -> None:
    """Warn when heights taken as mm (no units given) span more than :data:`RELIEF_MM` and
    a fifth of the map's smaller side: a road texture's relief is a few mm on a map of
    50-200 mm, and heights in um read as mm are 1000 times too tall."""
    import warnings

    relief = float(np.nanmax(z) - np.nanmin(z)) if np.isfinite(z).any() else 0.0
    side = step * min(z.shape)
    if assumed_mm and relief > max(0.2 * side, RELIEF_MM):
        warnings.warn(SurfaceWarning(
            f"{src}: heights taken as mm (no units given) span {relief:.4g} mm on a map {side:.4g} mm "
            f"wide; if they are in micrometres, set units = \"um\""), stacklevel=3)


def _unit_factor(src: str, declared: str | None, given: str | None) -> float:
    if given is not None and given not in UNITS:
        raise SurfaceError(f"{src}: units must be one of {', '.join(UNITS)}, got {given!r}")
    if declared is not None and declared not in UNITS:   # a file's own units field, unchecked before
        raise SurfaceError(f"{src}: the file's heights are in {declared!r}, not one of {', '.join(UNITS)}")
    if declared is not None and given is not None and declared != given:
        raise SurfaceError(f"{src}: units = {given!r} but the file says its heights are in {declared!r}")
    return UNITS[given or declared or "mm"]


def _spacing_mm(src: str, raw: RawMap, given: float | None, factor: float) -> float:
    if given is not None and not (isinstance(given, (int, float)) and math.isfinite(given) and given > 0):
        raise SurfaceError(f"{src}: spacing must be a number > 0 (mm), got {given!r}")
    own = None
    if raw.spacing is not None:
        own = raw.spacing * (factor if raw.spacing_units == "heights" else 1.0)
    if own is not None and given is not None and not math.isclose(own, given, rel_tol=1e-6):
        raise SurfaceError(f"{src}: spacing = {given!r} mm but the file's spacing is {own!r} mm")
    step = own if own is not None else given
    if step is None:
        raise SurfaceError(f"{src}: no spacing: the file does not carry one, give [surface] spacing (mm)")
    return float(step)


def _crop(src, z, missing, step, crop):
    try:
        x0, x1, y0, y1 = (float(v) for v in crop)
    except (TypeError, ValueError):
        raise SurfaceError(f"{src}: crop must be [xmin, xmax, ymin, ymax] (mm), got {crop!r}") from None
    width, height = (z.shape[1] - 1) * step, (z.shape[0] - 1) * step
    if x0 < -1e-9 * step or y0 < -1e-9 * step or x1 > width * (1 + 1e-9) or y1 > height * (1 + 1e-9) \
            or x1 <= x0 or y1 <= y0:
        raise SurfaceError(f"{src}: crop {list(crop)!r} mm must lie within the map, x in [0, {width:g}], "
                           f"y in [0, {height:g}] mm from the first sample, with xmin < xmax and ymin < ymax")
    i0, i1 = max(0, math.ceil(x0 / step - 1e-9)), min(z.shape[1], math.floor(x1 / step + 1e-9) + 1)
    j0, j1 = max(0, math.ceil(y0 / step - 1e-9)), min(z.shape[0], math.floor(y1 / step + 1e-9) + 1)
    if i1 - i0 < MIN_SIDE or j1 - j0 < MIN_SIDE:
        raise SurfaceError(f"{src}: crop {list(crop)!r} mm leaves {max(j1 - j0, 0)} x {max(i1 - i0, 0)} samples "
                           f"(at least {MIN_SIDE} x {MIN_SIDE})")
    z, missing = z[j0:j1, i0:i1], missing[j0:j1, i0:i1]
    if missing.all():
        raise SurfaceError(f"{src}: every height in crop {list(crop)!r} is missing")
    return z, missing


def _plane(z, missing, step) -> np.ndarray:
    """Least-squares plane through the measured samples, on the whole grid."""
    J, I = np.indices(z.shape)
    ok = ~missing
    A = np.column_stack([np.ones(ok.sum()), I[ok] * step, J[ok] * step])
    c = np.linalg.lstsq(A, z[ok], rcond=None)[0]
    return c[0] + c[1] * I * step + c[2] * J * step


def _fill_nearest(z, missing) -> np.ndarray:
    index = ndimage.distance_transform_edt(missing, return_distances=False, return_indices=True)
    return z[tuple(index)]


def _resample(src, z, missing, step, h):
    if not (isinstance(h, (int, float)) and math.isfinite(h) and h > 0):
        raise SurfaceError(f"{src}: cell size h must be a number > 0 (mm), got {h!r}")
    ny, nx = z.shape
    mx, my = math.floor((nx - 1) * step / h + 1e-9) + 1, math.floor((ny - 1) * step / h + 1e-9) + 1
    if mx < MIN_SIDE or my < MIN_SIDE:
        raise SurfaceError(f"{src}: resampling to h = {h!r} mm leaves {my} x {mx} samples")
    x, y = np.arange(nx) * step, np.arange(ny) * step
    X, Y = np.meshgrid(np.minimum(np.arange(mx) * h, x[-1]), np.minimum(np.arange(my) * h, y[-1]))
    pts = np.column_stack([Y.ravel(), X.ravel()])
    out = RegularGridInterpolator((y, x), z)(pts).reshape(my, mx)
    gone = RegularGridInterpolator((y, x), missing.astype(float), method="nearest")(pts).reshape(my, mx) > 0.5
    return out, gone
