"""A seeded road strip (length along x, width along y): a chip seal of the kind
:mod:`twoscale.surface.texture` makes on a square, laid out on a rectangle so that a
metre-long section has no seams. Heights in mm, larger is closer to the body; rows y,
columns x.
"""

from __future__ import annotations

import math

import numpy as np


def road_strip(
    length: float,
    width: float,
    h: float,
    *,
    seed: int = 0,
    stone_radius=(2.0, 4.0),
    protrusion=(1.0, 2.5),
    packing: float = 0.85,
    rms: float = 0.02,
) -> np.ndarray:
    """Heights (ny, nx) of a chip-seal strip, mm: stones (half-ellipsoids, larger half-axis
    uniform in ``stone_radius`` mm, tops ``protrusion`` mm above a flat binder) placed by
    random sequential addition at the density of :func:`twoscale.surface.texture.chippings`,
    plus a self-affine micro-roughness of ``rms`` mm.

    Parameters
    ----------
    length, width : float
        Size of the strip along x and y, mm.
    h : float
        Spacing, mm.
    seed : int, default 0
    """
    rng = np.random.default_rng(seed)
    nx, ny = int(round(length / h)), int(round(width / h))
    x, y = (np.arange(nx) + 0.5) * h, (np.arange(ny) + 0.5) * h
    z = np.zeros((ny, nx))
    attempts = int(20_000 * length * width / 50.0**2)  # the square texture's density of tries
    cells: dict = {}
    cell = 2.0 * stone_radius[1]
    for _ in range(attempts):
        a = rng.uniform(*stone_radius)
        c = np.array([rng.uniform(0.0, length), rng.uniform(0.0, width)])
        key = (int(c[0] // cell), int(c[1] // cell))
        near = [p for dx in (-1, 0, 1) for dy in (-1, 0, 1) for p in cells.get((key[0] + dx, key[1] + dy), ())]
        if any(math.hypot(p[0] - c[0], p[1] - c[1]) < packing * (p[2] + a) for p in near):
            continue
        cells.setdefault(key, []).append((c[0], c[1], a))
        _stamp(z, x, y, c, a, rng, protrusion)
    return z + (_roughness(ny, nx, h, seed=seed + 1, rms=rms) if rms > 0 else 0.0)


def _roughness(
    ny: int, nx: int, h: float, *, seed: int, rms: float, hurst: float = 0.8, wavelengths=(0.3, 5.0)
) -> np.ndarray:
    """Gaussian self-affine roughness (ny, nx), mm, of rms ``rms``: the spectrum of
    :func:`twoscale.surface.texture.self_affine` on a rectangle."""
    rng = np.random.default_rng(seed)
    qx, qy = 2.0 * math.pi * np.fft.rfftfreq(nx, d=h), 2.0 * math.pi * np.fft.fftfreq(ny, d=h)
    Q = np.hypot(qx[None, :], qy[:, None])
    qmin, qmax = 2.0 * math.pi / wavelengths[1], 2.0 * math.pi / wavelengths[0]
    amp = np.where((Q >= qmin) & (Q <= qmax), np.maximum(Q, qmin) ** (-(1.0 + hurst)), 0.0)
    field = np.fft.irfft2(amp * np.fft.rfft2(rng.standard_normal((ny, nx))), s=(ny, nx))
    return field * (rms / field.std()) if field.std() > 0 else field


def _stamp(z: np.ndarray, x: np.ndarray, y: np.ndarray, c, a: float, rng, protrusion) -> None:
    """Raise ``z`` to one half-ellipsoid stone (half-axes a, b in plane, height e)."""
    b = a * rng.uniform(0.6, 1.0)
    top = rng.uniform(*protrusion)
    e = top + rng.uniform(0.5, 1.5)  # the sunk part lies below the binder
    phi = rng.uniform(0.0, math.pi)
    h = x[1] - x[0]
    i0, i1 = np.searchsorted(x, [c[0] - a - h, c[0] + a + h])
    j0, j1 = np.searchsorted(y, [c[1] - a - h, c[1] + a + h])
    X, Y = np.meshgrid(x[i0:i1] - c[0], y[j0:j1] - c[1])
    u = X * math.cos(phi) + Y * math.sin(phi)
    v = -X * math.sin(phi) + Y * math.cos(phi)
    s = 1.0 - (u / a) ** 2 - (v / b) ** 2
    stone = np.where(s > 0, e * np.sqrt(np.maximum(s, 0.0)) - (e - top), -np.inf)
    window = z[j0:j1, i0:i1]
    np.maximum(window, stone, out=window)
