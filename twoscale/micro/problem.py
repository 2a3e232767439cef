"""What every iteration of the micro step receives: :class:`MicroProblem` (the problem as the
macro step leaves it), :class:`BlockSettings` (the block iterations' internal limits) and
:class:`MicroContext` (both, with the user's :class:`~twoscale.options.MicroOptions` and the
patches the policy saw), passed whole from the driver to the strategies."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..options import MicroOptions

#: Merged blocks may cover this many times the cells of their patches: one constrained CG
#: on the common grid then costs about what the sweeps over the separate patches do (paper
#: cases, best of 4: seven spheres at d/2R = 0.5 248 -> 177 ms, at 1 241 -> 181 ms against
#: no growth, 1; two at d/2R = 1 stays apart; at 3, two at d/2R = 1 merged and went
#: 66 -> 122 ms).
MERGE_GROWTH = 2.0

#: A macro step that did not converge still sizes the patches by its forces (and starts the
#: union CG from its local approaches) where its last relative residual is at most this:
#: Newton stagnating near a solution (2,596 spheres under penetration control at 3.3e-4,
#: a few close pairs) is a better guide than each indenter's geometric reach (patches of
#: 1.5 M cells in all against 0.59 M from the forces); a failed safe path's iterate, far
#: from any solution, is not.
SIZING_RESIDUAL = 1e-2


@dataclass(frozen=True)
class MicroProblem:
    """The micro step's problem (docs/method.md section 3).

    Attributes
    ----------
    h : float
        Cell side, mm.
    forces : (N,) array
        Macro tip forces, N (eq. 7 and patch sizes).
    penetration : float
        Approach d, mm (the macro one under load control).
    tilt : (alpha, beta) or None, default None
        Tilt angles, radians (the macro ones when ``free_tilt``).
    pivot : (float, float), default (0, 0)
        Tilt pivot, mm.
    total_load : float or None, default None
        Load control: the approach (and the tilt when ``free_tilt``) are corrected until
        the pressure carries ``total_load`` N (and zero moments about the pivot).
    free_tilt : bool, default False
        Ball-and-socket joint (needs ``total_load``).
    anchor : (float, float), default (0, 0)
        A cell centre of the common lattice, mm.
    size_from_forces : bool, default True
        Size the patches from the macro forces; False sizes them by the geometric reach
        of each indenter (use when the macro step's forces are not near a solution:
        :meth:`from_macro` with ``SIZING_RESIDUAL``).
    sizing_approaches : (N,) array or None, default None
        Approach of each tip used to size the patches, mm (<= 0: no patch); default the
        geometric ``d - z_k - tilt``, or with far-field coupling the macro local approaches
        plus a fifth of the largest (``local_penetrations``). Asperities penetrating
        outside every block are still given a patch by the growth step.
    local_penetrations : (N,) array or None, default None
        The macro step's local approach of each tip, mm, where it converged or came near
        (the union CG's start, the far-field patch sizes), or deferred its safe path.
    sizing_penetrations : (N,) array or None, default None
        The macro step's local approach of each tip, mm, wherever they are finite, near a
        solution or not: with far-field coupling they size the patches where
        ``local_penetrations`` is None (a fifth of the largest added, never beyond the
        geometric reach; :func:`~.strategies._sizing`).
    start : MicroStart or None, default None
        A previous solve's pressure (:mod:`.start`): the iterations start from it on the
        patches of the asperities it loaded, from eq. 7 elsewhere.
    lift : (N,) array or None, default None
        How far a body's surface rising beside its contacts lifts each tip's approach, mm
        (:mod:`twoscale.bulge_rounds`): added to the geometric approach where the patches
        are sized, so that a tip above the approach gets one.
    """

    h: float
    forces: np.ndarray
    penetration: float
    tilt: tuple | None = None
    pivot: tuple = (0.0, 0.0)
    total_load: float | None = None
    free_tilt: bool = False
    anchor: tuple = (0.0, 0.0)
    size_from_forces: bool = True
    sizing_approaches: np.ndarray | None = None
    local_penetrations: np.ndarray | None = None
    sizing_penetrations: np.ndarray | None = None
    start: object = None
    lift: np.ndarray | None = None

    @classmethod
    def from_macro(
        cls,
        macro,
        *,
        h: float,
        total_load: float | None,
        free_tilt: bool,
        pivot: tuple,
        anchor: tuple = (0.0, 0.0),
        start=None,
    ) -> "MicroProblem":
        """The problem the macro step ``macro`` (a :class:`~twoscale.macro.result.MacroResult`)
        leaves: its forces, approach and tilt (under load control moved by the correction
        the ``start``'s micro step made to its own macro step), the local penetrations
        where it converged or ended near a solution (``SIZING_RESIDUAL``), or deferred its
        safe path: the union CG, the one iteration run after that without it, then starts from
        them while the patches reach as far as each tip can touch (10 merged spheres on the
        block, Newton stalled at 1.9e-2: 22 CG iterations against 36 from the CG's own start;
        49 spheres 27 against 31)."""
        penetration, tilt = macro.penetration, macro.tilt
        if start is not None and total_load is not None:
            penetration, tilt = start.theta(penetration, tilt)
        near = bool(macro.converged) or _near_solution(macro)
        starts = near or (bool(getattr(macro, "safe_path_deferred", False)) and _finite(macro))
        local = np.asarray(macro.local_penetrations, dtype=float) if starts else None
        return cls(
            h=h,
            forces=np.asarray(macro.forces, dtype=float),
            penetration=penetration,
            tilt=tilt,
            pivot=pivot,
            total_load=total_load,
            free_tilt=free_tilt,
            anchor=anchor,
            size_from_forces=near,
            local_penetrations=local,
            sizing_penetrations=np.asarray(macro.local_penetrations, dtype=float) if _finite(macro) else None,
            start=start,
        )

    @property
    def theta(self) -> np.ndarray:
        """``(d, alpha, beta)``: approach (mm) and tilt (radians, 0 without)."""
        return np.array([self.penetration, *(self.tilt if self.tilt is not None else (0.0, 0.0))], dtype=float)

    @property
    def n_unknowns(self) -> int:
        """Rigid-body unknowns the iterations correct: 0 (penetration control), 1 (load), 3 (load and tilt)."""
        return 0 if self.total_load is None else (3 if self.free_tilt else 1)

    @property
    def target(self) -> np.ndarray | None:
        """Load (N) and moments (0) to meet, ``(n_unknowns,)``, or None."""
        return None if self.total_load is None else np.array([self.total_load, 0.0, 0.0])[: self.n_unknowns]


def _near_solution(macro) -> bool:
    """Whether a macro step that did not converge ended near a solution: its last relative
    residual at most ``SIZING_RESIDUAL``, finite forces and local approaches."""
    last = macro.residuals[-1] if len(macro.residuals) else np.inf
    return bool(np.isfinite(last) and last <= SIZING_RESIDUAL and _finite(macro))


def _finite(macro) -> bool:
    return bool(np.all(np.isfinite(macro.forces)) and np.all(np.isfinite(macro.local_penetrations)))


@dataclass(frozen=True)
class BlockSettings:
    """Limits of the block iterations that are not user options (their defaults live here).

    Attributes
    ----------
    dense_max_entries : int, default 40000
        Cross blocks ``A_kl`` up to this many entries are formed densely, larger by FFT.
    max_corrections : int, default 20
        Newton corrections of (d, alpha, beta) allowed (block Gauss-Seidel).
    max_growths : int or None, default None
        Patch enlargements allowed in all; None: 50, or ``GROWTHS_PER_PATCH`` a patch if
        more (unloading a viscoelastic body leaves contacts wider than the macro step's
        elastic estimate on every tip at once).
    merge_growth : float, default ``MERGE_GROWTH`` (2)
        Cells a merged grid may have over its members' grids together (>= 1).
    """

    dense_max_entries: int = 40_000
    max_corrections: int = 20
    max_growths: int | None = None
    merge_growth: float = MERGE_GROWTH


@dataclass(frozen=True)
class MicroContext:
    """What every iteration needs: the body, the indenters (a ``TipTable``), the problem,
    the options, the block settings, and the one-asperity patches the policy saw (built
    once: the block iterations start from them, the union CG uses their extent; None:
    built from the problem).

    ``kept_starts`` is the context's cache of first pressures (eq. 7 or the warm start)
    per one-asperity patch, keyed by the patch, its macro force, the approach and tilt and
    the pivot: a fallback attempt on the same patches takes them instead of solving eq. 7
    again (2,117 clustered spheres: 11 s of CPU per attempt). One entry per patch; it lives
    as long as the context, one micro step."""

    provider: object
    asperities: object
    problem: MicroProblem
    options: MicroOptions = field(default_factory=MicroOptions)
    settings: BlockSettings = field(default_factory=BlockSettings)
    patches: tuple | None = None
    kept_starts: dict = field(default_factory=dict, compare=False, repr=False)
