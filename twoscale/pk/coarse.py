"""A coarse correction of the kernel's torus preconditioner over squares of the grid
(:class:`SquaresCorrection`).

The torus inverse ``C`` (:class:`~twoscale.influence.circulant.CirculantInverse`) removes the
error inside each contact in a few steps, but not the error shared by many contacts far apart
(their common sinking under the others' 1/r fields): on boxes of thousands of separated tips
the kernel's residual then halves per step. A coarse space ``Z`` of one function per square of
``side`` cells (the indicator of the square's loaded cells) deflates those modes: with
``E = Z^T A Z`` the search direction of the projected gap ``v`` is::

    c = E^-1 Z^T v,    d = C (v - A Z c) + Z c

(a coarse solve first, then the torus inverse on what it leaves: Tang, Nabben, Vuik & Erlangga
2009, "A-DEF1"-like; on the loaded cells ``S``). ``E`` is assembled on the loaded cells when the
contact has nearly settled (at most ``START`` of them changed in the last step; before, the
set moves by thousands of cells a step and ``E`` would be stale at once), and kept: its squares
are the ones loaded then, the cells that leave or enter later change ``Z`` (masked by the
current set) but not ``E``. The kernel restarts its conjugate directions at the switch
(:meth:`Corrected.restart`).

``E``: pairs of squares at most one square apart exactly, from the cross-correlation of their
loaded cells by small FFTs of the squares and Parseval against the kernel's offset table;
pairs farther apart as point loads at their loaded cells' centroids (the kernel interpolated
in its table). ``A Z c`` by a precorrected FFT on the loaded cells
(:class:`~twoscale.influence.precorrected.Precorrected`, about 1e-3 relative: a
preconditioner's product), a few ms instead of a padded FFT product.
"""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft
import scipy.linalg as sla
from scipy.spatial.distance import cdist

from ..influence.circulant import torus_shape
from ..influence.precorrected import Precorrected

#: The squares' side, cells. Seed 1's #101 (1,689 tips on 997 x 997 cells; union CG 27
#: iterations): sides 25 / 50 (1,233 / 397 squares loaded) 16 / 18 iterations.
SIDE = 25
#: The correction starts at the first step that changed at most this fraction of the loaded
#: cells. #101: 0.1 / 0.01 / 0.002 -> 14 / 16 / 18 iterations (the correction from its 2nd /
#: 7th / 11th step).
START = 0.01
#: At most this many loaded squares (``E`` dense, its Cholesky factor ``K^3 / 3`` flops):
#: beyond, no correction.
MAX_SQUARES = 2500
#: The correction is built only on grids of at least this many cells (on smaller ones an
#: iteration costs less than the build and the corrected steps' extra: 400 spheres on 261 x
#: 261 cells, 26 -> 20 iterations for the same CPU; seed 7's #3 and seed 6's #46, 179-191 K
#: cells, 20 -> 13 and 25 -> 15 for the same CPU; seed 7's #55, 505 x 517 cells, 24 -> 14
#: for 1.13x the CPU in 8 replayed pairs, where seed 7's #177, 612 x 613, takes 32 -> 20 for
#: 0.91x and every box of the earlier gains has at least 389 K cells) ...
MIN_CELLS = 300_000
#: ... and where the loaded squares are at most this full, weighted by their loaded cells
#: (``sum n_i^2 / (side^2 sum n_i)``): the precorrected product has about ``(2 r + 1)^2`` x
#: that near pairs a loaded cell, and contacts of a few large patches gain few iterations.
#: Thousands of tips (seeds 1's #101, 5's #20, 6's #147 and #1, 0's #12): 0.036-0.093; the
#: roads (seed 5's #130, the 100 mm road: 23 -> 20 iterations for twice the CPU): 0.31-0.51.
MAX_FILL = 0.2
#: The precorrected product's coarse spacing and near radius (cells) for ``A Z c``.
PRODUCT_COARSE, PRODUCT_RADIUS = 7, 10
#: The near offsets (in squares) whose pairs are summed exactly (with their mirror images).
NEAR_OFFSETS = ((0, 0), (0, 1), (1, -1), (1, 0), (1, 1))


class SquaresCorrection:
    """The kernel's preconditioner ``precondition(v, on)``: the torus ``inverse`` with the
    squares' coarse correction, on the grid of ``shape`` whose kernel is given at every
    offset by ``table`` (``GridOperator.coarse_table``: entry ``(m, n)`` the offset
    ``(m - ny + 1, n - nx + 1)``, mm/MPa; on a bonded block the half-space's, whose ``E`` and
    ``A Z c`` only approximate the block's: the balancing form stays symmetric positive
    definite, the CG exact). :meth:`on_part` gives it on a part's cells;
    ``op`` is the torus inverse (the precorrected route's sparse torus replaces it whole)."""

    def __init__(self, inverse, table: np.ndarray, shape: tuple, side: int = SIDE, start: float = START):
        self.op, self.table, self.shape = inverse, table, (int(shape[0]), int(shape[1]))
        self.side, self.start = int(side), float(start)
        self._whole: Corrected | None = None

    def on_part(self, cells: np.ndarray | None) -> "Corrected | None":
        if cells is None:  # every cell: the rows as the torus's own field, no scatter and gather
            apply = self._every_cell if torus_shape(self.op.source) != self.shape else None
            cells = np.arange(self.shape[0] * self.shape[1])
        else:
            cells = np.asarray(cells, dtype=np.intp)
            apply = self.op.on_cells(cells)
        return None if apply is None else Corrected(apply, self, cells)

    def _every_cell(self, values: np.ndarray) -> np.ndarray:
        """The torus inverse on the whole grid's values (n,): its own product of a field
        smaller than the torus (:meth:`~twoscale.influence.circulant.CirculantInverse.apply`,
        the same transforms as on the cells, bit for bit), where ``on_cells`` of every cell
        scatters and gathers them by index (604 x 593 cells on a 675 x 675 torus: 4.6
        against 5.6 ms a call)."""
        return self.op.apply(values.reshape(self.shape)).ravel()

    def restart(self) -> bool:
        """:meth:`Corrected.restart` of the whole grid's rows."""
        return self._whole is not None and self._whole.restart()

    def __call__(self, v: np.ndarray, on: np.ndarray) -> np.ndarray:
        """On whole-grid rows (1, ny, nx)."""
        if self._whole is None:
            self._whole = self.on_part(None)
        if self._whole is None:  # (the torus is the grid: no pruned product on cells)
            return self.op.apply(v[0])[None]
        return self._whole(v.reshape(1, -1), on.reshape(1, -1)).reshape(v.shape)


class Corrected:
    """:class:`SquaresCorrection` on the flat ``cells`` of its grid (the kernel's rows),
    ``torus`` the inverse's product on them (values in and out, (m,))."""

    def __init__(self, torus, owner: SquaresCorrection, cells: np.ndarray):
        self.torus, self.owner, self.cells = torus, owner, cells
        self.previous: np.ndarray | None = None
        self.coarse: CoarseSpace | None = None
        self.switched = False
        self.tried = False

    def restart(self) -> bool:
        """Whether the preconditioner changed at its last call (the kernel then restarts its
        conjugate directions); cleared by asking."""
        switched, self.switched = self.switched, False
        return switched

    def __call__(self, v: np.ndarray, on: np.ndarray) -> np.ndarray:
        values, loaded = v[0], on[0]
        if self.coarse is None and not self.tried:
            self._maybe_start(loaded)
        if self.coarse is None:
            return self.torus(values)[None]
        return self.coarse.direction(values, loaded, self.torus)[None]

    def _maybe_start(self, loaded: np.ndarray) -> None:
        previous, self.previous = self.previous, loaded.copy()
        if previous is None:
            return
        count = np.count_nonzero(loaded)
        if count and np.count_nonzero(previous != loaded) <= self.owner.start * count:
            self.tried = True
            self.coarse = CoarseSpace.build(self.owner, self.cells, loaded)
            self.switched = self.coarse is not None


class CoarseSpace:
    """The squares' coarse space on the loaded cells of one step: each part cell's square
    (``square``, -1 off the squares then loaded), the Cholesky factor of ``E``, and the
    precorrected product on the cells loaded then (``product``, their part indices ``at``)."""

    def __init__(self, square: np.ndarray, factor, product: Precorrected, at: np.ndarray):
        self.square, self.factor, self.product, self.at = square, factor, product, at
        self.index = square[at]  # the square of each cell loaded at the build
        self.k = int(square.max()) + 1

    @classmethod
    def build(cls, owner: SquaresCorrection, cells: np.ndarray, loaded: np.ndarray) -> "CoarseSpace | None":
        """On the part ``cells`` (flat grid indices) whose ``loaded`` ones are the contact;
        None on a small grid or full squares (``MIN_CELLS``, ``MAX_FILL``), when the
        squares are too many or ``E`` is not positive definite."""
        (ny, nx), s = owner.shape, owner.side
        at = np.flatnonzero(loaded)
        if ny * nx < MIN_CELLS or not len(at):
            return None
        y, x = np.divmod(cells[at], nx)
        columns = -(-nx // s)
        keys, index = np.unique((y // s) * columns + x // s, return_inverse=True)
        count = np.bincount(index).astype(float)
        if len(keys) > MAX_SQUARES or float(count @ count) > MAX_FILL * s * s * len(at):
            return None
        energy = coarse_matrix(owner.table, (ny, nx), s, keys, index, y, x)
        try:
            factor = sla.cho_factor(energy, lower=True, check_finite=False)
        except sla.LinAlgError:
            return None
        square = np.full(len(cells), -1, dtype=np.intp)
        square[at] = index
        product = Precorrected(owner.table, (ny, nx), cells[at], PRODUCT_COARSE, PRODUCT_RADIUS)
        return cls(square, factor, product, at)

    def direction(self, v: np.ndarray, loaded: np.ndarray, torus) -> np.ndarray:
        """``P v = Q^T C Q v + Z E^-1 Z^T v``, ``Q = I - A Z E^-1 Z^T``, on the cells loaded now
        (``Z`` and ``A`` on those also loaded then, ``D``): symmetric positive definite for any
        positive definite ``E`` and a symmetric ``A`` on ``D``, however well the two agree.
        ``Z``, ``A`` and the coarse solves act on the cells loaded at the build (``at``) alone."""
        member = loaded[self.at]  # D among them
        which = self.index[member]
        first = self._solve(v[self.at][member], which)
        w = np.multiply(v, loaded, dtype=float)
        w[self.at] = (v[self.at] - self._on_member(np.where(member, first[self.index], 0.0), member)) * member
        y = np.array(torus(w))
        y *= loaded
        second = self._solve(self._on_member(np.where(member, y[self.at], 0.0), member)[member], which)
        y[self.at[member]] += first[which] - second[which]
        return y

    def _solve(self, values: np.ndarray, which: np.ndarray) -> np.ndarray:
        """``E^-1 Z^T v`` for ``v``'s ``values`` on the member cells (squares ``which``)."""
        return sla.cho_solve(self.factor, np.bincount(which, weights=values, minlength=self.k), check_finite=False)

    def _on_member(self, values: np.ndarray, member: np.ndarray) -> np.ndarray:
        """``R_D A R_D v`` on the cells loaded at the build, ``values`` there zero off ``D``
        (the ``member`` ones)."""
        return np.where(member, self.product(values), 0.0)


def coarse_matrix(table: np.ndarray, shape: tuple, side: int, keys, index, y, x) -> np.ndarray:
    """``E = Z^T A Z`` (mm/MPa, (K, K)) for the squares ``keys`` (row-major ids on a lattice of
    squares of ``side`` cells over a grid of ``shape``) of the loaded cells at ``(y, x)``,
    ``index`` each cell's square: exact for squares at most one apart (:func:`near_sums`),
    point loads at the centroids beyond (:func:`kernel_between`)."""
    k = len(keys)
    count = np.bincount(index, minlength=k).astype(float)
    centroids = np.stack([np.bincount(index, y, k), np.bincount(index, x, k)], axis=1) / count[:, None]
    energy = kernel_between(table, shape, cdist(centroids, centroids))
    energy *= count[:, None]
    energy *= count[None, :]
    a, b, values = near_sums(table, shape, side, keys, index, y, x)
    energy[a, b] = values
    energy[b, a] = values
    return energy


def kernel_between(table: np.ndarray, shape: tuple, rho: np.ndarray) -> np.ndarray:
    """The kernel between point loads ``rho`` cells apart (at least one, in place): ``k / rho``,
    ``k`` from the table's farthest offset along the longer axis (Love's cell kernel is the
    point load's within ``1 / (24 rho^2)`` relative at ``rho`` cells)."""
    ny, nx = shape
    far = max(ny, nx) - 1
    k = table[ny - 1, nx - 1 + far] if nx >= ny else table[ny - 1 + far, nx - 1]
    np.maximum(rho, 1.0, out=rho)
    return np.divide(k * max(far, 1), rho, out=rho)


def near_sums(table: np.ndarray, shape: tuple, side: int, keys, index, y, x):
    """``sum_{a in i, b in j} A_ab`` for the squares ``i``, ``j`` at most one apart: pairs
    ``(i, j)`` and their sums. Each square's loaded cells as an indicator ``B_i`` on a field of
    ``2 side`` cells per axis, the pair's sum ``sum_e W(e) (B_i * B_j)(e)`` (the kernel ``W``
    at the squares' offset plus ``e``, the cross-correlation ``*``), by Parseval from the
    squares' spectra: a pass over a half spectrum per pair."""
    (ny, nx), s = shape, side
    columns, n2 = -(-nx // s), 2 * s
    indicator = np.zeros((len(keys), s, s), np.float32)
    indicator[index, y % s, x % s] = 1.0
    spectra = sfft.rfft2(indicator, s=(n2, n2))  # (complex64: the sums to ~1e-7, a preconditioner's)
    weight = np.full(n2 // 2 + 1, 2.0)
    weight[0] = weight[-1] = 1.0  # (the half spectrum's columns without a mirror)
    e = np.arange(-(s - 1), s)
    out_a, out_b, out_v = [], [], []
    for di, dj in NEAR_OFFSETS:
        j = np.searchsorted(keys, keys + di * columns + dj)
        j = np.minimum(j, len(keys) - 1)
        col = keys % columns + dj
        ok = (keys[j] == keys + di * columns + dj) & (col >= 0) & (col < columns)
        a, b = np.flatnonzero(ok), j[ok]
        if not len(a):
            continue
        window = np.zeros((n2, n2))
        dy = np.clip(np.abs(di * s + e), 0, ny - 1)
        dx = np.clip(np.abs(dj * s + e), 0, nx - 1)
        window[np.ix_(e % n2, e % n2)] = table[dy[:, None] + ny - 1, dx[None, :] + nx - 1]
        kernel = (sfft.rfft2(window) * (weight / (n2 * n2))).astype(np.complex64)
        left = spectra * kernel if di == dj == 0 else spectra[a] * kernel
        right = spectra if di == dj == 0 else spectra[b]
        # Re(sum L conj R) = sum (Re L Re R + Im L Im R): the float views' dot, no conjugate copy
        flat = left.reshape(len(a), -1).view(np.float32), right.reshape(len(a), -1).view(np.float32)
        sums = np.einsum("pi,pi->p", *flat).astype(float)
        out_a.append(a)
        out_b.append(b)
        out_v.append(sums)
    return np.concatenate(out_a), np.concatenate(out_b), np.concatenate(out_v)
