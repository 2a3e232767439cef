"""Influence blocks between patches ``A_kl`` (the coupling; ``A_kk`` with its local solves is
:class:`~.localblock.LocalBlock`).

Block ``k`` is the set of cells of patch ``k`` that asperity ``k`` owns; vectors on a block
are 1-D arrays over those cells (row-major order of the patch). Every number comes from the
influence provider (``grid_matrix`` for small blocks, ``grid_operator`` for large ones), so
the solver never knows which elastic body it works on.
"""

from __future__ import annotations

import math

import numpy as np

from ..influence.base import InfluenceProvider
from ..influence.separated import check_rtol
from .near_window import NearWindow
from .pair_entries import affordable_pairs, near_correction, pair_blocks
from .patches import Patch
from .route_bytes import preferred_bytes, spectrum_bytes, spectrum_is_smaller


def size_class(n: int) -> int:
    """Smallest size of the ladder 8, 10, 12, 14, 17, 21, ... (steps of ~20 %) that is
    >= ``n``: patches are enlarged to their class so that pairs of one class share a padded
    transform shape."""
    c = 8
    while c < n:
        c = max(c + 1, math.ceil(1.2 * c))
    return c


def scatter(patch: Patch, v: np.ndarray) -> np.ndarray:
    """Block vector(s) ``v`` (n,) or (n, m) onto the patch array(s) (ny, nx[, m]), zero elsewhere."""
    out = np.zeros(patch.grid.shape + v.shape[1:])
    out[patch.owned] = v
    return out


#: A dense pair block is cut from the provider's block of the two whole patch grids up to
#: this many entries (one strided copy); beyond it (and beyond 4x the owned cells' block)
#: the owned cells' block is computed directly.
GRID_BLOCK_MAX_ENTRIES = 1_000_000


class Coupling:
    """The off-diagonal blocks ``A_kl``: displacement on block ``k`` from pressure on block ``l``.

    Sums ``sum_l A_kl v_l`` (:meth:`rhs`) take one of three routes per pair, decided once:

    * *dense*: small pairs (``dense_max_entries``), the provider's block, cached;
    * *separated*: pairs far apart compared with their sizes, the provider's
      :meth:`~twoscale.influence.base.InfluenceProvider.separated_operator` (for the half-space a
      Chebyshev low-rank block within ``separated_rtol``); source moments once per block
      vector, node values summed per target before one interpolation;
    * *spectral*: the other pairs, the provider's FFT operator between the two patches
      enlarged to their size classes (:func:`size_class`, steps of 20 %); a block vector's
      spectrum is computed once per target class, and the sum over the sources of one class
      onto one target needs one inverse transform (per sweep about ``2N`` transforms per
      class instead of ``4N(N-1)``).

    Both use the operators' three stages of the contract
    (:class:`~twoscale.influence.base.GridOperator`: ``spectrum`` once per block vector and
    ``source_key``, ``multiply`` per pair, one ``finish`` per ``target_key``); an operator
    with only ``apply`` takes them too, through the contract's defaults.

    The last two use the translation-invariant part of the provider's kernel
    (:meth:`~twoscale.influence.base.InfluenceProvider.split`); a smooth low-rank remainder
    (the finite block's correction) is added per target from the sum of the sources'
    coefficients. Caches of per-vector quantities are keyed by the vector object, which
    the Gauss-Seidel sweeps replace (never modify) when a block changes.

    Parameters
    ----------
    provider : InfluenceProvider
    patches : sequence of Patch
    dense_max_entries : int, default 40_000
        Pairs whose dense block has at most this many entries are formed and cached
        (``provider.grid_matrix``); larger pairs use the routes above.
    cache_bytes : float, default 4e8
        Memory budget for cached dense pairs (beyond it pairs fall back to FFT); the dense
        pairs and all other cached pair operators together stay within twice it (so the
        other operators may use what the dense pairs leave; beyond it a pair takes the
        plain FFT product, rebuilt on use).
    separated_rtol : float or None, default 1e-8
        Accuracy of the separated route, relative to the pair's displacement; ``None``: no
        separated route.
    """

    def __init__(
        self,
        provider: InfluenceProvider,
        patches,
        *,
        dense_max_entries: int = 40_000,
        cache_bytes: float = 4e8,
        separated_rtol: float | None = 1e-8,
    ):
        check_rtol(separated_rtol, "separated_rtol", allow_none=True)
        self.provider = provider
        self.patches = list(patches)
        self.dense_max_entries = dense_max_entries
        self.cache_bytes = cache_bytes
        self.separated_rtol = separated_rtol
        self._base, self._correction = provider.split()
        self.separated_pairs = 0
        self._ops: dict = {}  # dense blocks (arrays)
        # a reciprocal kernel (translation-invariant, no correction: the half-space, whose
        # Love kernel is even) gives A_lk = A_kl^T: the reverse pair's block is its view
        self._reciprocal = self._correction is None and bool(getattr(self._base, "translation_invariant", False))
        self._mirrors: set = set()  # keys of _ops that are such views (no bytes of their own)
        # the pairs past the dense blocks' budget gathered from one kernel window (:mod:`.near_window`)
        self._window = NearWindow(provider) if self._reciprocal and NearWindow.usable(provider) else None
        self._fft: dict = {}
        self._bytes = 0.0
        self._fft_bytes = 0.0
        self._routes: dict = {}
        self._route_bytes, self.lean_routes = 0.0, False  # (:meth:`plan_routes`)
        # per block vector: source-side stages (spectra, Chebyshev moments) and correction
        # coefficients (see _per_vector)
        self._spectra: dict = {}
        self._coefficients: dict = {}

    def append(self, patch: Patch) -> None:
        """Add a patch (a new block at the end)."""
        self.patches.append(patch)

    def replace(self, k: int, patch: Patch) -> None:
        """Swap patch ``k`` (after growth) and drop every operator that involves it."""
        self.patches[k] = patch
        if self._window is not None:
            self._window.forget(k)
        self._spectra = {key: val for key, val in self._spectra.items() if key[0] != k}
        self._coefficients = {key: val for key, val in self._coefficients.items() if key[0] != k}
        for key in [key for key in self._routes if k in key]:
            self._route_bytes -= self._routes.pop(key)[2]
        for key in [key for key in self._ops if k in key]:
            M = self._ops.pop(key)
            self._bytes -= 0.0 if key in self._mirrors else M.nbytes
            self._mirrors.discard(key)
        for key in [key for key in self._fft if k in key]:
            self._fft_bytes -= self._fft.pop(key)[1]

    def keep_pairs(self, old: "Coupling", index: dict) -> None:
        """Take over ``old``'s dense pair blocks between patches both engines hold
        (``index``: a patch's index in ``old`` -> its index here, for the very same patch
        objects), within this engine's budget. Where a few contacts come to touch and
        their patches merge, the other pairs' blocks stay what they were (1,485 clustered
        spheres: one merge after the first sweep made all 2,466 near pairs' blocks again)."""
        for (k, l), M in old._ops.items():
            key = (index.get(k), index.get(l))
            if None in key or key in self._ops:
                continue
            own = 0.0 if (k, l) in old._mirrors else M.nbytes
            if self._bytes + own > self.cache_bytes:
                break
            self._ops[key] = M
            self._bytes += own
            if not own:
                self._mirrors.add(key)

    def full_operator(self, k: int, l: int):
        """Operator from the whole patch ``l`` to the whole patch ``k``: the provider's
        separated operator when the pair is far enough apart (``separated_rtol``), else its
        FFT operator; cached while the cached operators' size stays within the budget
        (``cache_bytes``)."""
        hit = self._fft.get((k, l))
        if hit is not None:
            return hit[0]
        back = self._fft.get((l, k))
        op = None if back is None else back[0].transposed()
        if op is not None:
            self._fft[(k, l)] = (op, 0.0)  # shares the reverse pair's arrays
            return op
        gk, gl = self.patches[k].grid, self.patches[l].grid
        if self.separated_rtol is not None and k != l:
            op = self.provider.separated_operator(gk, gl, rtol=self.separated_rtol)
            self.separated_pairs += op is not None
        if op is None:
            op = self.provider.grid_operator(gk, gl)
        size = float(op.nbytes)
        if self._operator_room(size):
            self._fft[(k, l)] = (op, size)
            self._fft_bytes += size
        return op

    def _operator_room(self, size: float) -> bool:
        # pair operators other than dense blocks may take what the dense blocks leave of
        # the two budgets (N = 10,000 sparse tips: dense pairs 169 MB, the others needed
        # ~450 MB; past 400 MB ~2,000 pairs rebuilt their operator on every sweep, 4 s)
        return self._fft_bytes + self._route_bytes + self._bytes + size <= 2.0 * self.cache_bytes

    def _dense(self, k: int, l: int) -> np.ndarray | None:
        """The dense block ``A_kl`` on the owned cells when the pair is small enough and the
        budget allows (cached in ``_ops``), else ``None`` (FFT pairs: :meth:`full_operator`)."""
        M = self._ops.get((k, l))
        if M is not None:
            return M
        back = self._ops.get((l, k)) if self._reciprocal else None
        if back is not None:
            # reciprocity: the reverse pair's block transposed, no new memory (half the
            # near pairs' blocks to make: 2,370 of 0.2 ms each on 939 scattered patches)
            self._ops[(k, l)] = back.T
            self._mirrors.add((k, l))
            return back.T
        pk, pl = self.patches[k], self.patches[l]
        nk, nl = int(pk.owned.sum()), int(pl.owned.sum())
        if (
            nk * nl <= self.dense_max_entries
            and self._bytes + 8.0 * nk * nl <= self.cache_bytes
            and self._operator_room(8.0 * nk * nl)
        ):
            ik = np.flatnonzero(pk.owned.ravel())
            il = np.flatnonzero(pl.owned.ravel())
            if pk.grid.size * pl.grid.size > max(4 * nk * nl, GRID_BLOCK_MAX_ENTRIES):
                # few owned cells on large grids (a patch overlapped by its neighbours): the
                # block of the owned cells alone, not the grids' block cut down (22 clustered
                # spheres: 0.9 s and up to 4 GB a pair for blocks of at most 40,000 entries)
                M = self.provider.cell_block(pk.grid.points()[ik], pl.grid.points()[il], pk.grid.h)
            elif hasattr(self.provider, "grid_entries"):  # the same numbers, without the whole matrix
                M = self.provider.grid_entries(pk.grid, pl.grid, ik, il)
            else:
                M = self.provider.grid_matrix(pk.grid, pl.grid)[np.ix_(ik, il)]
            self._bytes += M.nbytes
            self._ops[(k, l)] = M
            return M
        return None

    def prepare_dense(self, pairs) -> None:
        """Make the dense blocks of ``pairs`` ``(k, l)`` that :meth:`_dense` would make, in one
        pass where the kernel is translation-invariant (:func:`.pair_entries.pair_blocks`:
        the same numbers); the reverse pairs are their views as before."""
        if not (self._reciprocal and hasattr(self.provider, "grid_entries")):
            return
        fits = lambda size: self._bytes + size <= self.cache_bytes and self._operator_room(size)  # noqa: E731
        todo = affordable_pairs(self.patches, pairs, self._ops, self.dense_max_entries, fits, GRID_BLOCK_MAX_ENTRIES)
        for key, M in pair_blocks(self.provider, self.patches, todo).items():
            self._ops[key] = M
            self._bytes += M.nbytes

    def plan_routes(self, pairs) -> None:
        """:attr:`lean_routes` where the new routes of ``pairs`` overflow the budget (:mod:`.route_bytes`)."""
        new = [(k, l) for k, l in pairs if (k, l) not in self._routes and (l, k) not in self._routes]
        need = preferred_bytes(self.patches, new, self.dense_max_entries, self.separated_rtol, self._enlarged)
        self.lean_routes = bool(self._fft_bytes + self._route_bytes + self._bytes + need > 2.0 * self.cache_bytes)

    _enlarged = staticmethod(lambda g: g.subgrid(0, 0, size_class(g.nx), size_class(g.ny)))  # the spectral route's

    def apply(self, k: int, l: int, v: np.ndarray) -> np.ndarray:
        """``A_kl v`` for a block-``l`` vector (n_l,) or (n_l, m); returns block-``k`` values (mm)."""
        M = self._dense(k, l)
        if M is not None:
            return M @ v
        pk, pl = self.patches[k], self.patches[l]
        u = None if self._window is None else self._window.product(k, pk, l, pl, v)
        if u is not None:
            self._window.pairs.add((k, l))
            return u
        op = self.full_operator(k, l)
        if v.ndim == 1:
            return op.apply(scatter(pl, v))[pk.owned]
        return np.column_stack([op.apply(scatter(pl, v[:, j]))[pk.owned] for j in range(v.shape[1])])

    def _whole(self, k: int, l: int, v: np.ndarray) -> np.ndarray:
        """``A_kl v`` on the whole patch ``k`` (ny, nx), for a 1-D block vector."""
        pk, pl = self.patches[k], self.patches[l]
        u = None if self._window is None else self._window.product(k, pk, l, pl, v, whole=True)
        return self.full_operator(k, l).apply(scatter(pl, v)) if u is None else u

    def rhs(self, k: int, values: list, rhs: np.ndarray) -> np.ndarray:
        """``rhs - sum_{l != k} A_kl v_l`` with the block vectors ``values`` (mm)."""
        out = rhs.copy()
        self._subtract(k, [l for l in range(len(values)) if l != k], values, out)
        return out

    def route_counts(self) -> dict:
        """Ordered pairs per route so far: ``dense``, ``fft`` (plain FFT products), ``separated``,
        ``spectral``; and the ``separated_rtol`` in use (for the result's record)."""
        out = {"dense": 0, "fft": 0, "separated": 0, "spectral": 0}
        for key, (kind, _, _) in self._routes.items():
            if kind == "plain":
                kind = "dense" if key in self._ops else "fft"
            out[kind] += 1
        out["separated_rtol"] = self.separated_rtol
        return out

    # ------------------------------------------------------------------ routes
    def _route(self, k: int, l: int) -> tuple:
        """``(kind, operator, bytes)`` of the pair: kind "plain" (dense block or a plain
        product by :meth:`apply`), "separated" or "spectral" (operators of the kernel's
        translation-invariant part)."""
        key = (k, l)
        hit = self._routes.get(key)
        if hit is not None:
            return hit
        route = ("plain", None, 0.0)
        pk, pl = self.patches[k], self.patches[l]
        back = self._routes.get((l, k), route)
        mirror = None if back[1] is None else back[1].transposed()
        if mirror is not None:
            # the reverse pair's operator transposed (reciprocity): no new memory
            self.separated_pairs += back[0] == "separated"
            route = (back[0], mirror, 0.0)
        elif int(pk.owned.sum()) * int(pl.owned.sum()) > self.dense_max_entries:
            op, kind, big, gk, gl, rtol = None, "separated", self._enlarged, pk.grid, pl.grid, self.separated_rtol
            lean = self.lean_routes  # past the budget: the route holding fewer bytes
            if rtol is not None and not (lean and spectrum_is_smaller(gk, gl, big(gk), big(gl), rtol)):
                op = self._base.separated_operator(gk, gl, rtol=rtol)
                op = None if lean and op is not None and op.nbytes > spectrum_bytes(big(gk), big(gl)) else op
            if op is None:
                kind = "spectral"
                op = self._base.grid_operator(big(pk.grid), big(pl.grid))
            size = float(op.nbytes)
            if self._operator_room(size):
                route = (kind, op, size)
                self._route_bytes += size
                self.separated_pairs += kind == "separated"
        self._routes[key] = route
        return route

    def _subtract(self, k: int, sources, values: list, out: np.ndarray) -> None:
        """``out -= sum_{l in sources} A_kl v_l`` on block ``k``'s cells."""
        if not len(sources):
            return
        u = self._sum(k, sources, values, whole=False)
        if u is not None:
            out -= u

    def _sum(self, k: int, sources, values: list, *, whole: bool):
        """``sum_{l in sources} A_kl v_l`` by the pairs' routes (class docstring), on block
        ``k``'s cells or (``whole``, 1-D vectors only) on the whole patch; ``None`` if no
        source carries pressure."""
        pk = self.patches[k]
        pick = (lambda a: a) if whole else (lambda a: a[pk.owned])
        total = None
        # per route, the sum of multiply results per target_key (routes kept apart, and in this
        # order, so that the sums are added in the same order whatever the operators)
        staged: dict = {"separated": {}, "spectral": {}}
        smooth = []
        for l in sources:
            v = values[l]
            if v is None or not np.count_nonzero(v):
                continue
            kind, op, _ = self._route(k, l) if v.ndim == 1 else ("plain", None, 0.0)
            if kind == "plain":
                if whole:
                    term = self._whole(k, l, v)
                else:
                    term = self.apply(k, l, v)
                total = term if total is None else total + term
                continue
            smooth.append(l)
            term = op.multiply(self._spectrum(l, op, v))
            groups, key = staged[kind], op.target_key
            if key in groups:
                groups[key][1] += term
            else:
                groups[key] = [op, term]
        # spectral targets are enlarged to their size class: the patch is their corner
        parts = [
            pick(op.finish(acc)[: pk.grid.ny, : pk.grid.nx])
            for groups in staged.values()
            for op, acc in groups.values()
        ]
        if self._correction is not None and smooth:
            parts.append(pick(near_correction(self, pk.grid, smooth, values)))
        for term in parts:
            total = term if total is None else total + term
        return total

    @staticmethod
    def _per_vector(store: dict, key: tuple, v: np.ndarray, compute):
        """``compute()`` for block vector ``v``, reused while ``store[key]`` was made from this
        very vector object (the sweeps replace a block's vector when it changes; the store
        keeps ``v`` alive, so its identity cannot be reused by another array)."""
        hit = store.get(key)
        if hit is not None and hit[0] is v:
            return hit[1]
        out = compute()
        store[key] = (v, out)
        return out

    def _spectrum(self, l: int, op, v: np.ndarray) -> np.ndarray:
        """``op.spectrum`` of block ``l``'s vector ``v`` on the operator's source grid (the
        patch, or the patch enlarged to its size class: the patch is its corner), shared by
        the operators with the same ``source_key``."""

        def compute():
            p = np.zeros(op.source.shape)
            pl = self.patches[l]
            p[: pl.grid.ny, : pl.grid.nx][pl.owned] = v
            return op.spectrum(p)

        return self._per_vector(self._spectra, (l, op.source_key), v, compute)

    def patch_displacement(self, k: int, values: list) -> np.ndarray:
        """Displacement (mm) on the whole patch ``k`` (ny, nx) due to the blocks ``l != k``."""
        u = self._sum(k, [l for l in range(len(values)) if l != k], values, whole=True)
        return np.zeros(self.patches[k].grid.shape) if u is None else u
