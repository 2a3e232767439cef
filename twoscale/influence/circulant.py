"""An approximate inverse of a square zero-padded convolution (:class:`CirculantInverse`),
the preconditioner of the constrained conjugate gradients on the half-space."""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
import scipy.fft as sfft

from ..grid import Grid
from .base import GridOperator
from .on_cells import parseval_sum
from .stacked import KeptStackInverse, Workspace
from .transforms import fft_in_place, irfft_into, rfft_into


#: Sides from this many cells wrap the kernel onto a torus at least ``TORUS_MARGIN`` times
#: longer, of a fast FFT length (:func:`torus_shape`).
LONGER_TORUS_MIN_SIDE = 128
#: The torus of a side from ``LONGER_TORUS_MIN_SIDE`` cells is at least this much longer than
#: the side. On the grid's own torus the grid's opposite edges are neighbours: a union box
#: cut to a height map has contact at both (the map's stones), and the inverse coupled them
#: as if they touched. Union CG iterations of the sweep's roads with the torus 1.0 / 1.1 /
#: 2.0 times the side: road 50 mm at 0.45 MPa 25 / 21 / 21, road-um 50 mm 21 / 19 / 19.
TORUS_MARGIN = 1.1
#: The largest prime factor of a length pocketfft transforms at full speed.
FAST_PRIME = 11


def _largest_prime_factor(n: int) -> int:
    largest, k = 1, 2
    while k * k <= n:
        while n % k == 0:
            largest, n = k, n // k
        k += 1
    return max(largest, n)


def torus_shape(g: Grid) -> tuple[int, int]:
    """The torus the kernel is wrapped onto for a grid ``g``: per axis the grid's own length
    ``n`` below ``LONGER_TORUS_MIN_SIDE``, else the first fast FFT length (largest prime
    factor at most ``FAST_PRIME``) from ``TORUS_MARGIN n`` (its offsets ``-(L // 2) ..
    (L - 1) // 2`` stay within the padded table's ``-(n - 1) .. n - 1``). Two reasons: a
    box's side can be a prime (883 cells: an unpadded FFT pair 54 ms against 19 ms at
    900), which made one application cost more than a padded product; and on the side's
    own torus the grid's opposite edges are neighbours (``TORUS_MARGIN``). The longer
    torus is a slightly different approximate inverse (its extra cells see zero
    displacement); small grids keep their own."""

    def side(n: int) -> int:
        if n < LONGER_TORUS_MIN_SIDE:
            return n
        fast = sfft.next_fast_len(math.ceil(TORUS_MARGIN * n), real=True)
        return fast if fast // 2 <= n - 1 else n

    return side(g.ny), side(g.nx)


def _multiplier(g: Grid, table: np.ndarray, dtype) -> np.ndarray | None:
    """The inverse spectrum of the kernel of the padded ``table`` (entry 0 the offset
    ``-(n - 1)`` per axis) wrapped onto the torus of :func:`torus_shape` (in ``dtype``),
    None when that spectrum is not positive."""
    ly, lx = torus_shape(g)
    jy, jx = np.arange(ly), np.arange(lx)
    jy = np.where(jy <= (ly - 1) // 2, jy, jy - ly) + g.ny - 1
    jx = np.where(jx <= (lx - 1) // 2, jx, jx - lx) + g.nx - 1
    spectrum = sfft.rfft2(_gathered(table, jy, jx)).real
    if not float(spectrum.min()) > 0.0:
        return None
    out = (1.0 / spectrum).astype(dtype)
    out.setflags(write=False)
    return out


def _gathered(table: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``table[np.ix_(rows, cols)]`` for indices made of runs of consecutive ones (a
    wrapped torus: two per axis), as block copies of the runs (a fancy gather of a
    700 x 700 box's torus was a quarter of its multiplier)."""

    def runs(idx):
        if not len(idx):
            return []
        cut = np.flatnonzero(np.diff(idx) != 1) + 1
        bounds = np.r_[0, cut, len(idx)].tolist()
        return [(slice(a, b), slice(int(idx[a]), int(idx[a]) + b - a)) for a, b in zip(bounds, bounds[1:])]

    out = np.empty((len(rows), len(cols)), dtype=table.dtype)
    for r, tr in runs(rows):
        for c, tc in runs(cols):
            out[r, c] = table[tr, tc]
    return out


class CirculantInverse(GridOperator):
    """Approximate inverse of a square zero-padded convolution: the kernel wrapped onto a
    torus of the grid's own size or a little more (offsets ``-(L // 2) .. (L - 1) // 2`` per
    axis, ``L`` the next fast FFT length from ``n``: :func:`torus_shape`), inverted
    in Fourier space (the kernel is even, so its spectrum is real). Restricted to the
    loaded cells of a contact it is the classical FFT preconditioner of the constrained
    conjugate gradient (Vollebregt 2014), which keeps the iteration count from growing with
    the cells across a contact. One application costs an unpadded FFT pair, about a quarter
    of a product (the padded circulant's inverse was measured: no fewer iterations, 70
    against 68 on 300 merged tips)."""

    def __init__(self, grid: Grid, multiplier: np.ndarray):
        self.target = self.source = grid
        self._m = multiplier
        self._padded: tuple[np.ndarray, ...] | None = None  # (:meth:`_apply_pruned`)

    @classmethod
    def of(cls, op: GridOperator, table: Callable[[], np.ndarray], dtype) -> "CirculantInverse | None":
        """For ``op`` (source == target; ``table()`` its padded kernel table, whose entry 0
        is the offset ``-(n - 1)``), or None when the wrapped kernel's spectrum is not
        positive. The multiplier is kept in ``op._derived`` when ``op`` has one (an
        operator kept between solves: built once for all of them, ``table`` called once)."""
        if op.source != op.target:
            return None
        derived = getattr(op, "_derived", {})
        key = ("inverse", np.dtype(dtype).str)
        if key not in derived:
            derived[key] = _multiplier(op.source, table(), dtype)
        m = derived[key]
        return None if m is None else cls(op.source, m)

    def apply(self, v: np.ndarray) -> np.ndarray:
        """The approximate inverse on ``v`` (ny, nx), or on a stack (B, ny, nx): the
        transforms run along the last two axes, one call each for the whole stack."""
        shape = torus_shape(self.source)
        v = np.asarray(v)
        if v.ndim == 2 and shape != v.shape:
            return self._apply_pruned(v)
        a = sfft.rfft2(np.asarray(v, dtype=self._m.dtype), s=shape)
        a *= self._m
        ny, nx = self.source.shape
        return np.ascontiguousarray(sfft.irfft2(a, s=shape)[..., :ny, :nx], dtype=np.float64)

    def _apply_pruned(self, v: np.ndarray) -> np.ndarray:
        """:meth:`apply` on one field (ny, nx) smaller than the torus, through buffers kept
        with this object (:mod:`.transforms`): the transforms along x run on the field's
        ``ny`` rows only, forward (the torus's other rows are zero) and back (only the
        field's rows are kept), the ones along y in place (467 x 467 cells on a 540 x 540
        torus: 2.1-2.6 against 2.2-3.9 ms, minimum and median of 150 calls on a loaded
        machine; the same values to 1e-7 of the largest, float32 rounding)."""
        nx = v.shape[1]
        if self._padded is None:
            self._padded = self._buffers()
        rows = self._padded[0]
        rows[:, :nx] = v
        return self._pruned(rows)[:, :nx].astype(np.float64)

    def _buffers(self) -> tuple[np.ndarray, ...]:
        """The field's rows on the torus (0 beyond the field), the spectrum, the rows back."""
        (ly, lx), ny = torus_shape(self.source), self.source.ny
        return (
            np.zeros((ny, lx), self._m.dtype),
            np.zeros((ly, lx // 2 + 1), np.result_type(self._m.dtype, np.complex64)),
            np.empty((ny, lx), self._m.dtype),
        )

    def _pruned(self, rows: np.ndarray) -> np.ndarray:
        """The transforms of :meth:`_apply_pruned` from the field's ``rows`` on the torus
        (``ny`` rows, 0 beyond the field) into the kept rows back (returned)."""
        if self._padded is None:
            self._padded = self._buffers()
        _, spectrum, back = self._padded
        ny, lx = rows.shape
        rfft_into(rows, 1, spectrum[:ny])
        spectrum[ny:] = 0.0  # (the torus's rows off the field)
        fft_in_place(spectrum, 0, forward=True)
        spectrum *= self._m
        fft_in_place(spectrum, 0, forward=False)
        return irfft_into(spectrum[:ny], 1, lx, back)

    def offsets(self, radius: int) -> np.ndarray:
        """The approximate inverse's kernel (real space, float64) at the offsets ``-radius ..
        radius`` per axis, ``(2 radius + 1)^2``: the inverse transform of its multiplier (real,
        so even) at those offsets alone, as two products with cosine tables (#185's torus of
        1500 x 1500: a whole inverse transform 0.1 s in the solve)."""
        (ly, lx), d = torus_shape(self.source), np.arange(-radius, radius + 1)
        cy = np.cos(2.0 * np.pi * np.outer(d, np.arange(ly)) / ly)
        kx = np.arange(lx // 2 + 1)
        weight = np.where((kx == 0) | (2 * kx == lx), 1.0, 2.0)  # (the half-spectrum's mirrored columns)
        cx = np.cos(2.0 * np.pi * np.outer(kx, d) / lx) * weight[:, None]
        return (cy @ self._m.astype(np.float64)) @ cx / (ly * lx)

    def on_cells(self, cells: np.ndarray) -> Callable[[np.ndarray], np.ndarray] | None:
        """:meth:`apply` on the flat ``cells`` of the grid: ``f(values)`` takes the field's
        values on those cells (0 elsewhere) and gives the result there, both (m,) float64,
        the values straight into rows of their own (the other cells stay 0) and back from
        the kept ones (no grid-sized float64 copies), the result in an array kept with
        ``f`` (overwritten by its next call); None where :meth:`apply` does not prune (the
        torus is the grid)."""
        (ly, lx), (ny, nx) = torus_shape(self.source), self.source.shape
        if (ly, lx) == (ny, nx):
            return None
        j, i = np.divmod(np.asarray(cells, dtype=np.intp), nx)
        at = j * lx + i
        rows = np.zeros((ny, lx), self._m.dtype)
        # the result at the cells, in both precisions, kept (fresh arrays each call page-faulted)
        gathered, out = np.empty(len(at), self._m.dtype), np.empty(len(at))

        def inverse(values: np.ndarray) -> np.ndarray:
            rows.ravel()[at] = values
            np.copyto(out, np.take(self._pruned(rows).ravel(), at, out=gathered, mode="clip"))
            return out

        return inverse

    def energy_on_cells(self, cells: np.ndarray | None) -> Callable[[np.ndarray], float]:
        """``f(values) = v.C v`` for a field ``v`` given by its values on the flat ``cells`` of
        the grid (None: every cell), ``C`` the kernel wrapped on this torus (the operator this
        object inverts: its spectrum is ``1 / multiplier``), by Parseval from the forward
        transforms of :meth:`_pruned` alone (float32, summed in float64). A search
        direction's step length by this model of ``A`` costs a quarter of the padded
        product's forward transforms: within 0.02-8 % of ``t.A t`` for the roads' restarted
        directions (sums 0, at the stones' cells), whose steps then refresh ``A p``."""
        (ly, lx), (ny, nx) = torus_shape(self.source), self.source.shape
        if self._padded is None:
            self._padded = self._buffers()
        rows = np.zeros((ny, lx), self._m.dtype)
        at = None
        if cells is not None:
            j, i = np.divmod(np.asarray(cells, dtype=np.intp), nx)
            at = j * lx + i
        half = np.full(lx // 2 + 1, 2.0)  # the columns whose mirror the real transform leaves out
        half[0] = 1.0
        half[-1] = 1.0 if lx % 2 == 0 else 2.0
        weights = (half / (ly * lx) / self._m).astype(np.float32)

        def energy(values: np.ndarray) -> float:
            if at is None:
                rows[:, :nx] = values.reshape(ny, nx)
            else:
                rows.ravel()[at] = values
            spectrum = self._padded[1]
            rfft_into(rows, 1, spectrum[:ny])
            spectrum[ny:] = 0.0
            return parseval_sum(fft_in_place(spectrum, 0, forward=True), weights)

        return energy

    def apply_stack(self, V: np.ndarray) -> np.ndarray:
        """:meth:`apply` on a stack (B, ny, nx) (the micro step's blocks of one size class)."""
        return self.apply(V)

    def kept_stack(self, workspace: Workspace | None = None) -> KeptStackInverse:
        """:meth:`apply_stack` through ``workspace``'s buffers (:mod:`.stacked`; bit for bit)."""
        return KeptStackInverse(torus_shape(self.source), self.source.shape, self._m, workspace)

    @property
    def nbytes(self) -> int:
        return self._m.nbytes
