"""One-axis FFTs written into arrays the caller keeps: the float32 products and the
circulant inverse run the same transforms hundreds of times on fields of one shape, and
``scipy.fft`` allocates every output (and copies a strided input first). Through pocketfft's
own entry points (the ones ``scipy.fft`` calls) with ``out=``, the same transforms in the
same order: the same values to the bit, without the fresh arrays (on a 467 x 467 box's
float32 product, 960 x 960 padded: 5.3-7.6 against 7.7-9.8 ms, minimum of 150 calls on a
loaded machine). Where pocketfft's module is not found, the public functions."""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft

#: pocketfft's ``inorm``: no normalization, or divided by the transform's length.
_NONE, _BY_N = 0, 2


def _binding():
    """scipy's private binding of pocketfft (``c2c``, ``r2c``, ``c2r`` with ``out``, since
    scipy 1.4) if it is there and transforms a small field as ``scipy.fft`` does, else None."""
    try:
        from scipy.fft._pocketfft import pypocketfft as binding

        a = np.arange(12.0).reshape(3, 4)
        out = np.empty((3, 3), complex)
        binding.r2c(a, (1,), True, _NONE, out, 1)
        back = np.empty((3, 4))
        binding.c2r(binding.c2c(out, (0,), True, _NONE, None, 1), (0, 1), 4, False, _BY_N, back, 1)
        if np.allclose(out, sfft.rfft(a, axis=1)) and np.allclose(back, a):
            return binding
    except Exception:  # pragma: no cover - a scipy without it, or with another signature
        pass
    return None  # pragma: no cover


_pocketfft = _binding()


def rfft_into(a: np.ndarray, axis: int, out: np.ndarray) -> np.ndarray:
    """The real forward transform of ``a`` along ``axis`` written into ``out`` (its length
    along ``axis`` is ``a``'s // 2 + 1; ``out`` may be a strided view)."""
    if _pocketfft is None:  # pragma: no cover
        out[...] = sfft.rfft(a, axis=axis)
        return out
    return _pocketfft.r2c(a, (axis % a.ndim,), True, _NONE, out, 1)


def fft_in_place(a: np.ndarray, axis: int, forward: bool) -> np.ndarray:
    """The complex transform of ``a`` along ``axis`` in place, forward or backward (the
    backward one divided by the length, as ``scipy.fft.ifft``)."""
    if _pocketfft is None:  # pragma: no cover
        a[...] = (sfft.fft if forward else sfft.ifft)(a, axis=axis, overwrite_x=True)
        return a
    return _pocketfft.c2c(a, (axis % a.ndim,), forward, _NONE if forward else _BY_N, a, 1)


def irfft_into(a: np.ndarray, axis: int, n: int, out: np.ndarray) -> np.ndarray:
    """The backward real transform of ``a`` along ``axis`` to length ``n`` written into
    ``out``, divided by ``n`` (``scipy.fft.irfft``); ``a`` may be a strided view."""
    if _pocketfft is None:  # pragma: no cover
        out[...] = sfft.irfft(a, n=n, axis=axis)
        return out
    return _pocketfft.c2r(a, (axis % a.ndim,), n, False, _BY_N, out, 1)


def rfftn_into(a: np.ndarray, out: np.ndarray) -> np.ndarray:
    """The real forward transform of ``a`` along its last two axes written into ``out``
    (``scipy.fft.rfft2``: real along the last axis, then complex along the other)."""
    if _pocketfft is None:  # pragma: no cover
        out[...] = sfft.rfft2(a)
        return out
    return _pocketfft.r2c(a, (a.ndim - 2, a.ndim - 1), True, _NONE, out, 1)


def irfftn_into(a: np.ndarray, n: int, out: np.ndarray) -> np.ndarray:
    """The backward real transform of ``a`` along its last two axes (the last to length
    ``n``) written into ``out``, divided by the product of the lengths
    (``scipy.fft.irfft2``)."""
    if _pocketfft is None:  # pragma: no cover
        out[...] = sfft.irfft2(a, s=out.shape[-2:])
        return out
    return _pocketfft.c2r(a, (a.ndim - 2, a.ndim - 1), n, False, _BY_N, out, 1)


def padded_spectrum(a: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The zero-padded transform of ``a``'s last two axes to ``shape``, real along y and
    then complex along x (the layout of every ``ConvolutionOperator`` spectrum), in ``a``'s
    precision (float32 at least), as a new array: one padded field and the spectrum are
    made, the transform along y is written into the spectrum's first columns and the one
    along x runs in place (``scipy.fft.fft(..., n=)`` pads a copy of the spectrum)."""
    (my, mx), (ny, nx) = shape, a.shape[-2:]
    padded = np.zeros((*a.shape[:-2], my, nx), np.result_type(a.dtype, np.float32))
    padded[..., :ny, :] = a
    out = np.empty((*a.shape[:-2], my // 2 + 1, mx), np.result_type(padded.dtype, np.complex64))
    rfft_into(padded, -2, out[..., :nx])
    out[..., nx:] = 0.0
    return fft_in_place(out, -1, forward=True)


def padded_back(a: np.ndarray, my: int, start: int, n: int) -> np.ndarray:
    """The real field (..., ``my``, ``n``) back from a :func:`padded_spectrum` ``a``'s columns
    ``start .. start + n`` (after the transform back along x, run in place: ``a`` is
    overwritten), as a new array."""
    fft_in_place(a, -1, forward=False)
    out = np.empty((*a.shape[:-2], my, n), np.finfo(a.dtype).dtype)
    return irfft_into(a[..., start : start + n], -2, my, out)


def padded_transform(a: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The zero-padded transform of ``a``'s last two axes to ``shape`` in the layout of every
    :class:`~.convolution.ConvolutionOperator` spectrum: real along y (``shape[0] // 2 + 1`` rows kept),
    then complex along the contiguous x (a float32 product on 625 x 384 cells: 4.7-5.0 ms
    against 5.2-5.5 ms with ``rfft2``'s order)."""
    my, mx = shape
    ny = a.shape[-2]
    padded = np.zeros((*a.shape[:-2], my, a.shape[-1]), dtype=np.result_type(a.dtype, np.float32))
    padded[..., :ny, :] = a
    out = sfft.rfft(padded, axis=-2, overwrite_x=True)
    return sfft.fft(out, n=mx, axis=-1, overwrite_x=True)
