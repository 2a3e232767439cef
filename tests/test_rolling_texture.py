"""Texture figures of profiles whose mean profile depth and texture levels are known.

Profiles are sampled at x_i = (i + 1/2) dx inside each 100 mm segment, so that a segment's
samples are symmetric about its centre: a profile even about the centre has a
least-squares slope of exactly zero, and slope suppression only removes its mean.
"""

import json

import numpy as np
import pytest

from twoscale.errors import SurfaceError
from twoscale.rolling.texture import mean_profile_depth, road_texture, texture_spectrum

DX = 0.1  # mm
U = (np.arange(1000) + 0.5) * DX - 50.0  # position from a segment's centre, mm


def _square(A, duty=0.5, period=10.0):
    """+A on a fraction ``duty`` of each period (centred on the crests of cos(2 pi u / p)),
    -A elsewhere; even in u."""
    wrapped = (U + period / 2) % period - period / 2
    return np.where(np.abs(wrapped) < duty * period / 2, A, -A)


@pytest.mark.parametrize("duty", [0.5, 0.25])
def test_mpd_of_a_square_wave(duty):
    """A two-level profile (+A on a fraction f of the samples, -A elsewhere), even about the
    segment centre: slope suppression removes only its mean A (2f - 1); each 50 mm half
    holds +A samples (5 periods of 10 mm each), so both peaks are +A and
    MSD = A - A (2f - 1) = 2 A (1 - f); f = 1/2 gives MPD = A."""
    A = 0.8
    z = _square(A, duty)
    f = np.mean(z > 0)  # the sampled duty (0.24 for 0.25 at 0.1 mm)
    assert abs(f - duty) < 0.011
    m = mean_profile_depth(z, DX)
    assert m.mpd == pytest.approx(2 * A * (1 - f), rel=1e-12)
    if duty == 0.5:
        assert m.mpd == pytest.approx(A, rel=1e-12)
    assert m.segment_samples == 1000 and m.segments_used == 1
    assert m.etd == pytest.approx(0.2 + 0.8 * m.mpd)


def test_mpd_of_a_sine_is_its_sampled_crest():
    """A cos(2 pi u / p), whole periods, even about the centre: zero mean, zero slope; the
    samples nearest the crests lie dx/2 away, so each half's peak is A cos(pi dx / p)
    (A for a continuous profile)."""
    A, p = 0.5, 10.0
    m = mean_profile_depth(A * np.cos(2 * np.pi * U / p), DX)
    assert m.mpd == pytest.approx(A * np.cos(np.pi * DX / p), rel=1e-12)


def test_mpd_takes_one_peak_per_half():
    """Three spikes on a flat segment: 2 at u = -24.95 mm, 1 at 14.95 mm and 1 at 34.95 mm.
    Their first moment is -49.9 + 14.95 + 34.95 = 0, so the regression slope is zero and
    slope suppression removes only the mean 4/1000 mm; the first half's peak is 2, the
    second half's 1: MSD = (2 + 1)/2 - 0.004 = 1.496 mm."""
    z = np.zeros(1000)
    for u, v in [(-24.95, 2.0), (14.95, 1.0), (34.95, 1.0)]:
        z[int(np.argmin(np.abs(U - u)))] = v
    assert np.sum(U * z) == pytest.approx(0.0, abs=1e-12)
    assert mean_profile_depth(z, DX).mpd == pytest.approx(1.5 - 0.004, rel=1e-12)


def test_mpd_removes_the_slope_of_a_tilted_profile():
    # the square wave's own regression line is flat, so that of the sum is the added line:
    # suppressing it gives back MPD = A (without it, the peaks would differ by 2.5 mm)
    A = 0.8
    tilted = _square(A) + 3.0 + 0.05 * (U + 50.0)
    assert mean_profile_depth(tilted, DX).mpd == pytest.approx(A, rel=1e-10)


def test_mpd_of_a_strip_averages_lines_and_segments_and_drops_the_tail():
    amplitudes = np.array([0.2, 0.5, 1.1])
    tail = np.full(600, 50.0)  # 60 mm after the third segment: not used
    tail[::7] = -50.0
    strip = np.stack([np.concatenate([_square(a)] * 3 + [tail]) for a in amplitudes])
    m = mean_profile_depth(strip, DX)
    assert m.segment_msd.shape == (3, 3) and m.segments_used == 9 and m.segments_dropped == 0
    np.testing.assert_allclose(m.line_mpd, amplitudes, rtol=1e-12)
    assert m.mpd == pytest.approx(amplitudes.mean(), rel=1e-12)


def test_mpd_fills_short_dropouts_and_leaves_out_segments_missing_too_much():
    A = 0.8
    first = _square(A)
    inner = np.flatnonzero((first[1:-1] == first[:-2]) & (first[1:-1] == first[2:])) + 1
    first[inner[::3][:50]] = np.nan  # 5 % missing, single samples inside plateaus
    second = _square(3 * A)
    second[100:300] = np.nan  # 20 % missing: left out
    m = mean_profile_depth(np.concatenate([first, second]), DX)
    # linear interpolation between equal neighbours restores the plateaus exactly
    assert m.mpd == pytest.approx(A, rel=1e-12)
    assert m.segments_used == 1 and m.segments_dropped == 1
    assert np.isnan(m.segment_msd[0, 1])
    with pytest.raises(SurfaceError, match="missing"):
        mean_profile_depth(np.full(1200, np.nan), DX)


def test_a_strip_shorter_than_one_segment_is_refused():
    with pytest.raises(SurfaceError, match=r"80 mm long.*shorter than one 100 mm segment"):
        mean_profile_depth(np.zeros((4, 800)), DX)
    with pytest.raises(SurfaceError, match="spacing"):
        mean_profile_depth(np.zeros(2000), 0.0)
    with pytest.raises(SurfaceError, match="every line has more than 10% missing"):
        texture_spectrum(np.full((2, 100), np.nan), DX)


L, H = 800.0, 0.25  # texture profile: 800 mm at 0.25 mm, 3200 samples
X = np.arange(int(L / H)) * H
XC = 0.5 * (X[0] + X[-1])


def test_texture_level_of_a_sinusoid_in_its_band():
    """A cos(2 pi (x - xc) / 8 mm) over 100 whole periods, even about the profile's centre
    (no trend to remove), is bin-exact at 1/8 per mm, inside the 8 mm band (centre
    10^0.9 = 7.94 mm, edges 7.08 ... 8.91 mm): its mean square A^2/2 gives
    L = 20 log10(A / sqrt(2) / 1 um) there; the other bands see FFT rounding only."""
    A = 0.3
    s = texture_spectrum(A * np.cos(2 * np.pi * (X - XC) / 8.0), H)
    b = int(np.flatnonzero(s.nominal == 8.0)[0])
    assert s.wavelength[b] == pytest.approx(10**0.9, rel=1e-14)
    assert s.level_dB[b] == pytest.approx(20 * np.log10(A / np.sqrt(2) / 1e-3), abs=1e-9)
    assert np.all(np.delete(s.level_dB, b) < s.level_dB[b] - 200)
    # bands resolved by 800 mm at 0.25 mm (df = 1/800 per mm, Nyquist 2 per mm): 80 mm
    # holds bins 9-11 (100 mm only bin 8), 0.63 mm ends at 1.78 per mm (0.5 mm at 2.24)
    assert s.nominal[0] == 80.0 and s.nominal[-1] == 0.63 and np.all(s.bins >= 3)
    assert s.resolution == pytest.approx(1 / L)


def test_texture_levels_are_power_averages_over_lines():
    amplitudes = np.array([0.1, 0.3, 0.05])
    strip = amplitudes[:, None] * np.cos(2 * np.pi * (X - XC) / 20.0)[None, :]
    broken = strip[0].copy()
    broken[::5] = np.nan  # 20 % missing: this line is left out
    s = texture_spectrum(np.vstack([strip, broken]), H)
    b = int(np.flatnonzero(s.nominal == 20.0)[0])
    expected = 10 * np.log10(np.mean(amplitudes**2 / 2) / 1e-6)  # not the mean of the levels
    assert s.level_dB[b] == pytest.approx(expected, abs=1e-9)
    assert s.lines == 3 and s.lines_dropped == 1


def test_texture_spectrum_removes_a_tilt():
    A = 0.3
    z = A * np.cos(2 * np.pi * (X - XC) / 8.0)
    tilted = texture_spectrum(z + 0.01 * X + 2.0, H)
    flat = texture_spectrum(z, H)
    np.testing.assert_allclose(tilted.mean_square, flat.mean_square, rtol=1e-8, atol=1e-20)


def test_texture_json_holds_the_mpd_and_the_spectrum():
    z = np.vstack([_square(0.8)] * 2)
    t = road_texture(z, DX)
    d = json.loads(json.dumps(t.to_json_dict(), allow_nan=False))
    assert d["mean_profile_depth"]["mpd_mm"] == pytest.approx(0.8)
    assert d["mean_profile_depth"]["segments_used"] == 2
    spec = d["texture_spectrum"]
    assert len(spec["wavelength_mm"]) == len(spec["level_dB"]) == len(spec["bins"]) > 0
    assert d["strip"]["length_mm"] == pytest.approx(100.0) and d["units"]["level"] == "dB re 1 um"
