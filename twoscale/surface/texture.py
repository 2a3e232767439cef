"""Seeded synthetic road textures: packed chippings with a self-affine micro-roughness.

A stand-in for a laser-profilometer scan of a surface dressing or an asphalt concrete,
for examples, tests and benchmarks (real scans go through :mod:`.reading`). Stones are
half-ellipsoids of random size and orientation placed by random sequential addition
(no two closer than ``packing`` times the sum of their radii) and sunk into a flat
binder by a random depth; the micro-roughness is a Gaussian random field with the power
spectrum ``q^-2(1+H)`` between two wavelengths (Hurst exponent ``H``), filtered by FFT.
Heights in mm, larger is closer to the body (the tyre), rows y, columns x.
"""

from __future__ import annotations

import math

import numpy as np


def chippings(
    size: float,
    h: float,
    *,
    seed: int = 0,
    stone_radius=(2.0, 4.0),
    protrusion=(1.0, 2.5),
    packing: float = 0.85,
    attempts: int = 20_000,
) -> tuple[np.ndarray, np.ndarray]:
    """Heights (n, n) of stones on a flat binder at 0, and the stones ``(x, y, a)``.

    Parameters
    ----------
    size : float
        Side of the square sample, mm.
    h : float
        Spacing, mm.
    seed : int, default 0
    stone_radius : (float, float), default (2, 4)
        Range of the stones' larger half-axis, mm (uniform).
    protrusion : (float, float), default (1, 2.5)
        Range of the stones' top above the binder, mm (uniform).
    packing : float, default 0.85
        Smallest centre distance over the sum of the two larger half-axes.
    attempts : int, default 20000
        Random placements tried.
    """
    rng = np.random.default_rng(seed)
    n = int(round(size / h))
    x = (np.arange(n) + 0.5) * h
    z = np.zeros((n, n))
    placed = []
    for _ in range(attempts):
        a = rng.uniform(*stone_radius)
        c = np.array(rng.uniform(0.0, size, 2))
        if placed:
            p = np.asarray(placed)
            if np.any(np.hypot(p[:, 0] - c[0], p[:, 1] - c[1]) < packing * (p[:, 2] + a)):
                continue
        placed.append((c[0], c[1], a))
        _stamp(z, x, c, a, rng, protrusion)
    return z, np.asarray(placed)


def _stamp(z: np.ndarray, x: np.ndarray, c, a: float, rng, protrusion) -> None:
    """Raise ``z`` to one half-ellipsoid stone (half-axes a, b in plane, height e)."""
    b = a * rng.uniform(0.6, 1.0)
    top = rng.uniform(*protrusion)
    e = top + rng.uniform(0.5, 1.5)  # the sunk part lies below the binder
    phi = rng.uniform(0.0, math.pi)
    h = x[1] - x[0]
    lo = np.searchsorted(x, [c[0] - a - h, c[1] - a - h])
    hi = np.searchsorted(x, [c[0] + a + h, c[1] + a + h])
    X, Y = np.meshgrid(x[lo[0] : hi[0]] - c[0], x[lo[1] : hi[1]] - c[1])
    u = X * math.cos(phi) + Y * math.sin(phi)
    v = -X * math.sin(phi) + Y * math.cos(phi)
    s = 1.0 - (u / a) ** 2 - (v / b) ** 2
    stone = np.where(s > 0, e * np.sqrt(np.maximum(s, 0.0)) - (e - top), -np.inf)
    window = z[lo[1] : hi[1], lo[0] : hi[0]]
    np.maximum(window, stone, out=window)


def self_affine(
    n: int, h: float, *, seed: int = 0, rms: float = 0.02, hurst: float = 0.8, wavelengths=(0.3, 5.0)
) -> np.ndarray:
    """Gaussian self-affine roughness (n, n), mm, with the given rms height (mm)."""
    rng = np.random.default_rng(seed)
    q = 2.0 * math.pi * np.fft.fftfreq(n, d=h)
    Q = np.hypot(q[None, :], q[:, None])
    qmin, qmax = 2.0 * math.pi / wavelengths[1], 2.0 * math.pi / wavelengths[0]
    amp = np.where((Q >= qmin) & (Q <= qmax), np.maximum(Q, qmin) ** (-(1.0 + hurst)), 0.0)
    field = np.real(np.fft.ifft2(amp * np.fft.fft2(rng.standard_normal((n, n)))))
    return field * (rms / field.std()) if field.std() > 0 else field


def road(
    size: float = 50.0, h: float = 0.1, *, seed: int = 0, rms: float = 0.02, stone_radius=(2.0, 4.0)
) -> np.ndarray:
    """A road texture (n, n), mm: :func:`chippings` (stone radii uniform in
    ``stone_radius``, mm) plus :func:`self_affine` roughness."""
    z, _ = chippings(size, h, seed=seed, stone_radius=stone_radius)
    return z + self_affine(z.shape[0], h, seed=seed + 1, rms=rms)
