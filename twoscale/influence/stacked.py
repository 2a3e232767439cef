"""Products on stacks of fields (B, ny, nx) through padded buffers kept between calls: the
two-level iteration's stacked local solves (:mod:`twoscale.micro.pk_stack`) apply each
canvas's operator and its approximate inverse to stacks of one shape some thousands of
times a solve, and ``scipy.fft``'s functions allocate a padded input, a padded spectrum
and every output for each (on 4,548 paraboloids under load: the zero padding along x
alone 4.9 of 87 profiled seconds, ``numpy.zeros`` 2.0). Here the same pocketfft
transforms, in the same order and with the same normalisations, write into arrays carved
from one :class:`Workspace` that the products of a solve share (one call at a time): the
same values to the bit, without the fresh arrays. The workspace holds at most
:data:`WORKSPACE_BYTES`; a stack that needs more goes through in parts (each field's
transforms are its own: the parts give the whole stack's values)."""

from __future__ import annotations

from typing import Callable

import math

import numpy as np

from .transforms import fft_in_place, irfft_into, irfftn_into, rfft_into, rfftn_into


#: The bytes a :class:`Workspace` keeps at most. #162's canvases (4,548 paraboloids) take
#: 0.1 MB a field and stacks of up to ~1,000: whole, a float64 product needed up to 100 MB;
#: in parts of 4 MB (a few times the L2 cache) a stack of 600 fields of 40 x 40 cells
#: took 31 against 44 ms (float64) and 22 against 27 ms (float32) through ``scipy.fft``.
WORKSPACE_BYTES = 4 << 20
_ALIGN = 64


class Workspace:
    """Bytes for the stacked products of one solve, shared by them (they run one at a time:
    each call's arrays are carved again) and kept as long as the workspace; at most
    ``limit`` bytes unless one field needs more."""

    def __init__(self, limit: int = WORKSPACE_BYTES):
        self.limit = limit
        self._raw = np.empty(0, np.uint8)

    def fields(self, per_field: int) -> int:
        """How many fields of ``per_field`` bytes one part of a stack takes (at least 1)."""
        return max(1, self.limit // max(per_field, 1))

    def arrays(self, shapes: tuple, dtypes: tuple) -> tuple:
        """Arrays of ``shapes`` and ``dtypes`` (contents undefined), carved from the kept
        bytes (made again, larger, when they are too few)."""
        sizes = [_aligned(math.prod(s) * np.dtype(d).itemsize) for s, d in zip(shapes, dtypes)]
        if self._raw.size < sum(sizes) + _ALIGN:
            self._raw = np.empty(sum(sizes) + _ALIGN, np.uint8)
        at, out = (-self._raw.ctypes.data) % _ALIGN, []
        for shape, dtype, size in zip(shapes, dtypes, sizes):
            n = math.prod(shape) * np.dtype(dtype).itemsize
            out.append(self._raw[at : at + n].view(dtype).reshape(shape))
            at += size
        return tuple(out)

    @property
    def nbytes(self) -> int:
        return self._raw.nbytes


def _aligned(n: int) -> int:
    return -(-n // _ALIGN) * _ALIGN


def _in_parts(f: Callable, P: np.ndarray, out: np.ndarray, workspace: Workspace, per_field: int) -> np.ndarray:
    """``f(part, out_part)`` over parts of the stack ``P`` that fit ``workspace``."""
    step = workspace.fields(per_field)
    for i in range(0, len(P), step):
        f(P[i : i + step], out[i : i + step])
    return out


def _field_bytes(shapes: tuple, dtypes: tuple) -> int:
    """Bytes one field takes in a workspace: its arrays of ``shapes`` and ``dtypes``, aligned."""
    return sum(_aligned(math.prod(s) * np.dtype(d).itemsize) for s, d in zip(shapes, dtypes))


class KeptStackProduct:
    """A zero-padded FFT convolution's ``apply_stack`` (:class:`.convolution.ConvolutionOperator`
    and its float32 form) through a :class:`Workspace`: the stack's fields go into the padded
    field (its padding rows set to 0), the transform along y is written into the padded
    spectrum and the one along x runs in place (its padding columns set to 0 first), the
    kernel multiplies it in place (``times_kernel``), the transforms back run in place and
    into the field back, whose target rows are written into the new float64 stack returned.

    Parameters
    ----------
    op : GridOperator
        The convolution: its ``fft_shape`` (the padded transform's) and grids.
    times_kernel : callable
        Multiplies a spectrum stack by the kernel spectrum in place.
    dtype : numpy dtype
        The transforms' real precision (float32 or float64).
    workspace : Workspace, optional
        Shared with the caller's other stacked products (None: one of its own).
    """

    def __init__(self, op, times_kernel: Callable, dtype, workspace: Workspace | None = None):
        (my, mx), (self.ny, self.nx), (self.tny, self.tnx) = op.fft_shape, op.source.shape, op.target.shape
        self.my, self._times_kernel = my, times_kernel
        self.workspace = Workspace() if workspace is None else workspace
        self._shapes = ((my, self.nx), (my // 2 + 1, mx), (my, self.tnx))
        self._dtypes = (dtype, np.result_type(dtype, np.complex64), dtype)
        self._per_field = _field_bytes(self._shapes, self._dtypes)

    def __call__(self, P: np.ndarray) -> np.ndarray:
        out = np.empty((len(P), self.tny, self.tnx))
        return _in_parts(self._part, P, out, self.workspace, self._per_field)

    def _part(self, P: np.ndarray, out: np.ndarray) -> None:
        b = len(P)
        padded, spectrum, back = self.workspace.arrays(tuple((b, *s) for s in self._shapes), self._dtypes)
        padded[:, : self.ny] = P
        padded[:, self.ny :] = 0.0
        rfft_into(padded, -2, spectrum[..., : self.nx])
        spectrum[..., self.nx :] = 0.0
        fft_in_place(spectrum, -1, forward=True)
        self._times_kernel(spectrum)
        fft_in_place(spectrum, -1, forward=False)
        sy, sx = self.ny - 1, self.nx - 1
        irfft_into(spectrum[..., sx : sx + self.tnx], -2, self.my, back)
        out[...] = back[:, sy : sy + self.tny]


class KeptStackInverse:
    """:class:`.circulant.CirculantInverse`'s ``apply_stack`` through a :class:`Workspace`:
    the fields into the torus's field (0 beyond them), its two-axis real transform into the
    spectrum, the multiplier in place, the two-axis transform back into the field back
    (pocketfft's two-axis calls, as ``scipy.fft.rfft2`` and ``irfft2`` make them), the
    fields' part of it written into the new float64 stack returned."""

    def __init__(self, torus: tuple, shape: tuple, multiplier: np.ndarray, workspace: Workspace | None = None):
        (ly, lx), (self.ny, self.nx) = torus, shape
        self.lx, self._m = lx, multiplier
        self.workspace = Workspace() if workspace is None else workspace
        self._shapes = ((ly, lx), (ly, lx // 2 + 1), (ly, lx))
        self._dtypes = (multiplier.dtype, np.result_type(multiplier.dtype, np.complex64), multiplier.dtype)
        self._per_field = _field_bytes(self._shapes, self._dtypes)

    def __call__(self, V: np.ndarray) -> np.ndarray:
        out = np.empty((len(V), self.ny, self.nx))
        return _in_parts(self._part, V, out, self.workspace, self._per_field)

    def _part(self, V: np.ndarray, out: np.ndarray) -> None:
        b = len(V)
        field, spectrum, back = self.workspace.arrays(tuple((b, *s) for s in self._shapes), self._dtypes)
        field[:, : self.ny, : self.nx] = V
        field[:, : self.ny, self.nx :] = 0.0
        field[:, self.ny :] = 0.0
        rfftn_into(field, spectrum)
        spectrum *= self._m
        irfftn_into(spectrum, self.lx, back)
        out[...] = back[:, : self.ny, : self.nx]
