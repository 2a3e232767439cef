"""Conditioning a height map for the solver: units, missing samples, plane detrend, crop,
resampling to the cell size, which side faces the body, and placement on the lattice.

The steps run in that order (:func:`condition`). The result is centred on the scene's
origin with a sample exactly at (0, 0): cell centres are on the lattice ``h Z^2``, the
one the two-scale solver and the reference grid share, so the height map is used as it
is when the cell size equals the spacing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..errors import SurfaceWarning  # noqa: F401  (documented here; raised by surface.edges)
from ..options import settings_from
from .heightmap import HeightMap, SurfaceError
from .reading import MIN_SIDE, POINT_SUFFIXES, RawMap

#: Height units and their size in mm.
MM_PER_UNIT = {"mm": 1.0, "um": 1e-3, "nm": 1e-6, "m": 1e3}
#: Most samples a conditioned map may have (a 200 mm square at 0.04 mm), and the memory
#: one sample costs through conditioning, segmentation and the solvers' look-ups (an
#: upper estimate, bytes; measured in docs/surfaces.md, "Size and memory").
MAX_SAMPLES = 25_000_000
BYTES_PER_SAMPLE = 200
#: How missing samples are treated: "nearest" fills each with the nearest measured
#: height; "mask" leaves them without material (they never touch).
FILL_MODES = ("nearest", "mask")
#: Largest relief (height span) over the map's smaller side for heights taken as mm when
#: no units are given: a measured texture is far flatter (a road: 2-10 mm over 50-200 mm;
#: a hemisphere: 0.5), while heights in um read as mm are 1000 times too tall (the
#: example road: 2.9 m over 50 mm).
MAX_RELIEF_RATIO = 1.0


@dataclass(frozen=True)
class Conditioning:
    """How a raw map is conditioned (the keywords ``spacing``, ``units``, ``fill``,
    ``detrend``, ``crop``, ``invert`` of :func:`condition`, documented there)."""

    spacing: float | None = None
    units: str | None = None
    fill: str = "nearest"
    detrend: bool = False
    crop: tuple | None = None
    invert: bool = False


def condition(raw: RawMap, *, h: float | None = None, h_name: str = "h", **conditioning) -> HeightMap:
    """The raw map as a :class:`HeightMap` in mm, ready for segmentation.

    Parameters
    ----------
    raw : RawMap
        As read by :func:`twoscale.surface.reading.read_heightmap`, or made in Python.
    h : float, optional
        Resample (bilinear) to this spacing, mm; default: keep the spacing.
    h_name : str, default "h"
        Where ``h`` came from, as a refusal names it (``"grid.h"``, ``"--h"``).
    **conditioning
        The keywords below (:class:`Conditioning`); another is refused by name.
    spacing : float, optional
        Sample spacing, mm, for files that do not carry it (must agree with the file's
        when both are known).
    units : {"mm", "um", "nm", "m"}, optional
        Units of the heights; default the file's (``raw.units``). When neither says,
        the heights are taken as mm, unless their relief exceeds
        :data:`MAX_RELIEF_RATIO` times the map's smaller side (heights in um read as mm):
        then an error asks for ``units``.
    fill : {"nearest", "mask"}, default "nearest"
        Missing samples: filled with the nearest measured height, or left without
        material (never in contact). The count is in ``HeightMap.filled`` either way.
    detrend : bool, default False
        Subtract the least-squares plane (scanner tilt).
    crop : (xmin, xmax, ymin, ymax), optional
        Keep the samples in this window, mm, measured from the first sample (before
        centring).
    invert : bool, default False
        False: larger heights are closer to the body (summits up, as a road scan).
        True: the map is flipped (a scan of the tread side, or of a mould).

    Raises
    ------
    SurfaceError
        Unknown units or fill mode, no spacing, heights implausible in mm without
        ``units``, a crop or resampling that leaves too few samples, or a map larger than
        :data:`MAX_SAMPLES` samples or than the memory available after resampling
        (checked before anything of the resampled size is allocated).
    """
    c = settings_from(Conditioning, conditioning, "condition")
    spacing, units, fill, detrend, crop, invert = c.spacing, c.units, c.fill, c.detrend, c.crop, c.invert
    src = raw.source or "height map"
    factor, unit, units_from = _units(src, raw.units, units)
    step = _spacing_mm(src, raw, spacing, factor)
    if fill not in FILL_MODES:
        raise SurfaceError(f"{src}: fill must be one of {', '.join(FILL_MODES)}, got {fill!r}")
    z, missing = raw.heights, np.isnan(raw.heights)
    if crop is not None:
        z, missing = _crop(src, z, missing, step, crop)
    if units_from == "default":
        _check_relief(src, z, step)
    elif unit != "mm" and str(src).lower().endswith(POINT_SUFFIXES):  # x, y scaled with the heights
        _check_shared_unit(src, z * factor, step, unit)
    _check_size(src, z.shape, step, h, h_name)  # before anything of the resampled size exists
    if factor != 1.0:  # (mm: the map's own array; HeightMap copies it)
        z = z * factor
    if detrend:
        z = z - _plane(z, missing, step)
    if missing.any():
        z = _fill_nearest(z, missing)
    measured = None
    if h is not None and not math.isclose(h, step, rel_tol=1e-9):
        z, missing = _resample(z, missing, step, h)
        measured, step = step, h
    if invert:
        z = -z
    if fill == "mask":
        z = np.where(missing, np.nan, z)
    ny, nx = z.shape
    return HeightMap(
        z,
        step,
        x0=-(nx // 2) * step,
        y0=-(ny // 2) * step,
        source=src,
        filled=int(missing.sum()),
        units=unit,
        units_from=units_from,
        measured_spacing=measured,
    )


def _check_relief(src: str, z: np.ndarray, step: float) -> None:
    """Refuse heights taken as mm (no units given) whose relief exceeds
    :data:`MAX_RELIEF_RATIO` times the map's smaller side: heights in um read as mm."""
    lo, hi = float(np.nanmin(z)), float(np.nanmax(z))
    side = step * (min(z.shape) - 1)
    if hi - lo > MAX_RELIEF_RATIO * side:
        raise SurfaceError(
            f"{src}: surface.units is not given and the heights, taken as mm, run from {lo:.4g} to {hi:.4g} "
            f"({hi - lo:.4g} mm of relief on a map {side:.4g} mm wide): they look like another unit; "
            f'give surface.units ("um" if they are micrometres, "mm" if they really are mm; in Python '
            f"SurfaceOptions(units=...) or RawMap(units=...))"
        )


def _check_shared_unit(src: str, z_mm: np.ndarray, step: float, unit: str) -> None:
    """Refuse a point list read in ``unit`` (not mm: its x, y are scaled with the heights)
    whose relief exceeds :data:`MAX_RELIEF_RATIO` times its smaller side: the ratio does not
    depend on the shared unit, so x, y and the heights were written in different ones."""
    relief, side = float(np.nanmax(z_mm) - np.nanmin(z_mm)), step * (min(z_mm.shape) - 1)
    if relief > MAX_RELIEF_RATIO * side:
        raise SurfaceError(
            f"{src}: the heights span {relief:.4g} mm on a map {side:.4g} mm wide, with x, y read in the heights' "
            f"unit ({unit}; a point list's three columns share one unit): x, y and the heights look like different "
            f"units; write x and y in the heights' unit"
        )


def _resampled_shape(src: str, shape: tuple, step: float, h: float) -> tuple[int, int]:
    """Samples (rows, columns) of a ``shape`` map at spacing ``step`` resampled to ``h``."""
    if isinstance(h, bool) or not (isinstance(h, (int, float)) and math.isfinite(h) and h > 0):
        raise SurfaceError(f"{src}: cell size h must be a number > 0 (mm), got {h!r}")
    ny, nx = shape
    return math.floor((ny - 1) * step / h + 1e-9) + 1, math.floor((nx - 1) * step / h + 1e-9) + 1


def _check_size(src: str, shape: tuple, step: float, h: float | None, h_name: str) -> None:
    """Refuse, from the numbers alone, a map over :data:`MAX_SAMPLES` samples or over the
    memory available (:func:`twoscale.resources.default_limit`) once resampled to ``h``."""
    from ..resources import default_limit

    resampled = h is not None and not math.isclose(h, step, rel_tol=1e-9)
    my, mx = _resampled_shape(src, shape, step, h) if resampled else shape
    if mx < MIN_SIDE or my < MIN_SIDE:
        raise SurfaceError(
            f"{src}: resampling to {h_name} = {h!r} mm leaves {my} x {mx} samples (at least {MIN_SIDE} x {MIN_SIDE})"
        )
    n = float(mx) * float(my)
    need, limit = BYTES_PER_SAMPLE * n, default_limit()
    if n <= MAX_SAMPLES and need <= limit:
        return
    width, height = (shape[1] - 1) * step, (shape[0] - 1) * step
    origin = f"{h_name} = {h:g} mm" if resampled else f"the map's own spacing ({step:g} mm; no {h_name} given)"
    over = (
        f"more than {MAX_SAMPLES:,}"
        if n > MAX_SAMPLES
        else f"about {need / 1e9:.3g} GB, over 80 % of the memory available now ({limit / 1e9:.3g} GB)"
    )
    raise SurfaceError(
        f"{src}: {origin} gives {my:,} x {mx:,} = {n:.3g} samples on {width:.4g} x {height:.4g} mm, "
        f"{over}: crop the map or give {h_name} >= {_fitting_h(shape, step, limit):g} mm"
    )


def _fitting_h(shape: tuple, step: float, limit: float) -> float:
    """The smallest two-digit cell size (mm) at which the map fits both bounds."""
    cap = min(float(MAX_SAMPLES), limit / BYTES_PER_SAMPLE)
    if not cap >= MIN_SIDE**2:
        return math.inf
    area = (shape[1] - 1) * (shape[0] - 1) * step * step
    h = _round_up(max(math.sqrt(area / cap), step * 1e-6))  # samples go as area / h^2
    while math.prod(_resampled_shape("", shape, step, h)) > cap:  # the +1 sample per side
        h = _round_up(h * 1.01)
    return h


def _round_up(x: float) -> float:
    """``x`` rounded up to two significant digits."""
    e = math.floor(math.log10(x)) - 1
    return float(f"{math.ceil(x / 10.0**e - 1e-9) * 10.0**e:.3g}")


def _units(src: str, declared: str | None, given: str | None) -> tuple[float, str, str]:
    """Size of the height unit in mm, its name, and where it came from ("map", "option",
    "default")."""
    for name, v in (("units", given), ("the map's units", declared)):
        if v is not None and v not in MM_PER_UNIT:
            raise SurfaceError(f"{src}: {name} must be one of {', '.join(MM_PER_UNIT)}, got {v!r}")
    if declared is not None and given is not None and declared != given:
        raise SurfaceError(f"{src}: units = {given!r} but the file says its heights are in {declared!r}")
    if declared is not None:
        return MM_PER_UNIT[declared], declared, "map"
    if given is not None:
        return MM_PER_UNIT[given], given, "option"
    return MM_PER_UNIT["mm"], "mm", "default"


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
        if raw.source == "array":  # heights given in Python
            raise SurfaceError(
                f"{src}: no spacing: give RawMap(heights, spacing=...) or SurfaceOptions(spacing=...) (mm)"
            )
        raise SurfaceError(f"{src}: no spacing: the file does not carry one, give [surface] spacing (mm)")
    return float(step)


def _crop(src, z, missing, step, crop):
    try:
        x0, x1, y0, y1 = (float(v) for v in crop)
    except (TypeError, ValueError):
        raise SurfaceError(f"{src}: crop must be [xmin, xmax, ymin, ymax] (mm), got {crop!r}") from None
    width, height = (z.shape[1] - 1) * step, (z.shape[0] - 1) * step
    if (
        x0 < -1e-9 * step
        or y0 < -1e-9 * step
        or x1 > width * (1 + 1e-9)
        or y1 > height * (1 + 1e-9)
        or x1 <= x0
        or y1 <= y0
    ):
        raise SurfaceError(
            f"{src}: crop {list(crop)!r} mm must lie within the map, x in [0, {width:g}], "
            f"y in [0, {height:g}] mm from the first sample, with xmin < xmax and ymin < ymax"
        )
    i0, i1 = max(0, math.ceil(x0 / step - 1e-9)), min(z.shape[1], math.floor(x1 / step + 1e-9) + 1)
    j0, j1 = max(0, math.ceil(y0 / step - 1e-9)), min(z.shape[0], math.floor(y1 / step + 1e-9) + 1)
    if i1 - i0 < MIN_SIDE or j1 - j0 < MIN_SIDE:
        raise SurfaceError(
            f"{src}: crop {list(crop)!r} mm leaves {max(j1 - j0, 0)} x {max(i1 - i0, 0)} samples "
            f"(at least {MIN_SIDE} x {MIN_SIDE})"
        )
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
    """``z`` with each missing sample set to its nearest measured one (the Euclidean
    feature transform's choice), the transform run on the window of the missing samples
    grown by a margin beyond the farthest of them from a measured one (then every sample
    as near is in the window; at most the whole map): a road's holes, 1,600 samples of
    490,000, 13-30 against 1-2 ms."""
    rows, cols = np.flatnonzero(missing.any(axis=1)), np.flatnonzero(missing.any(axis=0))
    ny, nx = missing.shape
    margin = 8
    while True:
        j0, j1 = max(rows[0] - margin, 0), min(rows[-1] + margin + 1, ny)
        i0, i1 = max(cols[0] - margin, 0), min(cols[-1] + margin + 1, nx)
        whole = (j0, j1, i0, i1) == (0, ny, 0, nx)
        window = missing[j0:j1, i0:i1]
        if not window.all() or whole:
            far, (jj, ii) = ndimage.distance_transform_edt(window, return_indices=True)
            if whole or far.max() + 2 <= margin:
                break
            margin = int(far.max()) + 3
        else:
            margin *= 2
    out = z.copy()
    out[j0:j1, i0:i1][window] = z[j0:j1, i0:i1][jj[window], ii[window]]
    return out


def _resample(z, missing, step, h):
    """Bilinear resampling of ``z`` (spacing ``step``) to spacing ``h``, one axis after the
    other (no coordinate arrays: the only large arrays are the result and one
    intermediate), and the nearest sample's ``missing`` flag."""
    my, mx = _resampled_shape("", z.shape, step, h)
    (jy, wy, ny_), (ix, wx, nx_) = (_axis(n, m, step, h) for n, m in zip(z.shape, (my, mx)))
    rows = z[:, ix] * (1.0 - wx) + z[:, ix + 1] * wx
    out = rows[jy] * (1.0 - wy)[:, None] + rows[jy + 1] * wy[:, None]
    gone = missing[ny_][:, nx_]
    return out, gone


def _axis(n: int, m: int, step: float, h: float):
    """Along one axis of ``n`` samples resampled to ``m``: the left neighbour and weight of
    the right one (bilinear), and the nearest sample, of each new sample."""
    p = np.minimum(np.arange(m) * (h / step), n - 1.0)
    left = np.minimum(np.floor(p).astype(np.int64), n - 2)
    return left, p - left, np.minimum(np.floor(p + 0.5).astype(np.int64), n - 1)
