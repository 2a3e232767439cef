"""The influence-provider contract.

An influence provider answers three questions, all about the vertical surface
displacement ``u`` (mm, positive into the body) of the elastic body:

* point-to-point compliance (macro step): ``u`` at tip ``k`` per unit point force (N)
  at tip ``l``, :meth:`InfluenceProvider.point_compliance`;
* cell-to-cell blocks (micro step): ``u`` at the centre of cell ``i`` per unit uniform
  pressure (MPa) on the square cell ``j`` of side ``h``,
  :meth:`InfluenceProvider.cell_block` (arbitrary cells) and
  :meth:`InfluenceProvider.grid_matrix` (aligned grids, fast path);
* fast products on aligned grids, :meth:`InfluenceProvider.grid_operator`, which
  returns a :class:`GridOperator` applying the same matrix without forming it.

All three describe the same linear map; providers must keep them consistent
(tests check ``grid_operator`` against ``grid_matrix`` against ``cell_block``).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Callable

import numpy as np

from ..grid import Grid
from ..material import Material
from .points import DensePointOperator, PointOperator


class GridOperator(ABC):
    """Linear map from pressure on the ``source`` grid to displacement on ``target``.

    ``apply(p)`` takes an array of shape ``source.shape`` (MPa) and returns one of
    shape ``target.shape`` (mm). Operators are immutable: they hold precomputed
    transforms, never solutions.

    Only :meth:`apply` is required. Solvers that sum the products of many sources onto one
    target also use its three stages, ``apply(p) == finish(multiply(spectrum(p)))``:

    * :meth:`spectrum` — a source-side transform of ``p``, reused by every operator with the
      same :attr:`source_key` (e.g. an FFT, or Chebyshev moments);
    * :meth:`multiply` — the operator on that transform (a new array);
    * :meth:`finish` — back to the target grid; ``multiply`` results of operators with the
      same :attr:`target_key` may be added before one ``finish``.

    The defaults work from ``apply`` alone (``spectrum`` is ``p``, ``multiply`` applies,
    ``finish`` is the identity), so a new body plugs in without them, only without the
    speed-up. An operator that overrides one stage overrides all three and both keys.
    """

    target: Grid
    source: Grid

    @abstractmethod
    def apply(self, p: np.ndarray) -> np.ndarray:
        """Displacement on the target grid, mm, from pressure ``p`` on the source grid, MPa."""

    def __call__(self, p: np.ndarray) -> np.ndarray:
        return self.apply(p)

    def apply_stack(self, P: np.ndarray) -> np.ndarray:
        """:meth:`apply` on a stack of pressures (B, ny, nx) -> (B, target ny, nx), mm.
        Default: one :meth:`apply` per pressure; FFT operators transform the stack at once
        (many small blocks of one size solved together: one call instead of B)."""
        return np.stack([self.apply(p) for p in P]) if len(P) else np.zeros((0, *self.target.shape))

    def kept_stack(self, workspace=None) -> Callable[[np.ndarray], np.ndarray]:
        """:meth:`apply_stack` as a callable that may take its arrays from ``workspace`` (a
        :class:`~twoscale.influence.stacked.Workspace` the caller keeps for a solve and
        shares among its stacked products; None: one of the callable's own), for a caller
        that applies this operator to many stacks of one shape. Default: :meth:`apply_stack`."""
        return self.apply_stack

    def spectrum(self, p: np.ndarray) -> np.ndarray:
        """Source-side transform of the pressure ``p`` (``source.shape``, MPa); default ``p``."""
        return p

    def multiply(self, s: np.ndarray) -> np.ndarray:
        """The operator on a :meth:`spectrum` (a new array, which callers may add to in place);
        default: the displacement ``apply(s)`` (mm)."""
        return np.array(self.apply(s), dtype=float)

    def finish(self, a: np.ndarray) -> np.ndarray:
        """Displacement on the target grid (mm) from a (sum of) :meth:`multiply` result(s);
        ``a`` may be overwritten. Default: ``a`` (already a displacement)."""
        return a

    def single_precision(self) -> "GridOperator":
        """The same operator computing in single precision where that is cheaper (e.g.
        float32 FFTs), for the first iterations of a solve that finishes in double
        precision (:func:`twoscale.reference.cg.solve_cg` ``precision="mixed"``); it
        takes and returns float64 arrays. Default: ``self`` (no cheaper variant)."""
        return self

    def columns(self, targets: np.ndarray | None = None):
        """A callable ``add(out, cells, values)`` that adds to ``out`` (the target's cells,
        flattened, mm; with ``targets``, flat target cells, only those, in that order) the
        displacement of the pressures ``values`` (MPa) on the flat source ``cells`` alone,
        exactly and at a cost per cell, for an iteration that changes a few cells between
        products; None (default) when the operator has no such cheap form."""
        return None

    def preconditioner(self) -> "GridOperator | None":
        """An operator close to this one's inverse (square operators: ``source == target``),
        cheap to apply, for preconditioned solves (:func:`twoscale.reference.cg.solve_cg`
        ``precondition=True``); it takes a gap (mm) and returns a pressure-like array (MPa).
        Default: None (the solver then runs unpreconditioned)."""
        return None

    def coarse_table(self) -> np.ndarray | None:
        """The offset table (mm/MPa; as :meth:`~.convolution.ConvolutionOperator.offset_table`)
        of a translation-invariant kernel close to this square operator's, for a
        preconditioner's coarse space (:class:`~twoscale.pk.coarse.SquaresCorrection`), or
        None. Default: the operator's own ``offset_table()`` where it has one (a convolution)."""
        own = getattr(self, "offset_table", None)
        return None if own is None else own()

    def transposed(self) -> "GridOperator | None":
        """The operator from ``target`` to ``source`` sharing this one's arrays, or None
        (default) when it has no such cheap form. Cell influence is reciprocal on every
        elastic body (Maxwell-Betti: ``A_ts = A_st^T`` for cells of one size), so callers that
        need both directions of a pair may take one from the other."""
        return None

    @property
    def source_key(self) -> tuple:
        """Operators with equal keys give equal :meth:`spectrum` for equal pressure arrays.
        Values only (never ``id``); default: the class and the source grid."""
        return ("apply", type(self), self.source)

    @property
    def target_key(self) -> tuple:
        """Operators with equal keys accept the sum of their :meth:`multiply` results in one
        :meth:`finish`. Default: the class and the target grid."""
        return ("apply", type(self), self.target)

    @property
    def nbytes(self) -> int:
        """Bytes the operator holds, for callers' cache budgets. The default estimates a
        zero-padded half-spectrum of the pair; operators that know better say so."""
        return 8 * (self.target.nx + self.source.nx) * (self.target.ny + self.source.ny)

    @property
    def flops_estimate(self) -> float:
        """Rough cost of one :meth:`apply` in floating-point operations."""
        return float(self.target.size * self.source.size)


class LowRankCorrection(ABC):
    """A smooth part of a provider's kernel in factored form (see :meth:`InfluenceProvider.split`):
    the displacement on a target grid from pressure on any source grids is
    ``evaluate(target, sum_s coefficients(source_s, p_s))``, the coefficients living on one
    node space shared by every grid (vectors may be shorter than later ones when the space
    grows: missing entries are zero)."""

    @abstractmethod
    def coefficients(self, source: Grid, p: np.ndarray) -> np.ndarray:
        """Node coefficients of pressure ``p`` (``source.shape``, MPa), 1-D."""

    @abstractmethod
    def evaluate(self, target: Grid, c: np.ndarray) -> np.ndarray:
        """Displacement (mm) on ``target`` (``target.shape``) from node coefficients ``c``."""

    def at_points(self, targets: np.ndarray, c: np.ndarray) -> np.ndarray | None:
        """Displacement (mm) at the surface points ``targets`` ((M, 2), mm) from node
        coefficients ``c``, (M,); None where the correction has no value at points (callers
        then take the provider's whole kernel)."""
        return None


class InfluenceProvider(ABC):
    """Compliance of an elastic body's surface; see the module docstring."""

    #: Short name used in results and files ("halfspace", "block", ...).
    kind: str = "abstract"
    #: The body's material (E in MPa, nu); the half-space part of any body.
    material: Material
    #: Whether :meth:`grid_matrix` is cheap next to factorising the block it returns (the
    #: half-space's is a strided copy from cached kernel values): solvers may then rebuild a
    #: block when they need it instead of storing it.
    cheap_grid_matrix: bool = False
    #: Whether a pressure that is nowhere negative can raise the surface somewhere (a bonded,
    #: nearly incompressible block bulges beside its contacts); False: the surface only
    #: sinks (the half-space), so no tip above the approach can touch.
    surface_rises: bool = False

    @abstractmethod
    def point_compliance(self, targets: np.ndarray, sources: np.ndarray) -> np.ndarray:
        """Displacement at ``targets`` per unit normal point force at ``sources``.

        Parameters
        ----------
        targets : (M, 2) array, mm
        sources : (N, 2) array, mm

        Returns
        -------
        (M, N) array, mm/N, a new one the caller owns (it may write into it). Coincident
        points give ``inf`` (the point-force displacement is singular); callers use the
        off-diagonal part only.
        """

    @abstractmethod
    def cell_block(self, targets: np.ndarray, sources: np.ndarray, h: float) -> np.ndarray:
        """Displacement at cell centres ``targets`` per unit uniform pressure on the
        square cells of side ``h`` centred at ``sources``.

        Parameters
        ----------
        targets : (M, 2) array, mm
        sources : (N, 2) array, mm
        h : float, mm

        Returns
        -------
        (M, N) array, mm/MPa.
        """

    def grid_matrix(self, target: Grid, source: Grid | None = None) -> np.ndarray:
        """Dense block between two aligned grids, shape ``(target.size, source.size)``,
        rows and columns in row-major cell order (x fastest). mm/MPa."""
        source = target if source is None else source
        return self.cell_block(target.points(), source.points(), target.h)

    @abstractmethod
    def grid_operator(self, target: Grid, source: Grid | None = None) -> GridOperator:
        """Fast product from pressure on ``source`` (default: ``target``) to
        displacement on ``target``; both grids must share ``h`` and lattice."""

    def split(self) -> tuple["InfluenceProvider", LowRankCorrection | None]:
        """``(base, correction)`` with ``self``'s cell blocks equal to ``base``'s plus the
        low-rank ``correction`` (``None``: no correction, ``base`` is ``self``).

        Solvers may apply the two parts separately, e.g. fast products of a
        translation-invariant ``base`` and one sum of coefficients for the correction. The
        finite block returns (half-space, its FEM correction)."""
        return self, None

    def separated_operator(self, target: Grid, source: Grid, *, rtol: float = 1e-8) -> GridOperator | None:
        """A cheaper product between two grids far apart compared with their sizes, within
        ``rtol`` of the largest displacement that one-signed pressure gives, or ``None``
        when the provider has none for this pair (callers then use :meth:`grid_operator`).

        The half-space answers with a Chebyshev low-rank block
        (:mod:`twoscale.influence.separated`); the default is ``None``.
        """
        return None

    def point_operator(
        self, targets: np.ndarray, sources: np.ndarray, *, exclude=None, rtol: float = 1e-6
    ) -> PointOperator:
        """Sum of point-force displacements ``u_i = sum_j G(t_i, s_j) F_j`` without
        keeping the ``(M, N)`` matrix (:mod:`twoscale.influence.points`).

        Parameters
        ----------
        targets : (M, 2) array, mm
        sources : (N, 2) array, mm
        exclude : sparse (M, N), optional
            Pairs left out of the sum (its stored entries). Coincident points always
            contribute nothing.
        rtol : float, default 1e-6
            Accuracy a fast operator must keep, relative to ``max |u|`` for forces of one
            sign; the default operator is exact and ignores it.

        Returns
        -------
        PointOperator
        """
        if not (np.isfinite(rtol) and 0.0 < rtol < 1.0):
            raise ValueError(f"rtol must be in (0, 1), got {rtol!r}")
        return DensePointOperator(self.point_compliance, targets, sources, exclude)

    def domain(self) -> tuple[float, float, float, float] | None:
        """Rectangle ``(x0, x1, y0, y1)`` (mm, scene frame) where this body answers for
        loaded points; ``None`` (default): everywhere (the half-space).

        A finite body answers only inside its top face (the block: within one source
        spacing of its sides). Solvers check the scene against it before solving.
        """
        return None

    def cache_usage(self) -> tuple:
        """What this body's on-disk caches read, wrote and dropped so far, as
        :class:`twoscale.io.cache_entry.CacheUsage` objects; ``()`` (default): none."""
        return ()

    def build_bytes(self, rect: tuple[float, float, float, float]) -> float:
        """Memory its first answers for loads in ``rect`` ``(x0, x1, y0, y1)`` (mm, scene
        frame) will take to build beyond what it holds (the block's factorisation where its
        cache lacks a field), bytes; 0 (default): nothing is built."""
        return 0.0

    def smooth_self_compliance(self, points: np.ndarray) -> np.ndarray:
        """Regular part of the point compliance at coincident points, mm/N, shape (N,).

        The point compliance is ``1/(pi E* r) + C(x, x')`` with ``C`` smooth; this
        returns ``C(x_k, x_k)``. The macro step adds it to each asperity's own law
        (an asperity on a finite block is stiffer or softer than on the half-space).
        Zero for the half-space.
        """
        return np.zeros(len(np.asarray(points).reshape(-1, 2)))

    def self_compliance(self, h: float, at: tuple[float, float] = (0.0, 0.0)) -> float:
        """Displacement at a cell centre per unit pressure on that cell, mm/MPa."""
        pt = np.asarray([at], dtype=float)
        return float(self.cell_block(pt, pt, h)[0, 0])
