"""The float32 zero-padded FFT product on a part of a square grid (:class:`CellProduct`), in
one call or in its two halves: the forward transform of the values, whose Parseval sum
gives ``v.A v`` without the transforms back, and the transforms back.

The conjugate gradient's step length needs ``t.A t`` of its search direction ``t``, and the
displacement after the step either follows from ``A t`` or, after a step that clipped or
let in many cells, is a fresh product ``A p`` (``A t`` then serves the step length only).
The zero-padded convolution is a circular one on the padded torus, and with the kernel's
table starting at the offset ``-(n - 1)`` per axis the target's window starts ``n - 1``
cells in; so ``t.A t = sum_k |T_k|^2 K_k exp(2 pi i k.(n - 1) / M) / M`` over the torus's
frequencies ``k`` (``M`` its cells, ``T`` and ``K`` the spectra), where the kernel's factor
is real (Love's kernel is even) and positive. The product's layout keeps the half-spectrum
along y (real transform first): its inner rows count twice.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .transforms import fft_in_place, irfft_into, rfft_into

#: The Parseval sum and its weights run over blocks of the half-spectrum's rows of about this
#: many entries (their temporaries stay small beside the kept buffers on boxes of millions of
#: cells: the weights of a 2700 x 2700 padded grid, made whole, took a 29 MB complex temporary,
#: fresh pages, 65-75 ms in the solve; in blocks 15-20 ms).
ENERGY_CHUNK = 1 << 18
#: The transforms along y run on the columns that hold a cell only when those skip at least
#: this fraction of the grid's columns (gaps narrower than :data:`GAP_COLUMNS` filled in).
SKIP_FRACTION = 0.05
GAP_COLUMNS = 64


def column_runs(cells: np.ndarray, nx: int) -> list[tuple[int, int]] | None:
    """The runs ``[c0, c1)`` of the columns of a grid ``nx`` wide that hold one of the flat
    ``cells`` (gaps under :data:`GAP_COLUMNS` columns kept in the runs), or None when they
    skip less than :data:`SKIP_FRACTION` of the columns: the zero-padded transforms along
    y of the other columns are zero forward and unread back (a part on 84 % of a box's
    columns: a sixth of those transforms)."""
    held = np.flatnonzero(np.bincount(np.asarray(cells) % nx, minlength=nx))
    if held.size == 0:
        return None
    gaps = np.flatnonzero(np.diff(held) > GAP_COLUMNS)
    runs = list(zip(held[np.r_[0, gaps + 1]].tolist(), (held[np.r_[gaps, held.size - 1]] + 1).tolist()))
    covered = sum(c1 - c0 for c0, c1 in runs)
    return runs if covered <= (1.0 - SKIP_FRACTION) * nx else None


def energy_weights(khat: np.ndarray, source_shape: tuple[int, int], fft_shape: tuple[int, int]) -> np.ndarray:
    """The Parseval weights (float32, the half-spectrum's shape) of a square operator's kernel
    spectrum ``khat`` (complex64, the layout of ``ConvolutionOperator``): ``sum(w |T|^2)`` is
    ``t.A t`` for the spectrum ``T`` of a field ``t`` of ``source_shape``. From the float32
    spectrum the float32 products keep (1-2 ms on 1000 x 1000; from the float64 one 4-10
    ms), within 3e-8 of the largest weight."""
    (ny, nx), (my, mx) = source_shape, fft_shape
    py = np.exp(2j * np.pi * (np.arange(my // 2 + 1) * (ny - 1) % my) / my).astype(np.complex64)
    px = np.exp(2j * np.pi * (np.arange(mx) * (nx - 1) % mx) / mx).astype(np.complex64)
    w = np.empty(khat.shape, np.float32)
    step = max(1, ENERGY_CHUNK // mx)
    shifted = np.empty((min(step, len(khat)), mx), np.complex64)  # (blocks: no spectrum-sized temporary)
    for j in range(0, len(khat), step):
        block = shifted[: len(khat[j : j + step])]
        np.multiply(khat[j : j + step], px, out=block)
        block *= py[j : j + step, None]
        w[j : j + step] = block.real
    w[1 : (my + 1) // 2] *= 2.0  # (the rows whose mirror the real transform leaves out)
    w /= my * mx
    w.setflags(write=False)
    return w


def parseval_sum(a: np.ndarray, w: np.ndarray) -> float:
    """``sum(w |a|^2)`` of a complex64 half-spectrum ``a`` with float32 weights ``w`` of its
    shape, in blocks of about ``ENERGY_CHUNK`` entries (float32 terms summed in float64:
    2e-10 relative)."""
    total, step = 0.0, max(1, ENERGY_CHUNK // a.shape[1])
    for j in range(0, len(a), step):
        terms = np.square(a[j : j + step].real)
        terms += np.square(a[j : j + step].imag)
        terms *= w[j : j + step]
        total += float(terms.sum(dtype=np.float64))
    return total


class CellProduct:
    """``A v`` for pressures ``v`` on the flat ``cells`` of a square float32 convolution's
    grid (``op``: the float32 operator, whose kept transform buffers it shares): the values
    go straight into a padded float32 field of their own (the other cells stay 0) and the
    displacement comes back at those cells from the kept field back, both (m,) float64, the
    displacement in an array kept with this object (overwritten by the next product).
    ``cells`` None: every cell, through ``op``'s own padded field (no index arrays; a new array).

    Call it for the product, or :meth:`forward` and then :meth:`energy` and/or
    :meth:`finish`: between them no other product of ``op`` may run (they share its
    spectrum buffer)."""

    def __init__(self, op, cells: np.ndarray | None):
        (ny, nx), (my, _) = op.source.shape, op.fft_shape
        self.op = op
        self.spectrum: np.ndarray | None = None  # the forward half's, until finished
        self._model: Callable[[np.ndarray], float] | None = None  # (model_energy, made on first call)
        self._model_made = False
        if cells is None:
            self.at = self.back_at = self.padded = self.runs = None
            return
        self.at = np.asarray(cells, dtype=np.intp)
        self.back_at = self.at + (ny - 1) * nx  # the target's rows of the field back start at row ny - 1
        self.padded = np.zeros((my, nx), np.float32)
        self.runs = column_runs(self.at, nx)  # (None: the transforms of every column)
        self.gathered = np.empty(len(self.at), np.float32)  # the field back at the cells, kept
        self.out = np.empty(len(self.at))  # the product, kept (a fresh array each page-faulted)

    def __call__(self, values: np.ndarray) -> np.ndarray:
        return self.forward(values).finish()

    def forward(self, values: np.ndarray) -> "CellProduct":
        """The forward transforms of ``values`` (m,) into ``op``'s kept spectrum buffer."""
        op = self.op
        if self.padded is None:  # every cell: the operator's own padded field
            self.spectrum = op._spectrum_in_place(values.reshape(op.source.shape), op.buffers())
            return self
        self.padded.ravel()[self.at] = values
        if self.runs is None:
            self.spectrum = op._spectrum_in_place(None, (self.padded, *op.buffers()[1:]))
            return self
        spectrum, edge = op.buffers()[1], 0
        for c0, c1 in self.runs:  # (the same transforms of those columns; the others zero)
            spectrum[:, edge:c0] = 0.0
            rfft_into(self.padded[:, c0:c1], 0, spectrum[:, c0:c1])
            edge = c1
        spectrum[:, edge:] = 0.0
        self.spectrum = fft_in_place(spectrum, 1, forward=True)
        return self

    def energy(self) -> float:
        """``v.A v`` of the values :meth:`forward` took, by Parseval from their spectrum (a
        pass over the half-spectrum; the float32 spectrum's rounding, no transform back)."""
        if self.spectrum is None:
            raise RuntimeError("energy() needs forward() first")
        return parseval_sum(self.spectrum, self.op.energy_weights())

    def model_energy(self):
        """``v -> v.C v`` for values on these cells, ``C`` the kernel wrapped on the torus of
        the operator's preconditioner (``CirculantInverse.energy_on_cells``: its forward
        transforms alone), made on first call; None where the operator has none."""
        if not self._model_made:
            inverse = self.op.preconditioner() if hasattr(self.op, "preconditioner") else None
            self._model = None if inverse is None else inverse.energy_on_cells(self.at)
            self._model_made = True
        return self._model

    def finish(self) -> np.ndarray:
        """``A v`` at the cells (m,) float64, from the spectrum :meth:`forward` left."""
        a, op = self.spectrum, self.op
        if a is None:
            raise RuntimeError("finish() needs forward() first")
        self.spectrum = None
        a *= op._khat
        if self.runs is None:
            back = op._back_in_place(a, op.buffers())
        else:  # the transforms back along y of the cells' columns only
            back, sx, my = op.buffers()[2], op.source.nx - 1, op.fft_shape[0]
            fft_in_place(a, 1, forward=False)
            for c0, c1 in self.runs:
                irfft_into(a[:, sx + c0 : sx + c1], 0, my, back[:, c0:c1])
        if self.back_at is None:
            ny = op.source.ny
            return back[ny - 1 : 2 * ny - 1].ravel().astype(np.float64)
        # (into the kept values: fresh arrays each product page-faulted; "raise" buffers a copy)
        np.copyto(self.out, np.take(back.ravel(), self.back_at, out=self.gathered, mode="clip"))
        return self.out
