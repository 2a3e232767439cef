"""A body seen through caches its solver owns: :class:`OperatorCaches`, :class:`CachedBody`.

A provider answers "displacement here from pressure there" and keeps nothing. What recurs
across patches and solves (the half-space's Love offset tables and Chebyshev interpolation
matrices; the operators between pairs of patches: FFT kernel spectra, separated low-rank
blocks) is kept in an :class:`OperatorCaches` that a solver owns, bounded in bytes:
a :class:`~twoscale.solver.ContactSolver` keeps one for its life, a one-shot solve makes a
fresh one (:func:`with_caches`). :class:`CachedBody` is the provider the solvers then
receive: the body's answers, taken from those caches where they were built before.

On a body whose cell kernel depends only on lattice offsets (``translation_invariant``,
the half-space) a pair operator is kept under the pair's relative geometry (shapes, cell
offset, ``h``) and moved to the grids asked for: a scene shifted by whole cells (the next
position of a rolling road) finds every pair of patches it had before. Elsewhere pair
operators are kept under the grids themselves (the same scene solved again).
"""

from __future__ import annotations

import hashlib
from typing import Any, Callable

import numpy as np

from ..grid import Grid
from .base import GridOperator, InfluenceProvider
from .cache import BoundedCache

#: Bound of a solver's offset tables and interpolation matrices, bytes (about 200 of the
#: largest patch tables).
TABLE_CACHE_BYTES = 64e6
#: Bound of a solver's pair operators (kernel spectra, separated blocks), bytes.
OPERATOR_CACHE_BYTES = 192e6
#: What is kept for a pair too close for a separated operator (the answer ``None``).
_TOO_CLOSE = "too close"
#: Point sets from this size to :data:`KEPT_COMPLIANCE_POINTS` have their compliance among
#: themselves kept (:meth:`CachedBody.point_compliance`).
KEPT_COMPLIANCE_FROM = 64
#: Largest point set whose compliance among itself is kept (2,048^2 values, 34 MB).
KEPT_COMPLIANCE_POINTS = 2048


class OperatorCaches:
    """The bounded caches of one solver object (or of one one-shot solve).

    Parameters
    ----------
    table_bytes, operator_bytes : float
        Bounds of ``tables`` (offset tables, interpolation matrices) and ``operators``
        (pair operators), bytes.

    Attributes
    ----------
    tables, operators : BoundedCache
    solve : int
        The solve now running (entries remember the solve that built them, so that a
        solve can say what it took over from earlier ones).
    kept, built : dict
        This solve's pair operators by kind ("fft", "separated"): taken over from an
        earlier solve, and built by this one (a pair asked for again within the solve, or
        translated from one of its pairs, counts once).
    """

    def __init__(self, table_bytes: float = TABLE_CACHE_BYTES, operator_bytes: float = OPERATOR_CACHE_BYTES):
        self.tables = BoundedCache(table_bytes, name="offset tables")
        self.operators = BoundedCache(operator_bytes, name="pair operators")
        self.solve = 0
        self.kept: dict = {}
        self.built: dict = {}

    @property
    def nbytes(self) -> int:
        """Bytes held now (both caches)."""
        return int(self.tables.nbytes + self.operators.nbytes)

    @property
    def max_bytes(self) -> float:
        """The bound on :attr:`nbytes`."""
        return self.tables.max_bytes + self.operators.max_bytes

    def start_solve(self) -> None:
        """A new solve begins: its counts start at zero."""
        self.solve += 1
        self.kept, self.built = {}, {}

    def count(self, kind: str, kept: bool) -> None:
        """One more pair operator of ``kind`` taken over (``kept``) or built."""
        counts = self.kept if kept else self.built
        counts[kind] = counts.get(kind, 0) + 1

    def clear(self) -> None:
        """Drop every entry (a solver object's :meth:`~twoscale.solver.ContactSolver.reset`)."""
        self.tables.clear()
        self.operators.clear()


def _takes_tables(body: InfluenceProvider, method: str) -> bool:
    """Whether ``body``'s ``method`` takes the keyword ``tables``."""
    import inspect

    try:
        return "tables" in inspect.signature(getattr(body, method)).parameters
    except (TypeError, ValueError, AttributeError):
        return False


def _pair_key(kind: str, target: Grid, source: Grid, *extra) -> tuple:
    """Key of a pair operator on a translation-invariant body: the pair's relative geometry
    (the grids themselves when they are off each other's lattice)."""
    try:
        ti, tj = target.offset_in(source)
    except ValueError:
        return (kind, target, source, *extra)
    return (kind, float(source.h), target.nx, target.ny, source.nx, source.ny, ti, tj, *extra)


class CachedBody(InfluenceProvider):
    """``body`` answering through ``caches`` (the solver's): the same answers, with tables
    and pair operators kept there. Everything else is the body's (its kind, material,
    domain, on-disk caches, attributes)."""

    def __init__(self, body: InfluenceProvider, caches: OperatorCaches):
        if isinstance(body, CachedBody):
            body = body.body
        self.body, self.caches = body, caches
        self._invariant = bool(getattr(body, "translation_invariant", False))
        # the caller-owned tables go to the methods that take them (a subclass may not)
        self._tables = {
            name: {"tables": caches.tables} if self._invariant and _takes_tables(body, name) else {}
            for name in ("grid_matrix", "grid_entries", "grid_operator", "separated_operator")
        }

    def __getattr__(self, name: str) -> Any:
        # only reached for names this object does not have: the body's attributes
        if name in ("body", "caches", "_invariant", "_tables"):
            raise AttributeError(name)
        return getattr(self.body, name)

    def __repr__(self) -> str:
        return f"CachedBody({self.body!r})"

    @property
    def kind(self) -> str:  # type: ignore[override]
        return self.body.kind

    @property
    def material(self):  # type: ignore[override]
        return self.body.material

    @property
    def cheap_grid_matrix(self) -> bool:  # type: ignore[override]
        return bool(getattr(self.body, "cheap_grid_matrix", False))

    @property
    def surface_rises(self) -> bool:  # type: ignore[override]
        return bool(getattr(self.body, "surface_rises", False))

    # ------------------------------------------------------------------ the body's answers
    def point_compliance(self, targets, sources):
        """The body's. On a translation-invariant body (a function of each pair's offset)
        the compliance among one set of points (the targets are the sources) is kept, the
        last set only, and a later request among points most of which are kept is cut from
        it, the rows and columns of the others made by the body: the same values. The
        macro step's interaction among the tips is made again when the step is refined,
        and the coarse space's among the blocks' points are the tips but for merged blocks
        (their members' mean): 1,013 tips, three sets of 1e6 Boussinesq values, 0.05-0.1 s
        each, against 5 ms a cut."""
        n = len(targets)
        if not (self._invariant and KEPT_COMPLIANCE_FROM <= n <= KEPT_COMPLIANCE_POINTS and len(sources) == n):
            return self.body.point_compliance(targets, sources)
        points = np.asarray(targets, dtype=float)
        if not (sources is targets or np.array_equal(points, np.asarray(sources, dtype=float))):
            return self.body.point_compliance(targets, sources)
        kept = self.caches.operators.get(("compliance",))
        if kept is not None:
            where = np.array([kept[0].get(p, -1) for p in map(tuple, points.tolist())], dtype=np.intp)
            if 2 * np.count_nonzero(where >= 0) >= n:
                return _cut(kept[1], where, lambda t, s: self.body.point_compliance(points[t], points[s]))
        T = np.asarray(self.body.point_compliance(targets, sources), dtype=float)  # (the body's: a new array)
        index = {p: k for k, p in enumerate(map(tuple, points.tolist()))}
        self.caches.operators.put(("compliance",), (index, T.copy()), T.nbytes)
        return T

    def cell_block(self, targets, sources, h):
        return self.body.cell_block(targets, sources, h)

    def point_operator(self, targets, sources, *, exclude=None, rtol: float = 1e-6):
        """The body's point operator; on a translation-invariant body kept for later solves
        under the exact points (the far field of the same patches again)."""
        if not self._invariant:
            return self.body.point_operator(targets, sources, exclude=exclude, rtol=rtol)
        digest = hashlib.sha1()
        parts = [np.asarray(targets, dtype=float), np.asarray(sources, dtype=float)]
        if exclude is not None:  # a sparse pattern: its shape and stored positions
            import scipy.sparse as sp

            ex = sp.csr_matrix(exclude)
            parts += [np.array(ex.shape), ex.indptr, ex.indices]
        for arr in parts:
            arr = np.ascontiguousarray(arr)
            digest.update(repr((arr.shape, arr.dtype.str)).encode())
            digest.update(arr.tobytes())
        key = ("points", digest.hexdigest(), float(rtol))
        make = lambda: self.body.point_operator(targets, sources, exclude=exclude, rtol=rtol)
        return self._kept_or_made("points", key, make, _held_bytes)

    def smooth_self_compliance(self, points):
        return self.body.smooth_self_compliance(points)

    def self_compliance(self, h: float, at: tuple[float, float] = (0.0, 0.0)) -> float:
        return self.body.self_compliance(h, at)

    def domain(self):
        return self.body.domain()

    def cache_usage(self) -> tuple:
        return self.body.cache_usage()

    def split(self):
        base, correction = self.body.split()
        if correction is None and base is self.body:
            return self, None
        return CachedBody(base, self.caches), correction

    # ------------------------------------------------------------------ through the caches
    def grid_matrix(self, target: Grid, source: Grid | None = None) -> np.ndarray:
        return self.body.grid_matrix(target, source, **self._tables["grid_matrix"])

    def grid_entries(self, target: Grid, source: Grid, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """``grid_matrix(target, source)[np.ix_(rows, cols)]``: the body's own gather where
        it has one."""
        entries = getattr(self.body, "grid_entries", None)
        if entries is None:
            return self.grid_matrix(target, source)[np.ix_(rows, cols)]
        return entries(target, source, rows, cols, **self._tables["grid_entries"])

    def grid_operator(self, target: Grid, source: Grid | None = None) -> GridOperator:
        source = target if source is None else source
        if not self._invariant:
            return self.body.grid_operator(target, source)
        key = _pair_key("fft", target, source)
        op = self._kept("fft", key, target, source)
        if op is None:
            op = self._keep("fft", key, self.body.grid_operator(target, source, **self._tables["grid_operator"]))
        return op

    def separated_operator(self, target: Grid, source: Grid, *, rtol: float = 1e-8):
        if not self._invariant:
            return self.body.separated_operator(target, source, rtol=rtol)
        key = _pair_key("separated", target, source, rtol)
        op = self._kept("separated", key, target, source)
        if op is None:
            # a pair's two directions: the reverse one's operator transposed (no new kernel values)
            back = self._kept("separated", _pair_key("separated", source, target, rtol), source, target)
            op = back.transposed() if back is not None and back is not _TOO_CLOSE else back
        if op is None:
            op = self._keep(
                "separated",
                key,
                self.body.separated_operator(target, source, rtol=rtol, **self._tables["separated_operator"]),
            )
        return None if op is _TOO_CLOSE else op

    def factorisation(self, grid: Grid, cells: np.ndarray, make: Callable[[], tuple]) -> tuple:
        """A dense block's factorisation on ``cells`` (a boolean mask over ``grid``): kept in
        the solver's caches under the cells' geometry relative to the grid (on a
        translation-invariant body the same block anywhere has the same matrix), else
        ``make()`` (a ``(kind, factor)`` pair of arrays), kept for later solves."""
        if not self._invariant:
            return make()
        key = ("factor", float(grid.h), grid.nx, grid.ny, np.packbits(cells).tobytes())
        return self._kept_or_made("factor", key, make, _factor_bytes)

    def remembered(self, kind: str, key: tuple) -> Any:
        """A value an earlier solve kept under ``(kind, key)`` with :meth:`remember` (counted as
        taken over), else None; None also on a body that is not translation-invariant. A
        value kept by this solve is not returned: within a solve the arithmetic stays that
        of a one-shot solve."""
        if not self._invariant:
            return None
        hit = self.caches.operators.get((kind, *key))
        if hit is None or hit[0] >= self.caches.solve:
            return None
        self.caches.count(kind, kept=True)
        return hit[1]

    def remember(self, kind: str, key: tuple, value: np.ndarray) -> None:
        """Keep the array ``value`` under ``(kind, key)`` for later solves (counted as built)."""
        if self._invariant:
            self.caches.count(kind, kept=False)
            self.caches.operators.put((kind, *key), (self.caches.solve, value), value.nbytes)

    def _kept_or_made(self, kind: str, key: tuple, make: Callable[[], Any], size: Callable[[Any], int]) -> Any:
        """The value kept under ``key`` (counted as taken over when an earlier solve made
        it), else ``make()``, kept and counted as built."""
        hit = self.caches.operators.get(key)
        if hit is not None:
            made, value = hit
            if made < self.caches.solve:
                self.caches.count(kind, kept=True)
                self.caches.operators.put(key, (self.caches.solve, value), size(value))
            return value
        value = make()
        self.caches.count(kind, kept=False)
        self.caches.operators.put(key, (self.caches.solve, value), size(value))
        return value

    def _kept(self, kind: str, key: tuple, target: Grid, source: Grid):
        hit = self.caches.operators.get(key)
        if hit is None:
            return None
        made, op = hit
        if op is _TOO_CLOSE:
            return op
        if made < self.caches.solve:
            # taken over from an earlier solve: from now on it counts as this solve's
            self.caches.count(kind, kept=True)
            self.caches.operators.put(key, (self.caches.solve, op), op.nbytes)
        return op.moved(target, source)

    def _keep(self, kind: str, key: tuple, op):
        if op is None:
            self.caches.operators.put(key, (self.caches.solve, _TOO_CLOSE), 0)
            return _TOO_CLOSE
        self.caches.count(kind, kept=False)
        if hasattr(op, "moved"):  # an operator that cannot follow a translation is not kept
            self.caches.operators.put(key, (self.caches.solve, op), op.nbytes)
        return op


def _cut(kept: np.ndarray, where: np.ndarray, make: Callable) -> np.ndarray:
    """The compliance among points whose rows in ``kept`` are ``where`` (-1: not kept),
    those of the others by ``make(target_rows, source_rows)``."""
    n = len(where)
    have, miss = np.flatnonzero(where >= 0), np.flatnonzero(where < 0)
    # rows, then columns, by two takes (a two-index gather of 1,383 points' 1.9 M entries,
    # and its copy into place: 0.1 s of CPU a call); the others' rows and columns made after
    rows = np.where(where >= 0, where, 0)
    out = kept.take(rows, axis=0).take(rows, axis=1)
    if miss.size:
        out[miss, :] = make(miss, np.arange(n))
        out[np.ix_(have, miss)] = make(have, miss)
    return out


def _held_bytes(op: Any) -> int:
    """Bytes an operator holds in its arrays and sparse matrices (one level of attributes)."""
    total = 0
    for v in vars(op).values():
        if isinstance(v, np.ndarray):
            total += v.nbytes
        elif hasattr(v, "data") and hasattr(v, "indices"):  # scipy sparse
            total += v.data.nbytes + v.indices.nbytes + getattr(v, "indptr", v.indices).nbytes
    return int(total)


def _factor_bytes(f: tuple) -> int:
    """Bytes of a ``(kind, factor)`` pair (scipy's Cholesky or LU factor: arrays in a tuple)."""
    return int(sum(getattr(a, "nbytes", 0) for a in f[1]))


def with_caches(body: InfluenceProvider, caches: OperatorCaches | None = None) -> CachedBody:
    """``body`` through ``caches``; a body already seen through caches stays as it is
    unless ``caches`` are given; without either, fresh caches (a one-shot solve's)."""
    if isinstance(body, CachedBody) and caches is None:
        return body
    return CachedBody(body, OperatorCaches() if caches is None else caches)


__all__ = ["CachedBody", "OperatorCaches", "with_caches", "TABLE_CACHE_BYTES", "OPERATOR_CACHE_BYTES"]
