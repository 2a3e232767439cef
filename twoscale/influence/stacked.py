"""Products on stacks of fields (B, ny, nx) through padded buffers the product keeps: the
two-level iteration's stacked local solves (:mod:`twoscale.micro.pk_stack`) apply one
canvas's operator and its approximate inverse to stacks of one shape some thousands of
times a solve, and ``scipy.fft``'s functions allocate a padded input, a padded spectrum
and every output for each (on 4,548 paraboloids under load: the zero padding along x
alone 4.9 of 87 profiled seconds, ``numpy.zeros`` 2.0). Here the same pocketfft
transforms, in the same order and with the same normalisations, write into arrays kept
with the product (:mod:`.transforms`): the same values to the bit, without the fresh
arrays. Each product's buffers hold as many fields as the largest stack it was given
(the first, as a rule: a stack's rows leave it as they converge) and live as long as
the product, which its caller keeps for one solve."""

from __future__ import annotations

from typing import Callable

import numpy as np

from .transforms import fft_in_place, irfft_into, irfftn_into, rfft_into, rfftn_into


class _Buffers:
    """Arrays of ``shapes`` (each without the leading stack axis) and ``dtypes``, zero when
    made, for stacks of up to :attr:`capacity` fields; :meth:`take` gives the first ``b``
    of each (made again, larger, when ``b`` exceeds the capacity)."""

    def __init__(self, shapes: tuple, dtypes: tuple):
        self.shapes, self.dtypes = shapes, dtypes
        self.capacity, self._arrays = 0, ()

    def take(self, b: int) -> tuple:
        if b > self.capacity:
            self._arrays = tuple(np.zeros((b, *s), d) for s, d in zip(self.shapes, self.dtypes))
            self.capacity = b
        return tuple(a[:b] for a in self._arrays)

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in self._arrays)


class KeptStackProduct:
    """A zero-padded FFT convolution's ``apply_stack`` (:class:`.convolution.ConvolutionOperator`
    and its float32 form) through kept buffers: the stack's fields go into the padded field
    (its padding rows stay 0), the transform along y is written into the padded spectrum and
    the one along x runs in place (its padding columns set to 0 first), the kernel multiplies
    it in place (``times_kernel``), the transforms back run in place and into the field
    back; the target's rows of it are returned as a new float64 stack.

    Parameters
    ----------
    fft_shape : (my, mx)
        The padded transform's shape.
    source_shape, target_shape : (ny, nx)
        The operator's grids.
    times_kernel : callable
        Multiplies a spectrum stack by the kernel spectrum in place.
    dtype : numpy dtype
        The transforms' real precision (float32 or float64).
    """

    def __init__(self, fft_shape, source_shape, target_shape, times_kernel: Callable, dtype):
        (my, mx), (self.ny, self.nx), (self.tny, self.tnx) = fft_shape, source_shape, target_shape
        self.my, self._times_kernel = my, times_kernel
        complex_type = np.result_type(dtype, np.complex64)
        self._buffers = _Buffers(((my, self.nx), (my // 2 + 1, mx), (my, self.tnx)), (dtype, complex_type, dtype))

    def __call__(self, P: np.ndarray) -> np.ndarray:
        padded, spectrum, back = self._buffers.take(len(P))
        padded[:, : self.ny] = P
        rfft_into(padded, -2, spectrum[..., : self.nx])
        spectrum[..., self.nx :] = 0.0
        fft_in_place(spectrum, -1, forward=True)
        self._times_kernel(spectrum)
        fft_in_place(spectrum, -1, forward=False)
        sy, sx = self.ny - 1, self.nx - 1
        irfft_into(spectrum[..., sx : sx + self.tnx], -2, self.my, back)
        return back[:, sy : sy + self.tny].astype(np.float64)

    @property
    def nbytes(self) -> int:
        """Bytes the buffers hold now."""
        return self._buffers.nbytes


class KeptStackInverse:
    """:class:`.circulant.CirculantInverse`'s ``apply_stack`` through kept buffers: the
    fields into the torus's field (0 beyond them), its two-axis real transform into the kept
    spectrum, the multiplier in place, the two-axis transform back into the kept field back
    (pocketfft's two-axis calls, as ``scipy.fft.rfft2`` and ``irfft2`` make them), the
    fields' part of it returned as a new float64 stack."""

    def __init__(self, torus: tuple, shape: tuple, multiplier: np.ndarray):
        (ly, lx), (self.ny, self.nx) = torus, shape
        self.lx, self._m = lx, multiplier
        dtype = multiplier.dtype
        complex_type = np.result_type(dtype, np.complex64)
        self._buffers = _Buffers(((ly, lx), (ly, lx // 2 + 1), (ly, lx)), (dtype, complex_type, dtype))

    def __call__(self, V: np.ndarray) -> np.ndarray:
        field, spectrum, back = self._buffers.take(len(V))
        field[:, : self.ny, : self.nx] = V
        rfftn_into(field, spectrum)
        spectrum *= self._m
        irfftn_into(spectrum, self.lx, back)
        return back[:, : self.ny, : self.nx].astype(np.float64)

    @property
    def nbytes(self) -> int:
        """Bytes the buffers hold now."""
        return self._buffers.nbytes
