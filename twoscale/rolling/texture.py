r"""Texture figures of a road strip: mean profile depth (ISO 13473-1) and the texture
level spectrum along x (ISO 13473-4).

The strip is ``heights[y, x]`` (mm, larger is closer to the tyre, rows y, columns x) at a
spacing ``h`` (mm); each row is a profile along the rolling direction x. A 1-D array is
one profile.

**Missing samples** (NaN, the instrument's dropouts) are replaced, line by line, by linear
interpolation between the valid neighbours (leading and trailing ones take the nearest
valid value). Linear interpolation never makes a new peak, so peaks are those of the
valid samples. A 100 mm segment with more than ``max_dropout`` (default 10 %) of its
samples missing is left out of the mean profile depth; a line with more than
``max_dropout`` missing is left out of the spectrum. Results count what was left out.

**Mean profile depth (MPD).** Each line is cut from its first sample into segments of
``n = round(100 mm / h)`` samples (the samples after the last whole segment are not
used). Per segment:

1. slope suppression: subtract the least-squares line :math:`a + b x` of the segment
   (this also makes its mean zero);
2. peak levels :math:`p_1, p_2`: the largest height of the first :math:`\lceil n/2\rceil`
   samples and of the remaining ones (the two 50 mm halves);
3. mean segment depth :math:`\mathrm{MSD} = (p_1 + p_2)/2 - \bar z`, :math:`\bar z` the
   segment's mean after step 1 (zero to rounding).

MPD is the mean of the MSD over all segments kept, of all lines (for a strip without
dropouts, the mean of the lines' MPD). The estimated texture depth ETD = 0.2 mm + 0.8 MPD
(ISO 13473-1) is given beside it. No low-pass filter is applied: the strip is taken as
already sampled at the spacing wanted (ISO 13473-1 asks for 1 mm or finer).

**Texture level spectrum.** Each line kept has its least-squares line removed (a tilt of
the strip is not texture) and its one-sided power spectrum computed in spatial frequency
:math:`\nu = 1/\lambda` (1/mm) exactly as for the force bands (:mod:`.bands`: no window,
Parseval normalisation, sum rule). Third-octave bands are base 10 in spatial frequency:
band ``k`` has the centre :math:`\nu_c = 10^{k/10}` /mm, i.e. the centre wavelength
:math:`\lambda_c = 10^{-k/10}` mm with the nominal labels 0.5, 0.63, 0.8, 1, ..., 400,
500 mm, edges :math:`\nu_c 10^{\pm 1/20}`; only bands with at least 3 bins that end below
the Nyquist frequency :math:`1/(2h)` and lie within 0.5 ... 500 mm are reported. The
band mean squares :math:`a_\text{rms}^2` are averaged over the lines (power average) and
:math:`L_\text{tx} = 10\log_{10}(a_\text{rms}^2 / a_\text{ref}^2) = 20\log_{10}(a_\text{rms}
/ 1\,\mu\text{m})` dB.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import SurfaceError
from .bands import MIN_BINS, REF_APPROACH, band_sums, centre, nominal, power_rows

#: MPD segment length, mm (ISO 13473-1).
SEGMENT_MM = 100.0
#: Largest fraction of missing samples a segment (MPD) or a line (spectrum) may have.
MAX_DROPOUT = 0.1
#: Band numbers of the standard's centre wavelengths 500 mm (k = -27) ... 0.5 mm (k = 3).
K_RANGE = (-27, 3)
#: Rows of the strip transformed at once (bounds the work array of the spectrum).
_ROWS = 256


@dataclass(frozen=True, eq=False)
class MeanProfileDepth:
    """Mean profile depth of a strip (ISO 13473-1), mm.

    Attributes
    ----------
    mpd : float
        Mean of the segments' MSD, mm.
    segment_msd : (ny, nseg) array
        MSD of each segment of each line, mm; NaN where too many samples were missing.
    segment_samples : int
        Samples per segment (``round(100 mm / h)``).
    spacing : float
        Sample spacing h, mm.
    """

    mpd: float
    segment_msd: np.ndarray
    segment_samples: int
    spacing: float

    @property
    def etd(self) -> float:
        """Estimated texture depth 0.2 + 0.8 MPD, mm (ISO 13473-1)."""
        return 0.2 + 0.8 * self.mpd

    @property
    def line_mpd(self) -> np.ndarray:
        """MPD of each line (mean of its kept segments), mm; NaN for a line with none."""
        kept = np.isfinite(self.segment_msd)
        total = np.where(kept, self.segment_msd, 0.0).sum(axis=1)
        count = kept.sum(axis=1)
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)

    @property
    def segments_used(self) -> int:
        return int(np.isfinite(self.segment_msd).sum())

    @property
    def segments_dropped(self) -> int:
        return int(self.segment_msd.size - self.segments_used)


@dataclass(frozen=True, eq=False)
class TextureSpectrum:
    """Third-octave texture levels along x (ISO 13473-4), power-averaged over the lines.

    Attributes
    ----------
    wavelength, nominal : (B,) arrays
        Exact centre wavelengths ``10**(-k/10)`` mm and their nominal labels (mm), from
        the longest to the shortest.
    mean_square : (B,) array
        Band mean square a_rms^2 averaged over the lines, mm^2.
    level_dB : (B,) array
        ``20 log10(a_rms / 1 um)``; ``-inf`` for a band without power.
    bins : (B,) int array
        FFT bins per band (per line).
    resolution : float
        Bin spacing in spatial frequency, 1/mm (1 / line length).
    lines, lines_dropped : int
        Lines averaged, and lines left out for missing samples.
    """

    wavelength: np.ndarray
    nominal: np.ndarray
    mean_square: np.ndarray
    level_dB: np.ndarray
    bins: np.ndarray
    resolution: float
    lines: int
    lines_dropped: int


@dataclass(frozen=True, eq=False)
class Texture:
    """What ``texture.json`` holds: the strip's MPD and texture spectrum."""

    mpd: MeanProfileDepth
    spectrum: TextureSpectrum
    shape: tuple[int, int]
    spacing: float
    missing: int

    def to_json_dict(self) -> dict:
        """A JSON-ready dict (lengths in mm, levels in dB re 1 um, ``null`` for -inf)."""
        m, s = self.mpd, self.spectrum
        line = m.line_mpd
        return {
            "units": {"length": "mm", "level": "dB re 1 um"},
            "strip": {
                "lines": self.shape[0],
                "samples_per_line": self.shape[1],
                "spacing_mm": self.spacing,
                "length_mm": self.shape[1] * self.spacing,
                "missing_samples": self.missing,
                "missing_filled": "linear interpolation along x",
            },
            "mean_profile_depth": {
                "standard": "ISO 13473-1",
                "mpd_mm": _num(m.mpd),
                "etd_mm": _num(m.etd),
                "segment_mm": SEGMENT_MM,
                "segment_samples": m.segment_samples,
                "slope_suppression": "least-squares line per segment",
                "segments_used": m.segments_used,
                "segments_dropped": m.segments_dropped,
                "max_dropout": MAX_DROPOUT,
                "averaged": "mean of the segments' MSD over all lines and segments",
                "line_mpd_mm": [_num(v) for v in line],
                "line_mpd_std_mm": _num(np.nanstd(line)) if np.any(np.isfinite(line)) else None,
            },
            "texture_spectrum": {
                "standard": "ISO 13473-4",
                "reference_um": 1.0,
                "bands": "third octave, base 10",
                "detrend": "least-squares line per line",
                "window": "none",
                "averaged": "power average (mean square) over the lines",
                "lines": s.lines,
                "lines_dropped": s.lines_dropped,
                "resolution_per_mm": s.resolution,
                "min_bins": MIN_BINS,
                "wavelength_mm": s.nominal.tolist(),
                "wavelength_exact_mm": s.wavelength.tolist(),
                "level_dB": [_num(v) for v in s.level_dB],
                "bins": s.bins.tolist(),
            },
        }


def _num(v) -> float | None:
    v = float(v)
    return v if math.isfinite(v) else None


def _strip(heights, spacing: float) -> np.ndarray:
    z = np.array(heights, dtype=float)
    z = z[None, :] if z.ndim == 1 else z
    if z.ndim != 2 or z.size == 0:
        raise SurfaceError(f"texture strip must be a 1-D profile or a 2-D map heights[y, x], got shape {z.shape}")
    if not (math.isfinite(spacing) and spacing > 0):
        raise SurfaceError(f"texture spacing must be a finite number > 0 (mm), got {spacing!r}")
    if np.any(np.isinf(z)):
        raise SurfaceError("texture strip has infinite heights")
    return z


def filled(z: np.ndarray) -> np.ndarray:
    """``z`` (lines along the last axis) with NaN replaced by linear interpolation along
    each line (ends: the nearest valid value); a line without any valid sample stays NaN."""
    out = z.copy()
    index = np.arange(z.shape[1])
    for j in np.flatnonzero(np.isnan(z).any(axis=1)):
        ok = ~np.isnan(z[j])
        if ok.any():
            out[j] = np.interp(index, index[ok], z[j, ok])
    return out


def _detrended(rows: np.ndarray) -> np.ndarray:
    """Rows (..., n) minus their least-squares lines."""
    n = rows.shape[-1]
    t = np.arange(n) - 0.5 * (n - 1)
    mean = rows.mean(axis=-1, keepdims=True)
    slope = (rows * t).sum(axis=-1, keepdims=True) / float(np.sum(t * t))
    return rows - mean - slope * t


def mean_profile_depth(heights, spacing: float, *, max_dropout: float = MAX_DROPOUT) -> MeanProfileDepth:
    """Mean profile depth (ISO 13473-1) of a profile or a strip ``heights[y, x]``, mm.

    Parameters
    ----------
    heights : (nx,) or (ny, nx) array
        Heights, mm (larger is closer to the tyre); NaN for missing samples.
    spacing : float
        Sample spacing along x, mm.
    max_dropout : float, default 0.1
        Segments with a larger fraction of missing samples are left out.

    Raises
    ------
    SurfaceError
        The strip is shorter than one 100 mm segment, or no segment is usable.
    """
    z = _strip(heights, spacing)
    n = int(round(SEGMENT_MM / spacing))
    if n < 2 or z.shape[1] < n:
        raise SurfaceError(
            f"texture strip is {z.shape[1] * spacing:g} mm long along x ({z.shape[1]} samples "
            f"at {spacing:g} mm), shorter than one {SEGMENT_MM:g} mm segment of the mean profile depth"
        )
    nseg = z.shape[1] // n
    missing = np.isnan(z[:, : nseg * n]).reshape(z.shape[0], nseg, n).mean(axis=2)
    seg = _detrended(filled(z)[:, : nseg * n].reshape(z.shape[0], nseg, n))
    half = (n + 1) // 2
    msd = 0.5 * (seg[..., :half].max(axis=2) + seg[..., half:].max(axis=2)) - seg.mean(axis=2)
    msd = np.where(missing <= max_dropout, msd, np.nan)
    if not np.any(np.isfinite(msd)):
        raise SurfaceError(
            f"texture strip: every {SEGMENT_MM:g} mm segment has more than "
            f"{max_dropout:.0%} missing samples; no mean profile depth"
        )
    msd.setflags(write=False)
    return MeanProfileDepth(float(np.nanmean(msd)), msd, n, float(spacing))


def texture_spectrum(heights, spacing: float, *, max_dropout: float = MAX_DROPOUT) -> TextureSpectrum:
    """Third-octave texture levels along x (ISO 13473-4), dB re 1 um, power-averaged over
    the lines of ``heights[y, x]`` (mm) at ``spacing`` (mm); see the module text.

    Bands are those within 0.5 ... 500 mm that hold at least 3 bins and end below the
    Nyquist frequency (empty arrays when the strip resolves none).
    """
    z = _strip(heights, spacing)
    if z.shape[1] < 2:
        raise SurfaceError(f"texture strip has {z.shape[1]} sample along x; a spectrum needs at least 2")
    keep = np.isnan(z).mean(axis=1) <= max_dropout
    if not np.any(keep):
        raise SurfaceError(
            f"texture strip: every line has more than {max_dropout:.0%} missing samples; no texture spectrum"
        )
    lines = filled(z[keep])
    power = np.zeros(z.shape[1] // 2 + 1)
    for start in range(0, lines.shape[0], _ROWS):
        power += power_rows(_detrended(lines[start : start + _ROWS])).sum(axis=0)
    power /= lines.shape[0]
    freq = np.fft.rfftfreq(z.shape[1], spacing)
    ks, sums, count = band_sums(freq, power, 0.5 / spacing, f_ref=1.0)
    inside = (ks >= K_RANGE[0]) & (ks <= K_RANGE[1])
    ks, sums, count = ks[inside], sums[inside], count[inside]
    with np.errstate(divide="ignore"):
        level = 10.0 * np.log10(sums / REF_APPROACH**2)
    arrays = [1.0 / centre(ks, 1.0), nominal(-ks, 1.0), sums, level, count]
    for a in arrays:
        a.setflags(write=False)
    return TextureSpectrum(*arrays, float(freq[1] - freq[0]), int(keep.sum()), int((~keep).sum()))


def road_texture(heights, spacing: float, *, max_dropout: float = MAX_DROPOUT) -> Texture:
    """MPD and texture spectrum of a strip ``heights[y, x]`` (mm) at ``spacing`` (mm):
    the contents of ``texture.json`` (:meth:`Texture.to_json_dict`)."""
    z = _strip(heights, spacing)
    return Texture(
        mean_profile_depth(z, spacing, max_dropout=max_dropout),
        texture_spectrum(z, spacing, max_dropout=max_dropout),
        (int(z.shape[0]), int(z.shape[1])),
        float(spacing),
        int(np.isnan(z).sum()),
    )
