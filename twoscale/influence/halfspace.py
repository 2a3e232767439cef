"""The elastic half-space: Boussinesq point compliance, Love cell blocks, FFT products."""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np
import scipy.fft as sfft

from ..analytic.halfspace import boussinesq_point, love_far_field, love_rectangle
from ..grid import Grid
from ..material import Material
from .base import GridOperator, InfluenceProvider
from .cache import BoundedCache
from .circulant import CirculantInverse
from .separated import relative_frames


def _pairwise(targets: np.ndarray, sources: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(targets, dtype=float).reshape(-1, 2)
    s = np.asarray(sources, dtype=float).reshape(-1, 2)
    return t[:, None, 0] - s[None, :, 0], t[:, None, 1] - s[None, :, 1]


#: Offset tables up to this many entries (a 100 x 100 patch's self table: 4e4) are kept in
#: the caller's ``tables``.
TABLE_CACHE_ENTRIES = 40_000
#: Largest quadrant of Love values kept per cell size (entries; 16 MB): every offset table
#: within it is a gather from it instead of new Love evaluations.
QUADRANT_MAX_ENTRIES = 2_000_000
#: A quadrant that must grow grows to at least this factor of its old extent per axis.
QUADRANT_GROWTH = 1.5


def _folded(a: np.ndarray, start: int, n: int, *, axis: int) -> np.ndarray:
    """Rows (``axis=0``) or columns of ``a`` at the indices ``|start|, ..., |start + n - 1|``
    (two strided copies instead of a fancy-indexed gather)."""
    view = np.moveaxis(a, axis, 0)
    stop = start + n - 1
    if start >= 0:
        out = view[start : stop + 1]
    elif stop <= 0:
        out = view[-stop : -start + 1][::-1]
    else:
        out = np.concatenate([view[1 : -start + 1][::-1], view[: stop + 1]])
    return np.ascontiguousarray(np.moveaxis(out, 0, axis))


def _love_table(E_star: float, h: float, ox0: int, oy0: int, mx: int, my: int) -> np.ndarray:
    """Love's kernel on the lattice offsets ``(oy0 + m, ox0 + n) h``, shape (my, mx), mm/MPa."""
    ox = (ox0 + np.arange(mx)) * h
    oy = (oy0 + np.arange(my)) * h
    table = love_rectangle(ox[None, :], oy[:, None], 0.5 * h, 0.5 * h, E_star)
    table.setflags(write=False)
    return table


def _transform(a: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The zero-padded transform of ``a``'s last two axes to ``shape`` in the layout of every
    :class:`ConvolutionOperator` spectrum: real along y (``shape[0] // 2 + 1`` rows kept),
    then complex along the contiguous x (a float32 product on 625 x 384 cells: 4.7-5.0 ms
    against 5.2-5.5 ms with ``rfft2``'s order)."""
    my, mx = shape
    ny = a.shape[-2]
    padded = np.zeros((*a.shape[:-2], my, a.shape[-1]), dtype=np.result_type(a.dtype, np.float32))
    padded[..., :ny, :] = a
    out = sfft.rfft(padded, axis=-2, overwrite_x=True)
    return sfft.fft(out, n=mx, axis=-1, overwrite_x=True)


def _inverse(spectrum: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The real array of ``shape`` whose :func:`_transform` is ``spectrum``."""
    return sfft.irfft(sfft.ifft(spectrum, axis=-1), n=shape[0], axis=-2)


@dataclass(frozen=True)
class HalfSpace(InfluenceProvider):
    """Homogeneous isotropic elastic half-space (Boussinesq, Love).

    Parameters
    ----------
    material : Material
        E (MPa) and nu of the body; only ``E* = E / (1 - nu^2)`` matters.

    The half-space keeps nothing: its value is its material. The read-only arrays that
    recur across patches (Love offset tables, key ``h`` and the offset window; Chebyshev
    interpolation matrices) go to a ``tables`` cache the caller owns and passes
    (:meth:`grid_matrix`, :meth:`grid_operator`, :meth:`separated_operator`): a solver
    object's (:class:`~twoscale.influence.cached.CachedBody`), bounded there. Its cell
    kernel depends only on lattice offsets (``translation_invariant``): an operator between
    two grids serves every pair of grids translated from them (``operator.moved``).
    """

    material: Material
    kind: str = field(default="halfspace", init=False)
    cheap_grid_matrix = True  # a strided copy of a cached Love table (not a field)
    translation_invariant = True

    @property
    def E_star(self) -> float:
        return self.material.E_star

    def point_compliance(self, targets, sources):
        dx, dy = _pairwise(targets, sources)
        return boussinesq_point(np.hypot(dx, dy), self.E_star)

    def cell_block(self, targets, sources, h):
        dx, dy = _pairwise(targets, sources)
        return love_rectangle(dx, dy, 0.5 * h, 0.5 * h, self.E_star)

    # The half-space kernel depends only on the lattice offset between cells, so
    # dense blocks and fast products on aligned grids are built from one table of
    # Love values over the offsets that occur.
    def _offset_table(self, target: Grid, source: Grid, tables: BoundedCache | None):
        ti, tj = target.offset_in(source)
        ox0, oy0 = ti - (source.nx - 1), tj - (source.ny - 1)
        mx, my = target.nx + source.nx - 1, target.ny + source.ny - 1
        h = float(source.h)
        if mx * my > TABLE_CACHE_ENTRIES or tables is None:
            return self._window(h, ox0, oy0, mx, my, tables), ox0, oy0
        # patch-sized tables recur (every patch of the same shape has the same self table):
        # kept, read-only, in the caller's bounded cache (``h`` exact: a table is only
        # reused for the very cell size it was made for)
        key = ("love", h, ox0, oy0, mx, my)
        table = tables.get(key)
        if table is None:
            table = tables.put(key, self._window(h, ox0, oy0, mx, my, tables), 8 * mx * my)
        return table, ox0, oy0

    def _window(self, h: float, ox0: int, oy0: int, mx: int, my: int, tables: BoundedCache | None) -> np.ndarray:
        """Love's kernel on the offsets ``(oy0 + m, ox0 + n) h`` (read-only): a gather from
        the quadrant of offsets ``(|oy|, |ox|)`` (the kernel is even in both), kept per ``h``
        in the caller's ``tables`` (without them, a quadrant for this window only) and grown
        when a window reaches beyond it; a window whose quadrant would exceed
        ``QUADRANT_MAX_ENTRIES`` is gathered from a quadrant of its own, not kept. Near pairs of patches each have their own
        window: the gather costs a copy where new Love values cost ~50x more."""
        ax = max(abs(ox0), abs(ox0 + mx - 1)) + 1
        ay = max(abs(oy0), abs(oy0 + my - 1)) + 1
        key = ("love-quadrant", h)
        quadrant = None if tables is None else tables.get(key)
        if quadrant is None or quadrant.shape[0] < ay or quadrant.shape[1] < ax:
            if quadrant is not None:
                ax = max(ax, min(int(QUADRANT_GROWTH * quadrant.shape[1]), QUADRANT_MAX_ENTRIES // ay))
                ay = max(ay, min(int(QUADRANT_GROWTH * quadrant.shape[0]), QUADRANT_MAX_ENTRIES // ax))
            keep = ax * ay <= QUADRANT_MAX_ENTRIES
            if not keep:  # this window's own quadrant, not kept (a quarter of a self table's values)
                ax = max(abs(ox0), abs(ox0 + mx - 1)) + 1
                ay = max(abs(oy0), abs(oy0 + my - 1)) + 1
                if ax * ay >= mx * my:
                    return _love_table(self.E_star, h, ox0, oy0, mx, my)
            quadrant = _love_table(self.E_star, h, 0, 0, ax, ay)
            if tables is not None and keep:
                tables.put(key, quadrant, 8 * ax * ay)
        table = _folded(_folded(quadrant, oy0, my, axis=0), ox0, mx, axis=1)
        table.setflags(write=False)
        return table

    def grid_matrix(
        self, target: Grid, source: Grid | None = None, *, tables: BoundedCache | None = None
    ) -> np.ndarray:
        source = target if source is None else source
        table, _, _ = self._offset_table(target, source, tables)
        # Entry (target (jt, it), source (js, is)) is table[jt - js + nys - 1, it - is + nxs - 1].
        # In the flipped table F that is F[(nyt-1-jt) + js, (nxt-1-it) + is]: a sliding
        # window of F read backwards, so the block-Toeplitz matrix is one strided copy.
        flipped = table[::-1, ::-1]
        windows = np.lib.stride_tricks.sliding_window_view(flipped, (source.ny, source.nx))
        return np.ascontiguousarray(windows[::-1, ::-1]).reshape(target.size, source.size)

    def grid_operator(
        self, target: Grid, source: Grid | None = None, *, tables: BoundedCache | None = None
    ) -> "ConvolutionOperator":
        source = target if source is None else source
        table, _, _ = self._offset_table(target, source, tables)
        return ConvolutionOperator(target, source, table)

    def separated_operator(self, target: Grid, source: Grid, *, rtol: float = 1e-8, tables: BoundedCache | None = None):
        """Chebyshev low-rank block (:class:`~.separated.SeparatedOperator`) for a
        well-separated pair, with Love's cell kernel by its multipole expansion
        (:func:`~twoscale.analytic.halfspace.love_far_field`); ``None`` when the pair is
        too close for ``rtol``. Built in the frame of the source's lattice (the source's
        first cell at the origin, the target at its integer offset), so that its arrays
        depend only on the pair's relative position: the same arrays serve every
        translated pair (:meth:`~.separated.SeparatedOperator.moved`)."""
        from .separated import SeparatedOperator, plan

        rel_target, rel_source = relative_frames(target, source)
        sep = plan(rel_target, rel_source, rtol)
        if sep is None:
            return None
        E_star, h = self.E_star, float(source.h)
        op = SeparatedOperator(
            rel_target, rel_source, lambda dx, dy: love_far_field(dx, dy, h, E_star, sep.order), sep, cache=tables
        )
        return op.moved(target, source)

    def point_operator(self, targets, sources, *, exclude=None, rtol: float = 1e-6):
        """As :meth:`InfluenceProvider.point_operator`; above ``FAST_ENTRIES`` pairs an
        :class:`~twoscale.influence.halfspace_points.EwaldPointOperator` (Ewald split:
        FFT on a mesh plus near pairs, error <= ``rtol`` of ``max |u|``)."""
        from .halfspace_points import FAST_ENTRIES, EwaldPointOperator
        from .points import check_points

        t, s = check_points(targets, "targets"), check_points(sources, "sources")
        if len(t) * len(s) <= FAST_ENTRIES:
            return super().point_operator(t, s, exclude=exclude, rtol=rtol)
        return EwaldPointOperator(self.E_star, t, s, exclude=exclude, rtol=rtol)


class ConvolutionOperator(GridOperator):
    """Zero-padded (non-periodic) FFT convolution with a translation-invariant kernel.

    ``table[m, n]`` is the kernel at lattice offset ``(oy0 + m, ox0 + n)`` between a
    target and a source cell, covering every offset that occurs; the product is then
    exactly the linear convolution, computed in ``O(n log n)``.
    """

    def __init__(self, target: Grid, source: Grid, table: np.ndarray):
        self.target, self.source = target, source
        my, mx = table.shape
        self._shape = (sfft.next_fast_len(my, real=True), sfft.next_fast_len(mx, real=True))
        self._khat = _transform(table, self._shape)
        # transforms derived from the kernel (the preconditioner's, the float32 spectrum),
        # made on first use and shared with the moved copies of this operator
        self._derived: dict = {}

    def apply(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, dtype=float)
        if p.shape != self.source.shape:
            raise ValueError(f"pressure has shape {p.shape}, expected {self.source.shape}")
        return self.finish(self._times_kernel(self.spectrum(p)))

    def apply_stack(self, P: np.ndarray) -> np.ndarray:
        """:meth:`apply` on a stack (B, ny, nx): the same transforms along the last two axes,
        one call each for the whole stack."""
        return self.finish(self._times_kernel(self.spectrum(np.asarray(P, dtype=float))))

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
    def target_key(self) -> tuple:
        # finish keeps the window of the target behind source-shaped padding
        return ("fft", self._shape, self.source.shape, self.target)

    def spectrum(self, p: np.ndarray) -> np.ndarray:
        """Half-spectrum of the zero-padded source pressure (``source.shape``, or a stack of
        them along a leading axis), in the pressure's precision (:func:`_transform`)."""
        return _transform(p, self._shape)

    def single_precision(self) -> "_SingleConvolution":
        """float32 FFTs with the same kernel (about 2.5x cheaper on large grids; ~1e-7
        relative rounding)."""
        return _SingleConvolution(self)

    def preconditioner(self) -> "CirculantInverse | None":
        """An approximate inverse of this (square) operator (:class:`CirculantInverse`);
        None for a pair of different grids."""
        return CirculantInverse.of(self, self.padded_table, np.float64)

    def columns(self):
        """:meth:`GridOperator.columns`: each source cell's column is a window of the offset
        table (rebuilt once from the kernel spectrum and kept with the operator), a pass
        over the target per cell."""
        if "table" not in self._derived:
            my, mx = self.target.ny + self.source.ny - 1, self.target.nx + self.source.nx - 1
            self._derived["table"] = self.padded_table()[:my, :mx]
        table = self._derived["table"]
        (nyt, nxt), (nys, nxs) = self.target.shape, self.source.shape

        def add(out: np.ndarray, cells: np.ndarray, values: np.ndarray) -> None:
            o = out.reshape(nyt, nxt)
            js, i_s = np.divmod(np.asarray(cells), nxs)
            term = np.empty_like(o)  # one buffer for every column (a new array each was a page-faulting allocation)
            for j, i, v in zip(js.tolist(), i_s.tolist(), np.asarray(values).tolist()):
                np.multiply(table[nys - 1 - j : nys - 1 - j + nyt, nxs - 1 - i : nxs - 1 - i + nxt], v, out=term)
                o += term

        return add

    def multiply(self, spectrum: np.ndarray) -> np.ndarray:
        """Kernel times a source spectrum (a new array)."""
        return self._times_kernel(np.array(spectrum, dtype=np.complex128))

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
        The inverse of :func:`_transform` axis by axis: only the target's columns go through
        the real transform back along y, and only its rows are kept."""
        my = self._shape[0]
        sy, sx = self.source.ny - 1, self.source.nx - 1
        a = sfft.ifft(a, axis=-1, overwrite_x=True)[..., sx : sx + self.target.nx]
        return sfft.irfft(a, n=my, axis=-2)[..., sy : sy + self.target.ny, :]

    def padded_table(self) -> np.ndarray:
        """The kernel on the padded transform's whole lattice (``fft_shape``; entry 0 the
        offset table's first offset), back from the kernel spectrum."""
        return _inverse(self._khat, self._shape)

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

    @property
    def fft_shape(self) -> tuple[int, int]:
        return self._shape

    def apply(self, p: np.ndarray) -> np.ndarray:
        a = self._parent.spectrum(np.asarray(p, dtype=np.float32))
        a *= self._khat
        return self._parent.finish(a).astype(np.float64, copy=False)

    def preconditioner(self) -> "CirculantInverse | None":
        """The parent's :meth:`ConvolutionOperator.preconditioner`, applied in float32."""
        return CirculantInverse.of(self._parent, self._parent.padded_table, np.float32)


class _TransposedConvolution(ConvolutionOperator):
    """The transpose of a :class:`ConvolutionOperator`, holding only a reference to its
    kernel spectrum. The reverse pair's offset table is the parent's reversed along both
    axes (Love's kernel is even), and the zero-padded transform of a reversed real table
    of length ``m`` is the conjugate transform times ``exp(-2 pi i (m - 1) k / N)`` per
    axis: a phase vector per axis instead of a second spectrum."""

    def __init__(self, parent: ConvolutionOperator):
        self.target, self.source = parent.source, parent.target
        self._shape = parent.fft_shape
        self._derived = {}
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
