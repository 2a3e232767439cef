"""The spectrum of a zero-padded convolution whose kernel is even in both offsets (Love's, on
a grid's self pair), and its table back from that spectrum, by cosine transforms of the
kernel's quadrant: the operator's set-up without the transforms of its whole padded table."""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft

#: Grids from this many cells take their self operator's spectrum and table by the cosine
#: transforms of the kernel's quadrant; below, the transforms of the whole table are as
#: cheap (CPU us a spectrum, whole table against quadrant: 64 x 64 cells 100 / 117, 100 x
#: 100 217 / 221, 128 x 128 422 / 392, 160 x 160 694 / 548; 6 x 6 10 / 51).
EVEN_MIN_CELLS = 16_384


def even_spectrum(quadrant: np.ndarray, shape: tuple[int, int]) -> np.ndarray | None:
    """:func:`.transforms.padded_spectrum` of a grid's self table (offsets ``-(n - 1) .. n -
    1`` an axis, padded to ``shape``) whose kernel is even in both offsets, from its
    ``quadrant`` (offsets ``0 .. n - 1``), or None when a padded length is odd. The table's transform is then a cosine sum of the
    quadrant per axis times the phase of the table's first offset ``-(n - 1)``: a type-I DCT
    of the quadrant zero-padded to ``N / 2 + 1`` entries an axis (``N`` the padded length)
    instead of the transforms of the whole padded table (997 x 997 cells: 0.028 against
    0.125 s; 1933 x 1933: 0.12 against 0.42 s; within 2e-16 of the largest)."""
    (my, mx), (ny, nx) = shape, quadrant.shape
    if my % 2 or mx % 2 or my < 2 * ny or mx < 2 * nx:
        return None
    cos = np.zeros((my // 2 + 1, nx))
    cos[:ny] = quadrant
    cos = sfft.dct(cos, type=1, axis=0, overwrite_x=True)
    padded = np.zeros((my // 2 + 1, mx // 2 + 1))
    padded[:, :nx] = cos
    cos = sfft.dct(padded, type=1, axis=1, overwrite_x=True)
    phase_y, phase_x = _phases(shape, (ny, nx))
    out = np.empty((my // 2 + 1, mx), complex)
    out[:, : mx // 2 + 1] = cos
    out[:, mx // 2 + 1 :] = cos[:, mx // 2 - 1 : 0 : -1]  # (the sum is even in kx: entry mx - kx)
    out *= phase_y[:, None]
    out *= phase_x[None, :]
    return out


def _phases(shape: tuple[int, int], origin: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """The phase of the table's first offset ``-(n - 1)`` along y (half spectrum) and x."""
    (my, mx), (ny, nx) = shape, origin
    ky, kx = np.arange(my // 2 + 1), np.arange(mx)
    return np.exp(-2j * np.pi * (ky * (ny - 1) % my) / my), np.exp(-2j * np.pi * (kx * (nx - 1) % mx) / mx)


def even_lattice(spectrum: np.ndarray, shape: tuple[int, int], origin: tuple[int, int], columns: int | None = None):
    """The padded lattice (``shape``, its first ``columns``; with ``columns`` up to the self
    table's, its rows too: the table itself) whose transform is ``spectrum``,
    :func:`even_spectrum`'s of a self table on a grid of ``origin`` cells (the kernel's
    offset ``-(n - 1)`` at index 0), by the inverse type-I DCTs of its real cosine sums
    (within rounding of the whole inverse transform; 997 x 997 cells: 0.02 against 0.05 s),
    or None when a padded length is odd."""
    (my, mx), (ny, nx) = shape, origin
    if my % 2 or mx % 2:
        return None
    phase_y, phase_x = _phases(shape, origin)
    cos = spectrum[:, : mx // 2 + 1] * np.conj(phase_y)[:, None]
    cos *= np.conj(phase_x[: mx // 2 + 1])[None, :]
    quadrant = sfft.idct(sfft.idct(cos.real, type=1, axis=0), type=1, axis=1)
    if columns is not None and columns <= 2 * nx - 1:  # (the offset table: no wrapped offsets)
        return unfolded(quadrant, 1 - ny, 2 * ny - 1, 1 - nx, columns)
    iy = np.abs((np.arange(my) - (ny - 1) + my // 2) % my - my // 2)
    ix = np.abs((np.arange(mx if columns is None else columns) - (nx - 1) + mx // 2) % mx - mx // 2)
    return np.take(np.take(quadrant, iy, axis=0), ix, axis=1)


def _spans(start: int, n: int) -> list:
    """The indices ``|start|, ..., |start + n - 1|`` as (slice of the ``n``, slice of the
    quadrant) pairs: the negative offsets a reversed run, then the others a forward one."""
    stop, spans = start + n - 1, []
    if start < 0:
        last = min(stop, -1)
        spans.append((slice(0, last - start + 1), slice(-start, -last - 1, -1)))
    if stop >= 0:
        first = max(start, 0)
        spans.append((slice(first - start, n), slice(first, stop + 1)))
    return spans


def unfolded(quadrant: np.ndarray, oy0: int, my: int, ox0: int, mx: int) -> np.ndarray:
    """The quadrant's values at rows ``|oy0 + m|`` and columns ``|ox0 + n|``, (my, mx):
    at most four block copies into the new table (a fold per axis with a transposed copy
    between them cost 28 ms on a 700 x 700 box's table, 1399 x 1399 entries)."""
    out = np.empty((my, mx), dtype=quadrant.dtype)
    for rows, qrows in _spans(oy0, my):
        for cols, qcols in _spans(ox0, mx):
            out[rows, cols] = quadrant[qrows, qcols]
    return out
