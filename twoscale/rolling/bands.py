r"""Third-octave band levels of a uniformly sampled signal (IEC 61260 base-10 bands).

The computation, step by step, so that it can be redone by hand (a spreadsheet will do):

1. **Signal.** ``N`` samples :math:`x_n` at a constant step :math:`\Delta t` (s; for a
   profile along x the step is a length, mm, and frequencies are per mm). Remove the mean:
   :math:`y_n = x_n - \bar x`. No window, no other detrending.
2. **One-sided power.** :math:`X_k = \sum_n y_n e^{-2\pi i kn/N}` for
   :math:`k = 0 \dots \lfloor N/2 \rfloor` at frequencies :math:`f_k = k\,\Delta f`,
   :math:`\Delta f = 1/(N \Delta t)`, and

   .. math:: P_k = w_k \, |X_k|^2 / N^2, \qquad w_k = 2 \text{ except } w_0 = 1
             \text{ and, for even } N, w_{N/2} = 1 .

   The DC and Nyquist bins have no mirror image, hence weight 1. By Parseval,
   :math:`\sum_k P_k = \frac1N \sum_n y_n^2`, the mean square of the mean-removed
   signal (``P_0`` is zero after removing the mean). A sine of amplitude ``A`` at a bin
   frequency puts :math:`A^2/2` in that one bin.
3. **Bands.** Band number ``k`` (an integer) has the exact centre
   :math:`f_c = 1000 \cdot 10^{k/10}` Hz (IEC 61260-1, base 10) and the edges
   :math:`f_c\,10^{\pm 1/20}`. Its nominal label is the preferred number of the R10 series
   (..., 315, 400, 500, 630, 800, 1000, 1250, ... Hz; :func:`nominal`). A bin belongs to
   the band when :math:`f_c 10^{-1/20} \le f_k < f_c 10^{1/20}` (half-open, so no bin is
   counted twice). A band is reported only when it holds **at least 3 bins** and its
   upper edge does not exceed the Nyquist frequency :math:`1/(2\Delta t)` (a band cut by
   the Nyquist frequency would be under-estimated).
4. **Level.** :math:`L = 10 \log_{10}\big(\sum_{k \in \text{band}} P_k / x_\text{ref}^2\big)`
   dB, with :math:`x_\text{ref}` = 1 N for a force (:data:`REF_FORCE`) and 1 um = 1e-3 mm
   for an approach under load control (:data:`REF_APPROACH`). A band of exactly zero
   power has the level ``-inf``.

Without a window the signal is taken as periodic: a difference ``J`` between its last and
first samples leaks like a sawtooth, :math:`P_k = J^2 / (2 N^2 \sin^2(\pi k/N))`, about
:math:`0.0117\,J^2 \Delta f / f_c` per band; band levels near that are leakage.

**Welch averaging** (option :class:`Welch`): the mean-removed signal is cut into segments
of ``segment`` samples overlapping by ``overlap`` (a fraction); each segment has its own
mean removed, is multiplied by the window :math:`w_n` (Hann by default, to keep the
leakage of each short segment low; ``"boxcar"`` for none) and transformed; its one-sided
power is :math:`P_k = w_k |\sum_n w_n y_n e^{-2\pi i kn/M}|^2 / (M \sum_n w_n^2)`
(``M`` the segment length), the normalisation of :func:`scipy.signal.welch` with
``scaling="density"`` times :math:`\Delta f = 1/(M\Delta t)`. With it the sum rule holds
segment by segment for the windowed signal, :math:`\sum_k P_k = \sum_n w_n^2 y_n^2 /
\sum_n w_n^2`, a weighted mean square whose expectation is the mean square of a
stationary signal (exactly the segment's mean square with the boxcar window). The
``P_k`` are averaged over the segments; samples after the last whole segment are not
used. The bands then follow step 3 with :math:`\Delta f = 1/(M \Delta t)`: coarser
resolution, fewer bands with 3 bins, lower variance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError

#: Reference of force levels: 1 N.
REF_FORCE = 1.0
#: Reference of approach (displacement) levels: 1 um, in mm.
REF_APPROACH = 1e-3
#: Mantissas of the nominal band labels: the R10 series of preferred numbers (ISO 3), as IEC 61260-1 labels bands.
R10 = (1.0, 1.25, 1.6, 2.0, 2.5, 3.15, 4.0, 5.0, 6.3, 8.0)
#: The fewest FFT bins a band must hold to be reported.
MIN_BINS = 3
#: Centre of band 0 for time signals, Hz.
F_REF = 1000.0


def centre(k, f_ref: float = F_REF) -> np.ndarray:
    """Exact centre(s) of band number(s) ``k``: ``f_ref * 10**(k/10)`` (Hz for ``f_ref`` = 1000)."""
    return f_ref * 10.0 ** (np.asarray(k, dtype=float) / 10.0)


def nominal(k, f_ref: float = F_REF) -> np.ndarray:
    """Nominal label(s) of band number(s) ``k``: the R10 preferred number nearest the exact
    centre (``k = -5 .. 3`` give 315, 400, 500, 630, 800, 1000, 1250, 1600, 2000 Hz)."""
    k = np.asarray(k, dtype=int)
    mantissa = np.asarray(R10)[np.mod(k, 10)]
    value = f_ref * mantissa * 10.0 ** np.floor_divide(k, 10).astype(float)
    # 3.15 * 100 is 315.00000000000006 in binary: round to the label's few digits
    return np.vectorize(lambda v: float(f"{v:.6g}"), otypes=[float])(value) if value.size else value


@dataclass(frozen=True)
class Welch:
    """Welch averaging of the band powers (see the module text).

    Parameters
    ----------
    segment : int
        Samples per segment (>= 8, at most the signal's length).
    overlap : float, default 0.5
        Overlap of consecutive segments, a fraction in [0, 1).
    window : str, default "hann"
        A window name :func:`scipy.signal.get_window` knows; ``"boxcar"`` for none.
    """

    segment: int
    overlap: float = 0.5
    window: str = "hann"

    def __post_init__(self) -> None:
        if isinstance(self.segment, bool) or not isinstance(self.segment, (int, np.integer)) or self.segment < 8:
            raise SceneError(f"welch segment must be an integer >= 8 (samples), got {self.segment!r}")
        if not (isinstance(self.overlap, (int, float)) and 0.0 <= self.overlap < 1.0):
            raise SceneError(f"welch overlap must be a fraction in [0, 1), got {self.overlap!r}")
        if self.step < 1:
            raise SceneError(
                f"welch overlap {self.overlap!r} leaves no step between segments of {self.segment} samples"
            )
        from scipy.signal import get_window

        try:
            get_window(self.window, 8)
        except (ValueError, TypeError) as exc:
            raise SceneError(f"welch window {self.window!r} is not a window scipy knows ({exc})") from None

    @property
    def step(self) -> int:
        """Samples between the starts of consecutive segments."""
        return self.segment - int(round(self.overlap * self.segment))


@dataclass(frozen=True, eq=False)
class BandLevels:
    """Third-octave levels of one signal (arrays in increasing band order).

    Attributes
    ----------
    index : (B,) int array
        Band numbers k: exact centre ``f_ref * 10**(k/10)``.
    centre, nominal : (B,) arrays
        Exact centre frequencies and their nominal labels (Hz for a time signal, 1/mm for
        a profile).
    lower, upper : (B,) arrays
        Band edges ``centre * 10**(-+1/20)``.
    mean_square : (B,) array
        Sum of ``P_k`` over the band's bins (unit^2: N^2, mm^2).
    level_dB : (B,) array
        ``10 log10(mean_square / reference**2)``; ``-inf`` for a band of zero power.
    bins : (B,) int array
        FFT bins in each band (>= :data:`MIN_BINS`).
    resolution : float
        Bin spacing Delta f (Hz or 1/mm).
    reference : float
        The level's reference (1 N: :data:`REF_FORCE`; 1e-3 mm: :data:`REF_APPROACH`).
    total_mean_square : float
        Sum of all ``P_k``: the mean square of the mean-removed signal (Welch: the
        segments' average windowed mean square).
    segments : int
        Segments averaged (1 without Welch).
    welch : Welch or None
        The Welch options used, None for the plain periodogram.
    """

    index: np.ndarray
    centre: np.ndarray
    nominal: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    mean_square: np.ndarray
    level_dB: np.ndarray
    bins: np.ndarray
    resolution: float
    reference: float
    total_mean_square: float
    segments: int = 1
    welch: Welch | None = None

    def columns(self) -> dict[str, np.ndarray]:
        """The ``bands.csv`` columns: ``band_Hz`` (nominal label) and ``level_dB``."""
        return {"band_Hz": self.nominal, "level_dB": self.level_dB}


def _checked(signal, dt: float) -> np.ndarray:
    x = np.asarray(signal, dtype=float)
    if x.ndim != 1 or x.size < 2:
        raise ValueError(f"signal must be 1-D with at least 2 samples, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"signal has {int(np.sum(~np.isfinite(x)))} samples that are not finite")
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"sample step dt must be a finite number > 0, got {dt!r}")
    return x


def one_sided_power(signal, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies ``f_k`` and one-sided powers ``P_k`` of the mean-removed signal, no window.

    ``sum(P) == mean((signal - mean(signal))**2)`` to rounding (Parseval; weights 1 on
    the DC and, for even length, Nyquist bins, 2 elsewhere). ``dt``: sample step (s, or
    mm for a profile); frequencies in 1/unit of ``dt``.
    """
    x = _checked(signal, dt)
    return np.fft.rfftfreq(x.size, dt), power_rows(x[None, :])[0]


def power_rows(rows: np.ndarray) -> np.ndarray:
    """One-sided powers ``P_k`` of each row of ``rows`` (M, N), mean removed, no window
    (the rows of :func:`one_sided_power`, without its checks)."""
    n = rows.shape[-1]
    spectrum = np.fft.rfft(rows - rows.mean(axis=-1, keepdims=True), axis=-1)
    power = (spectrum.real**2 + spectrum.imag**2) / float(n) ** 2
    power[..., 1 : (n + 1) // 2] *= 2.0  # bins with a mirror image; DC and (even n) Nyquist keep 1
    return power


def welch_power(signal, dt: float, welch: Welch) -> tuple[np.ndarray, np.ndarray, int]:
    """Frequencies, segment-averaged one-sided powers ``P_k`` (see the module text) and the
    number of segments, by :func:`scipy.signal.welch`."""
    from scipy.signal import welch as scipy_welch

    x = _checked(signal, dt)
    if welch.segment > x.size:
        raise SceneError(f"welch segment ({welch.segment} samples) is longer than the signal ({x.size} samples)")
    fs = 1.0 / dt
    f, density = scipy_welch(
        x - x.mean(),
        fs=fs,
        window=welch.window,
        nperseg=welch.segment,
        noverlap=welch.segment - welch.step,
        detrend="constant",
        scaling="density",
        return_onesided=True,
        average="mean",
    )
    segments = 1 + (x.size - welch.segment) // welch.step
    return f, density * (fs / welch.segment), segments


def band_sums(
    freq: np.ndarray, power: np.ndarray, nyquist: float, f_ref: float = F_REF
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Band numbers, band sums of ``power`` and bin counts of the bands that hold at least
    :data:`MIN_BINS` bins and end at or below ``nyquist`` (half the sampling frequency).

    ``freq`` must be the uniform grid ``k * df`` of :func:`one_sided_power`.
    """
    df, f_top = float(freq[1] - freq[0]), float(nyquist)
    lowest = math.floor(10.0 * math.log10(df / f_ref)) - 1
    highest = math.ceil(10.0 * math.log10(f_top / f_ref)) + 1
    ks = np.arange(lowest, highest + 1)
    lo, hi = centre(ks, f_ref) * 10.0**-0.05, centre(ks, f_ref) * 10.0**0.05
    first = np.searchsorted(freq, lo, side="left")  # first bin with f >= lo
    stop = np.searchsorted(freq, hi, side="left")  # first bin with f >= hi
    count = stop - first
    keep = (count >= MIN_BINS) & (hi <= f_top)
    cumulative = np.concatenate([[0.0], np.cumsum(power)])
    sums = cumulative[stop] - cumulative[first]
    return ks[keep], sums[keep], count[keep]


def _levels(freq, power, nyquist, segments, welch, reference: float, f_ref: float) -> BandLevels:
    ks, sums, count = band_sums(freq, power, nyquist, f_ref)
    c = centre(ks, f_ref)
    with np.errstate(divide="ignore"):
        level = 10.0 * np.log10(sums / reference**2)
    arrays = [ks, c, nominal(ks, f_ref), c * 10.0**-0.05, c * 10.0**0.05, sums, level, count]
    for a in arrays:
        a.setflags(write=False)  # a result is a value
    return BandLevels(*arrays, float(freq[1] - freq[0]), float(reference), float(power.sum()), int(segments), welch)


def third_octave_levels(
    signal, dt: float, *, reference: float = REF_FORCE, welch: Welch | None = None, f_ref: float = F_REF
) -> BandLevels:
    """Third-octave band levels of a uniformly sampled signal (see the module text).

    Parameters
    ----------
    signal : (N,) array
        The samples (N for a force, mm for an approach); finite.
    dt : float
        Sample step, s (> 0). For the rolling run: ``step / speed``.
    reference : float, default 1.0
        The level's reference in the signal's unit: :data:`REF_FORCE` (1 N) or
        :data:`REF_APPROACH` (1e-3 mm = 1 um).
    welch : Welch, optional
        Average the powers of overlapping windowed segments (plain periodogram when None).
    f_ref : float, default 1000
        Centre of band 0 (1000 Hz, IEC 61260). Band centres are ``f_ref * 10**(k/10)``.

    Returns
    -------
    BandLevels
        Only the bands with at least 3 bins that end below the Nyquist frequency; empty
        arrays when the signal is too short for any.
    """
    if not (math.isfinite(reference) and reference > 0):
        raise ValueError(f"reference must be a finite number > 0, got {reference!r}")
    if welch is None:
        freq, power = one_sided_power(signal, dt)
        return _levels(freq, power, 0.5 / dt, 1, None, reference, f_ref)
    freq, power, segments = welch_power(signal, dt, welch)
    return _levels(freq, power, 0.5 / dt, segments, welch, reference, f_ref)
