"""The elastic half-space: Boussinesq point compliance, Love cell blocks, FFT products."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.distance import cdist

from ..analytic.halfspace import boussinesq_point, love_far_field, love_on_lattice, love_rectangle
from ..grid import Grid
from ..material import Material
from .base import InfluenceProvider
from .cache import BoundedCache
from .convolution import ConvolutionOperator
from .even_kernel import EVEN_MIN_CELLS, unfolded
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


def _love_table(E_star: float, h: float, ox0: int, oy0: int, mx: int, my: int) -> np.ndarray:
    """Love's kernel on the lattice offsets ``(oy0 + m, ox0 + n) h``, shape (my, mx), mm/MPa."""
    ox = (ox0 + np.arange(mx)) * h
    oy = (oy0 + np.arange(my)) * h
    table = love_on_lattice(ox, oy, 0.5 * h, 0.5 * h, E_star)
    table.setflags(write=False)
    return table


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
        # the distances in one array, turned into the compliance in place (by hypot of the
        # offsets: four temporaries of its size, which in a fresh process cost 5-15x the
        # values themselves: 1,652 tips, 0.08-0.29 against 0.016 s)
        t = np.asarray(targets, dtype=float).reshape(-1, 2)
        s = np.asarray(sources, dtype=float).reshape(-1, 2)
        r = cdist(t, s)
        return boussinesq_point(r, self.E_star, out=r)

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
        table = unfolded(quadrant, oy0, my, ox0, mx)
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

    def grid_entries(
        self, target: Grid, source: Grid, rows: np.ndarray, cols: np.ndarray, *, tables: BoundedCache | None = None
    ) -> np.ndarray:
        """``grid_matrix(target, source)[np.ix_(rows, cols)]`` (flat cell indices of the two
        grids), the same numbers gathered from the offset table without the grids' whole
        matrix (a dense block's active columns, a near pair's owned cells). The table is
        C-contiguous, so entry ``(jt - js + nys - 1, it - is + nxs - 1)`` is its flat element
        ``r(jt, it) - c(js, is)``: one ``np.take`` of an outer difference. That is 2-4x
        faster than a two-index gather or a cut from the whole matrix (16 x 16 grids,
        200 x 200 entries: 100 against 400 us; 100 x 100: 40 against 80 us)."""
        table, _, _ = self._offset_table(target, source, tables)
        mx = table.shape[1]
        jt, it = np.divmod(np.asarray(rows, dtype=np.int64), target.nx)
        js, is_ = np.divmod(np.asarray(cols, dtype=np.int64), source.nx)
        r = jt * mx + it + ((source.ny - 1) * mx + source.nx - 1)
        return np.take(np.ascontiguousarray(table).ravel(), r[:, None] - (js * mx + is_))

    def grid_operator(
        self, target: Grid, source: Grid | None = None, *, tables: BoundedCache | None = None
    ) -> "ConvolutionOperator":
        source = target if source is None else source
        if target == source and target.size >= EVEN_MIN_CELLS:  # Love's kernel is even: its quadrant is enough
            h, (ny, nx) = float(source.h), source.shape
            quadrant = self._window(h, 0, 0, nx, ny, tables)
            kept = lambda: self._kept_window(h, 1 - nx, 1 - ny, 2 * nx - 1, 2 * ny - 1, tables)  # noqa: E731
            return ConvolutionOperator(target, source, quadrant, None if tables is None else kept, even=True)
        table, ox0, oy0 = self._offset_table(target, source, tables)
        if tables is None:
            return ConvolutionOperator(target, source, table)
        (my, mx), h = table.shape, float(source.h)
        return ConvolutionOperator(target, source, table, lambda: self._kept_window(h, ox0, oy0, mx, my, tables))

    def _kept_window(self, h: float, ox0: int, oy0: int, mx: int, my: int, tables: BoundedCache) -> np.ndarray | None:
        """:meth:`_window`'s table when the quadrant it gathers from is still in ``tables``
        (a copy's cost), else None (the operator then transforms its spectrum back)."""
        quadrant = tables.get(("love-quadrant", h))
        ax = max(abs(ox0), abs(ox0 + mx - 1)) + 1
        ay = max(abs(oy0), abs(oy0 + my - 1)) + 1
        if quadrant is None or quadrant.shape[0] < ay or quadrant.shape[1] < ax:
            return None
        return self._window(h, ox0, oy0, mx, my, tables)

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
