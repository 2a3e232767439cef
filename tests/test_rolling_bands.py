"""Third-octave band levels of synthetic signals whose band powers are known in closed form.

Conventions under test (twoscale.rolling.bands): one-sided power of the mean-removed
signal, no window, sum of all P_k = mean square; bands fc = 1000 * 10^(k/10) Hz with edges
fc * 10^(+-1/20), a bin in [lower, upper); only bands with >= 3 bins that end at or below
the Nyquist frequency.
"""

import numpy as np
import pytest
from scipy import stats

from twoscale.errors import SceneError
from twoscale.rolling.bands import (
    REF_APPROACH,
    Welch,
    centre,
    nominal,
    one_sided_power,
    third_octave_levels,
)

FS = 10_000.0  # Hz
N = 10_000  # samples: 1 s, bins 1 Hz apart, so integer frequencies are bin-exact
DT = 1.0 / FS


def _band_of(result, f):
    inside = (result.lower <= f) & (f < result.upper)
    assert inside.sum() == 1, f"{f} Hz is in {inside.sum()} reported bands"
    return int(np.flatnonzero(inside)[0])


def test_centres_and_nominal_labels_follow_iec_61260():
    # IEC 61260-1 table of nominal mid-band frequencies, 315 Hz ... 2 kHz (k = -5 ... 3)
    assert nominal(np.arange(-5, 4)).tolist() == [315, 400, 500, 630, 800, 1000, 1250, 1600, 2000]
    assert nominal([-30, -21, 10]).tolist() == [1.0, 8.0, 10_000.0]
    assert centre(0) == 1000.0 and centre(-10) == pytest.approx(100.0, rel=1e-15)
    assert centre(-5) == pytest.approx(1000 / np.sqrt(10), rel=1e-15)  # 316.23 Hz, labelled 315
    # nominal labels stay within 1.3 % of the exact base-10 centres over six decades
    k = np.arange(-40, 21)
    assert np.max(np.abs(nominal(k) / centre(k) - 1)) < 0.013


@pytest.mark.parametrize("n", [4096, 4097])
def test_parseval_sum_rule_is_exact(n):
    rng = np.random.default_rng(3)
    x = 5.0 + np.cumsum(rng.normal(size=n))  # a mean and a red spectrum
    f, P = one_sided_power(x, 2e-4)
    y = x - x.mean()
    assert P.sum() == pytest.approx(np.mean(y * y), rel=1e-12)
    assert f[1] == pytest.approx(1.0 / (n * 2e-4), rel=1e-14) and len(P) == n // 2 + 1
    assert P[0] == pytest.approx(0.0, abs=1e-20 * np.mean(y * y))
    # an independent implementation: scipy's periodogram (density) times the bin width
    from scipy.signal import periodogram

    _, density = periodogram(x, fs=5000.0, window="boxcar", detrend="constant", scaling="density")
    np.testing.assert_allclose(P, density * 5000.0 / n, rtol=1e-10, atol=1e-14 * P.max())
    assert third_octave_levels(x, 2e-4).total_mean_square == pytest.approx(np.mean(y * y), rel=1e-12)


@pytest.mark.parametrize("f0", [100.0, 316.0, 1000.0, 1995.0])
def test_a_bin_exact_sine_puts_its_mean_square_in_its_band_only(f0):
    """A sine of a whole number of periods (f0 T integer) has no leakage: its A^2/2 sits in
    one bin. What reaches other bands is FFT rounding, |dX_k| <~ eps log2(N) ||y||_2, i.e.
    a total below (eps log2 N)^2 * mean square ~ 1e-28 A^2: bounded here by 1e-22 A^2."""
    A, ref = 2.5, REF_APPROACH
    t = np.arange(N) * DT
    x = 0.7 + A * np.sin(2 * np.pi * f0 * t + 0.4)
    r = third_octave_levels(x, DT, reference=ref)
    b = _band_of(r, f0)
    assert abs(centre(r.index[b]) - f0) <= 0.5 * r.resolution + 1e-9 * f0  # at the band's centre
    assert r.mean_square[b] == pytest.approx(A**2 / 2, rel=1e-12)
    assert r.level_dB[b] == pytest.approx(10 * np.log10(A**2 / 2 / ref**2), abs=1e-9)
    others = np.delete(r.mean_square, b)
    assert np.all(others < 1e-22 * A**2)


def test_a_ramp_has_the_sawtooth_band_powers_in_every_band():
    """x_n = J n / N seen as periodic is a sawtooth: with r = exp(-2 pi i k / N),
    sum_n n r^n = N / (r - 1), so |X_k| = J / (2 sin(pi k / N)) and
    P_k = J^2 / (2 N^2 sin^2(pi k / N)) for 0 < k < N/2 (about J^2 / (2 pi^2 k^2): the
    leakage of a jump J between the last and first samples). Every band must hold the
    sum of these over its own bins, counted here from the band edges."""
    J = 0.004
    r = third_octave_levels(J * np.arange(N) / N, DT, reference=REF_APPROACH)
    for lo, hi, power in zip(r.lower, r.upper, r.mean_square):
        k = np.arange(int(np.ceil(lo / 1.0)), int(np.ceil(hi / 1.0)))  # bins 1 Hz apart in [lo, hi)
        assert power == pytest.approx(np.sum(J**2 / (2 * N**2 * np.sin(np.pi * k / N) ** 2)), rel=1e-9)
    assert len(r.index) >= 25


def _leak_bound(A, f0T, outside_bins):
    """Upper bound of the power of A cos(2 pi f0 t) in the given bins (k >= 1): the DFT of
    each complex exponential is a Dirichlet kernel |sin(pi u) / (N sin(pi u / N))| <=
    1 / (2 |u|) for the wrapped distance |u| <= N/2 (sin(pi v) >= 2 v on [0, 1/2])."""
    k = np.asarray(outside_bins, float)
    d1 = np.abs((k - f0T + N / 2) % N - N / 2)
    d2 = np.abs((k + f0T + N / 2) % N - N / 2)
    amplitude = A / 2 * (1 / (2 * d1) + 1 / (2 * d2))
    return float(np.sum(2 * amplitude**2))


def test_leakage_of_a_sine_between_bins_stays_within_the_dirichlet_bound():
    A, f0 = 1.0, 1000.5  # half a bin off: the worst case for an unwindowed FFT
    x = A * np.cos(2 * np.pi * f0 * np.arange(N) * DT)
    r = third_octave_levels(x, DT)
    b = _band_of(r, f0)
    f, P = one_sided_power(x, DT)
    outside = np.flatnonzero((f > 0) & ((f < r.lower[b]) | (f >= r.upper[b])))
    bound = _leak_bound(A, f0 * N * DT, outside)
    assert 0.0 < P[outside].sum() <= bound < 0.01 * A**2 / 2
    assert r.mean_square[b] == pytest.approx(P.sum() - P[outside].sum(), rel=1e-12)
    assert r.mean_square[b] >= P.sum() - bound


def test_white_noise_band_powers_follow_the_bandwidth():
    """Gaussian white noise of variance s^2: every bin k > 0 holds P_k = (s^2 / N) chi2(2),
    independent across k, so a band of m bins holds (s^2 / N) chi2(2m), mean 2 m s^2 / N.
    Each band must lie within its chi2 quantiles 1e-6 and 1 - 1e-6. The count m of bin
    frequencies k df in a half-open band of width B is floor or ceil of B / df, so band
    powers are proportional to the bandwidth, to within one bin."""
    n, fs, s = 2**16, 48_000.0, 0.3
    x = np.random.default_rng(7).normal(0.0, s, n)
    r = third_octave_levels(x, 1 / fs)
    assert len(r.index) >= 20
    width = r.upper - r.lower
    assert np.all(np.abs(r.bins - width / r.resolution) < 1.0)
    q = r.mean_square * n / s**2
    lo, hi = stats.chi2.ppf(1e-6, 2 * r.bins), stats.chi2.ppf(1 - 1e-6, 2 * r.bins)
    assert np.all((q > lo) & (q < hi)), np.c_[r.nominal, q / (2 * r.bins)]
    # per unit bandwidth, the wide bands (>= 200 bins) agree with s^2 / (fs/2) within 5 sigma
    wide = r.bins >= 200
    density = r.mean_square[wide] / (r.bins[wide] * r.resolution)
    np.testing.assert_allclose(density, s**2 / (fs / 2), rtol=5 / np.sqrt(200))


def test_only_bands_with_three_bins_below_nyquist_are_reported():
    # df = 1 Hz: the 6.3 Hz band [5.62, 7.08) holds bins 6, 7; the 8 Hz band [7.08, 8.91)
    # holds bin 8; the 10 Hz band [8.91, 11.22) holds 9, 10, 11; 12.5: 12-14; 16: 15-17;
    # 20 Hz [17.78, 22.39): 18-22. At the top, the 5 kHz band ends at 5623 Hz > 5000 Hz.
    x = np.random.default_rng(1).normal(size=N) + 3 * np.sin(2 * np.pi * 6.0 * np.arange(N) * DT)
    r = third_octave_levels(x, DT)
    assert r.nominal[:4].tolist() == [10.0, 12.5, 16.0, 20.0]
    assert r.bins[:4].tolist() == [3, 3, 3, 5]
    assert r.nominal[-1] == 4000.0 and r.upper[-1] <= FS / 2 < r.upper[-1] * 10**0.1
    assert np.all(r.bins >= 3) and r.resolution == pytest.approx(1.0)
    # the 6 Hz sine (4.5 units^2, in an unreported 2-bin band) is in no reported band
    assert r.mean_square.sum() < 0.5 * r.total_mean_square
    short = third_octave_levels(np.arange(4.0), DT)  # too short for any band
    assert short.index.size == 0 and short.level_dB.size == 0


def test_welch_normalisation_keeps_the_windowed_sum_rule():
    rng = np.random.default_rng(2)
    x = rng.normal(size=4096) + np.linspace(0, 1, 4096)
    w = Welch(segment=512, overlap=0.5)
    r = third_octave_levels(x, DT, welch=w)
    # by hand: segments start every 256 samples, each has its own mean removed, is
    # weighted by the Hann window (periodic, as scipy's default), and its windowed
    # mean square sum w^2 y^2 / sum w^2 is averaged over the segments
    y = x - x.mean()
    hann = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(512) / 512)
    starts = range(0, 4096 - 512 + 1, 256)
    expected = np.mean(
        [np.sum(hann**2 * (y[s : s + 512] - y[s : s + 512].mean()) ** 2) / np.sum(hann**2) for s in starts]
    )
    assert r.segments == len(starts) == 15
    assert r.total_mean_square == pytest.approx(expected, rel=1e-12)
    assert r.resolution == pytest.approx(FS / 512)
    # boxcar, no overlap: exactly the mean of the segments' variances
    box = third_octave_levels(x, DT, welch=Welch(segment=1024, overlap=0.0, window="boxcar"))
    assert box.total_mean_square == pytest.approx(np.mean(x.reshape(4, 1024).var(axis=1)), rel=1e-12)


def test_welch_agrees_with_the_plain_estimate_on_white_noise():
    """Both estimate the band power density s^2 / (fs/2). The plain band of m bins has the
    relative standard deviation 1/sqrt(m) (chi2(2m)). A Welch band of m' bins over K Hann
    segments overlapping by half: a bin's power has a relative variance 1, neighbours
    1 and 2 bins apart correlate by (1/4 / 3/8)^2 = 4/9 and (1/16 / 3/8)^2 = 1/36, and
    consecutive segments by at most (1/3)^2 + 2 (1/6)^2 = 1/6 in all; so the relative
    variance is below (1 + 8/9 + 1/18)(1 + 2/6) / (m' K) < 3 / (m' K). Bands must agree
    within 5 combined standard deviations."""
    n, fs, s = 2**16, 48_000.0, 1.5
    x = np.random.default_rng(11).normal(0.0, s, n)
    plain = third_octave_levels(x, 1 / fs)
    welch = third_octave_levels(x, 1 / fs, welch=Welch(segment=1024))
    assert welch.segments == 1 + (n - 1024) // 512
    common, ip, iw = np.intersect1d(plain.index, welch.index, return_indices=True)
    assert common.size >= 10
    dp = plain.mean_square[ip] / (plain.bins[ip] * plain.resolution)
    dw = welch.mean_square[iw] / (welch.bins[iw] * welch.resolution)
    sigma = np.sqrt(1 / plain.bins[ip] + 3 / (welch.bins[iw] * welch.segments))
    assert np.all(np.abs(dw / dp - 1) < 5 * sigma)
    sigma_w = np.sqrt(3 / (welch.bins * welch.segments))
    assert np.all(np.abs(welch.mean_square / (welch.bins * welch.resolution) / (s**2 / (fs / 2)) - 1) < 5 * sigma_w)


@pytest.mark.parametrize(
    "options, word",
    [
        (dict(segment=4), "segment"),
        (dict(segment=64, overlap=1.0), "overlap"),
        (dict(segment=64, window="nonsense"), "window"),
        (dict(segment=8, overlap=0.99), "no step"),
    ],
)
def test_bad_welch_options_name_the_field(options, word):
    with pytest.raises(SceneError, match=word):
        Welch(**options)


def test_bad_signals_are_refused():
    with pytest.raises(SceneError, match="longer than the signal"):
        third_octave_levels(np.zeros(100), DT, welch=Welch(segment=128))
    with pytest.raises(ValueError, match="not finite"):
        third_octave_levels(np.array([0.0, np.nan, 1.0]), DT)
    with pytest.raises(ValueError, match="dt"):
        third_octave_levels(np.zeros(10), 0.0)
    with pytest.raises(ValueError, match="reference"):
        third_octave_levels(np.zeros(10), DT, reference=-1.0)
