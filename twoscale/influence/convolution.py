"""Zero-padded FFT products with a translation-invariant kernel: the operator the half-space
(and every body that adds a correction to it) gives for a pair of grids, its float32 and
transposed forms, and the spectrum layout they and the circulant preconditioner share."""

from __future__ import annotations

import copy
from typing import Callable

import numpy as np
import scipy.fft as sfft

from ..grid import Grid
from .base import GridOperator
from .circulant import CirculantInverse
from .on_cells import CellProduct, energy_weights
from .stacked import KeptStackProduct, Workspace
from .table_columns import GridColumns, TargetColumns
from .even_kernel import even_lattice, even_spectrum, unfolded
from .transforms import fft_in_place, irfft_into, padded_back, padded_spectrum, padded_transform, rfft_into


def _inverse(spectrum: np.ndarray, shape: tuple[int, int], columns: int | None = None, even=None) -> np.ndarray:
    """The real array of ``shape`` whose :func:`.transforms.padded_transform` is ``spectrum``
    (its first ``columns`` only); ``even``: the grid shape of a self table whose kernel is
    even in both offsets (by its quadrant: :func:`.even_kernel.even_lattice`)."""
    out = None if even is None else even_lattice(spectrum, shape, even, columns)
    if out is not None:
        return out
    a = sfft.ifft(spectrum, axis=-1)
    if columns is None:
        return sfft.irfft(a, n=shape[0], axis=-2)
    return irfft_into(a[..., :columns], -2, shape[0], np.empty((*a.shape[:-2], shape[0], columns)))


class ConvolutionOperator(GridOperator):
    """Zero-padded (non-periodic) FFT convolution with a translation-invariant kernel.

    ``table[m, n]`` is the kernel at lattice offset ``(oy0 + m, ox0 + n)`` between a
    target and a source cell, covering every offset that occurs; the product is then
    exactly the linear convolution, computed in ``O(n log n)``. ``again``, if given,
    returns that same table when it is cheap to have again (e.g. gathered from a cache of
    kernel values the caller keeps), else None: :meth:`offset_table` then takes it instead
    of an inverse transform, and the operator does not hold the table meanwhile. ``even``:
    a self pair whose kernel is even in both offsets, ``table`` its quadrant (:mod:`.even_kernel`).
    """

    _even: tuple | None = None  # (the self grid's shape when ``even``; a transposed pair: None)

    def __init__(self, target: Grid, source: Grid, table: np.ndarray, again: Callable | None = None, even=False):
        self.target, self.source = target, source
        self._again = again
        my, mx = (2 * source.ny - 1, 2 * source.nx - 1) if even else table.shape
        self._shape = (sfft.next_fast_len(my, real=True), sfft.next_fast_len(mx, real=True))
        # (:func:`.transforms.padded_transform`'s values without its spectrum-sized copy: 700 x 700 cells'
        # table, 24 against 19 ms)
        self._even = source.shape if even else None
        self._khat = None if self._even is None else even_spectrum(table, self._shape)
        if self._khat is None:  # (an odd padded length: the whole table's transforms)
            table = unfolded(table, 1 - source.ny, my, 1 - source.nx, mx) if even else table
            self._khat = padded_spectrum(table, self._shape)
        # transforms derived from the kernel (the preconditioner's, the float32 spectrum),
        # made on first use and shared with the moved copies of this operator
        self._derived: dict = {}

    def apply(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, dtype=float)
        if p.shape != self.source.shape:
            raise ValueError(f"pressure has shape {p.shape}, expected {self.source.shape}")
        return self._finish(self._times_kernel(padded_transform(p, self._shape)))

    def apply_stack(self, P: np.ndarray) -> np.ndarray:
        """:meth:`apply` on a stack (B, ny, nx): the same transforms along the last two axes,
        one call each for the whole stack."""
        return self.finish(self._times_kernel(self.spectrum(np.asarray(P, dtype=float))))

    def kept_stack(self, workspace: Workspace | None = None) -> KeptStackProduct:
        """:meth:`apply_stack` through ``workspace``'s buffers (:mod:`.stacked`; bit for bit)."""
        return KeptStackProduct(self, self._times_kernel, np.float64, workspace)

    def _times_kernel(self, a: np.ndarray) -> np.ndarray:
        """``a`` (a source spectrum) times the kernel spectrum, in place."""
        a *= self._khat
        return a

    # The three stages of apply (GridOperator), for callers that sum the products of many
    # sources onto one target: operators with the same ``fft_shape`` and source shape accept
    # each other's spectra, and sums of ``multiply`` results go through one ``finish``.
    @property
    def fft_shape(self) -> tuple[int, int]:
        """Shape of the zero-padded transform."""
        return self._shape

    @property
    def source_key(self) -> tuple:
        return ("fft", self._shape, self.source.shape)

    @property
    def target_key(self) -> tuple:  # (finish keeps the target's window behind the source's padding)
        return ("fft", self._shape, self.source.shape, self.target)

    def spectrum(self, p: np.ndarray) -> np.ndarray:
        """Half-spectrum of the zero-padded source pressure (``source.shape``, or a stack of
        them along a leading axis), in the pressure's precision: :func:`.transforms.padded_transform`'s
        values, without its spectrum-sized copies (:func:`.transforms.padded_spectrum`)."""
        return padded_spectrum(p, self._shape)

    def single_precision(self) -> "_SingleConvolution":
        """float32 FFTs with the same kernel (about 2.5x cheaper on large grids; ~1e-7
        relative rounding)."""
        return _SingleConvolution(self)

    def preconditioner(self) -> "CirculantInverse | None":
        """An approximate inverse of this (square) operator (:class:`CirculantInverse`);
        None for a pair of different grids. Made from the kept :meth:`offset_table` (its
        wrapped offsets lie within it), so that the union CG, which also takes the
        operator's :meth:`columns`, rebuilds the table by one inverse transform, not two
        (a box of 1975 x 1968 cells: 0.45 s)."""
        return CirculantInverse.of(self, self.offset_table, np.float64)

    def columns(self, targets: np.ndarray | None = None):
        """:meth:`GridOperator.columns`: each source cell's column is a window of the offset
        table (rebuilt once from the kernel spectrum and kept with the operator), a pass
        over the target per cell (with ``targets``, a gather of the table at their offsets;
        :mod:`.table_columns`)."""
        table = self.offset_table()
        if targets is not None:
            return TargetColumns(table, self.source.shape, np.asarray(targets), self.target.nx)
        return GridColumns(table, self.target.shape, self.source.shape)

    def offset_table(self) -> np.ndarray:
        """The kernel at every offset between a target and a source cell (entry ``(m, n)``
        the offset ``(m - source.ny + 1, n - source.nx + 1)``), rebuilt once from the kernel
        spectrum and kept with the operator (read-only: :meth:`columns` and the rolling
        path's block preconditioner share it; back along y on its columns only), or given by
        ``again`` (a gather: the FFT pair costs 30 against ~3 ms on 467 x 467 cells)."""
        if "table" not in self._derived:
            my, mx = self.target.ny + self.source.ny - 1, self.target.nx + self.source.nx - 1
            table = None if self._again is None else self._again()
            if table is None:  # (:meth:`padded_table`'s values, without its padded copy)
                table = _inverse(self._khat, self._shape, mx, self._even)[:my]
            table.setflags(write=False)
            self._derived["table"] = table
        return self._derived["table"]

    def restricted(self, grid: Grid) -> "ConvolutionOperator | None":
        """This square operator's kernel on a ``grid`` of the same spacing and no larger (a
        window's cut) from the kept :meth:`offset_table`, a window of it (no kernel
        evaluated, and the new operator's own table); None before the table is made, for a
        pair of different grids or a larger or other ``grid``."""
        table = self._derived.get("table")
        (ny, nx), (my, mx) = grid.shape, self.source.shape
        if table is None or self.target != self.source or grid.h != self.source.h or ny > my or nx > mx:
            return None
        sub = np.ascontiguousarray(table[my - ny : my + ny - 1, mx - nx : mx + nx - 1])
        sub.setflags(write=False)
        out = ConvolutionOperator(grid, grid, sub)
        out._derived["table"] = sub
        return out

    def multiply(self, spectrum: np.ndarray) -> np.ndarray:
        return self._times_kernel(np.array(spectrum, dtype=np.complex128))  # (a new array)

    def transposed(self) -> "_TransposedConvolution":
        """The reverse pair's operator (``target`` and ``source`` swapped), sharing this
        one's kernel spectrum."""
        return _TransposedConvolution(self)

    def moved(self, target: Grid, source: Grid) -> "ConvolutionOperator":
        """This operator for ``target`` and ``source`` translated together by whole cells
        from its own pair (the same kernel spectrum: it depends on the offsets only)."""
        out = copy.copy(self)
        out.target, out.source = target, source
        return out

    def finish(self, a: np.ndarray) -> np.ndarray:
        """Target displacement from a (sum of) :meth:`multiply` result(s); ``a`` is overwritten.
        The inverse of :func:`.transforms.padded_transform` axis by axis, the target's columns and rows only
        (:meth:`_finish`'s values by pocketfft's own calls: :func:`.transforms.padded_back`)."""
        sy, sx = self.source.ny - 1, self.source.nx - 1
        return padded_back(a, self._shape[0], sx, self.target.nx)[..., sy : sy + self.target.ny, :]

    def _finish(self, a: np.ndarray) -> np.ndarray:
        """:meth:`finish` through ``scipy.fft`` (:meth:`apply`'s)."""
        my = self._shape[0]
        sy, sx = self.source.ny - 1, self.source.nx - 1
        a = sfft.ifft(a, axis=-1, overwrite_x=True)[..., sx : sx + self.target.nx]
        return sfft.irfft(a, n=my, axis=-2)[..., sy : sy + self.target.ny, :]

    def padded_table(self) -> np.ndarray:
        """The kernel on the padded transform's whole lattice (``fft_shape``; entry 0 the
        offset table's first offset), back from the kernel spectrum."""
        return _inverse(self._khat, self._shape, even=self._even)

    @property
    def nbytes(self) -> int:
        return self._khat.nbytes

    @property
    def flops_estimate(self) -> float:
        n = self._shape[0] * self._shape[1]
        return 5.0 * n * np.log2(max(n, 2))


class _SingleConvolution(GridOperator):
    """A :class:`ConvolutionOperator` computed with float32 FFTs (float64 in and out)."""

    def __init__(self, parent: "ConvolutionOperator"):
        self.target, self.source = parent.target, parent.source
        self._shape = parent.fft_shape
        derived = parent._derived
        if "complex64" not in derived:
            derived["complex64"] = parent._khat.astype(np.complex64)
        self._khat = derived["complex64"]
        self._parent = parent
        self._buffers: tuple[np.ndarray, ...] | None = None  # the float32 products' (:meth:`_new_buffers`)
        self._exact_buffers: tuple[np.ndarray, ...] | None = None  # :meth:`exact`'s, when kept

    @property
    def fft_shape(self) -> tuple[int, int]:
        return self._shape

    def apply(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p)
        if p.ndim != 2:
            a = self._parent.spectrum(np.asarray(p, dtype=np.float32))
            a *= self._khat
            return self._parent.finish(a).astype(np.float64, copy=False)
        buffers = self.buffers()
        a = self._spectrum_in_place(p, buffers)
        a *= self._khat
        return self._finish_in_place(a, buffers)

    def on_cells(self, cells: np.ndarray | None) -> CellProduct | None:
        """:meth:`apply` on the flat ``cells`` of a square operator's grid (None: every cell)
        (:class:`~.on_cells.CellProduct`: the pressures on those cells in, the displacement
        there out, both (m,) float64, without grid-sized float64 copies; also in its two
        halves); None for a pair of different grids."""
        return CellProduct(self, cells) if self.source == self.target else None

    def buffers(self) -> tuple[np.ndarray, ...]:
        """The float32 products' kept buffers (:meth:`_new_buffers`), made on first use."""
        if self._buffers is None:
            self._buffers = self._new_buffers(np.float32)
        return self._buffers

    def energy_weights(self) -> np.ndarray:
        """The kernel's Parseval weights (:func:`~.on_cells.energy_weights`), made once from
        the float32 spectrum and kept with the parent operator."""
        derived = self._parent._derived
        if "energy" not in derived:
            derived["energy"] = energy_weights(self._khat, self.source.shape, self._shape)
        return derived["energy"]

    def exact(self, p: np.ndarray, keep: bool = False) -> np.ndarray:
        """The parent's float64 product of one field (``ConvolutionOperator.apply``: the
        same transforms in the same order, the same values to the bit), into buffers made
        for the call (``keep``: kept for the next, ~1 ms of zeroed pages a call on a rolling
        tyre's cut) instead of ``scipy.fft``'s outputs and padded copies: 500 x 498 cells,
        11-13 against 20-30 ms."""
        p = np.asarray(p, dtype=float)
        if p.shape != self.source.shape:
            return self._parent.apply(p)
        buffers = (keep and self._exact_buffers) or self._new_buffers(np.float64)
        self._exact_buffers = buffers if keep else self._exact_buffers
        a = self._spectrum_in_place(p, buffers)
        a *= self._parent._khat
        return self._finish_in_place(a, buffers)

    def _new_buffers(self, dtype) -> tuple[np.ndarray, ...]:
        """The padded field, the padded spectrum (their padding zero) and the field back,
        in the precision ``dtype``, for :meth:`_spectrum_in_place` and :meth:`_finish_in_place`."""
        (my, mx), nx = self._shape, self.source.nx
        return (
            np.zeros((my, nx), dtype),
            np.zeros((my // 2 + 1, mx), np.result_type(dtype, np.complex64)),
            np.empty((my, self.target.nx), dtype),
        )

    def _spectrum_in_place(self, p: np.ndarray | None, buffers: tuple[np.ndarray, ...]) -> np.ndarray:
        """:func:`.transforms.padded_transform` of one field through ``buffers`` (:meth:`_new_buffers`; the
        float32 ones kept with this operator): the padding is not allocated again for
        every product (fresh pages the kernel zeroes: on 5.26 M cells 0.16 against 0.24 s
        a transform), the transform along y is written into the spectrum and the one along
        x runs in place (:mod:`.transforms`). The returned spectrum is the buffer itself,
        overwritten by the next product."""
        padded, spectrum, _ = buffers
        nx = padded.shape[1]
        if p is not None:  # (None: the padded field is written already)
            padded[: p.shape[0]] = p
        rfft_into(padded, 0, spectrum[:, :nx])
        spectrum[:, nx:] = 0.0
        return fft_in_place(spectrum, 1, forward=True)

    def _finish_in_place(self, a: np.ndarray, buffers: tuple[np.ndarray, ...]) -> np.ndarray:
        """:meth:`ConvolutionOperator.finish` of the spectrum ``a`` (overwritten), the real
        transform back along y written into the field back of ``buffers``; the target's
        displacement as a new float64 array."""
        sy = self.source.ny - 1
        return self._back_in_place(a, buffers)[sy : sy + self.target.ny].astype(np.float64)

    def _back_in_place(self, a: np.ndarray, buffers: tuple[np.ndarray, ...]) -> np.ndarray:
        """The transforms back of :meth:`_finish_in_place` into the field back of
        ``buffers`` (every padded row: the target's start at row ``source.ny - 1``)."""
        back, sx = buffers[2], self.source.nx - 1
        fft_in_place(a, 1, forward=False)
        return irfft_into(a[:, sx : sx + self.target.nx], 0, self._shape[0], back)

    def apply_stack(self, P: np.ndarray) -> np.ndarray:
        """:meth:`apply` on a stack (B, ny, nx): the transforms take the leading axis as
        they come (one call each for the whole stack)."""
        return self.apply(P)

    def kept_stack(self, workspace: Workspace | None = None) -> KeptStackProduct:
        """:meth:`apply_stack` through ``workspace``'s buffers (:mod:`.stacked`)."""
        return KeptStackProduct(self, self._times_kernel, np.float32, workspace)

    def _times_kernel(self, a: np.ndarray) -> np.ndarray:
        a *= self._khat
        return a

    def preconditioner(self) -> "CirculantInverse | None":
        """The parent's :meth:`ConvolutionOperator.preconditioner`, applied in float32."""
        return CirculantInverse.of(self._parent, self._parent.offset_table, np.float32)


class _TransposedConvolution(ConvolutionOperator):
    """The transpose of a :class:`ConvolutionOperator`, holding only a reference to its
    kernel spectrum. The reverse pair's offset table is the parent's reversed along both
    axes (Love's kernel is even), and the zero-padded transform of a reversed real table
    of length ``m`` is the conjugate transform times ``exp(-2 pi i (m - 1) k / N)`` per
    axis: a phase vector per axis instead of a second spectrum."""

    def __init__(self, parent: ConvolutionOperator):
        self.target, self.source = parent.source, parent.target
        self._shape = parent.fft_shape
        self._derived, self._again = {}, None
        self._parent = parent._khat
        ny, nx = self._shape
        my, mx = parent.target.ny + parent.source.ny - 1, parent.target.nx + parent.source.nx - 1
        self._py = np.exp(-2j * np.pi * ((my - 1) * np.arange(ny // 2 + 1) % ny) / ny)[:, None]
        self._px = np.exp(-2j * np.pi * ((mx - 1) * np.arange(nx) % nx) / nx)[None, :]

    @property
    def _khat(self) -> np.ndarray:
        """The kernel spectrum itself (built when asked for, e.g. for a float32 copy; the
        products use :meth:`_times_kernel`, which never builds it)."""
        out = np.conj(self._parent)
        out *= self._py
        out *= self._px
        return out

    def _times_kernel(self, a: np.ndarray) -> np.ndarray:
        # a conj(K) py px = conj(conj(a) K) py px: in place, no spectrum-sized temporary
        np.conj(a, out=a)
        a *= self._parent
        np.conj(a, out=a)
        a *= self._py
        a *= self._px
        return a

    def transposed(self) -> None:
        return None

    @property
    def nbytes(self) -> int:
        return self._py.nbytes + self._px.nbytes
