"""Frozen result objects shared by every solver.

A solver's pressure lives on one or more aligned rectangular grids ("patches"):
the reference solver has one grid covering the scene, the two-scale solver one
patch per asperity. Per-asperity figures are integrals over the cells each
asperity owns (the indenter nearest the body).

Numbering: in Python every index is 0-based, as in numpy (``asperities.forces[k]`` is
the asperity ``scene.asperities[k]``, ``PressureField.owner`` holds 0-based indices,
``MicroDetails.merged_patches`` too). Everything a person reads (terminal tables,
result.json's ``merged_patches``, CSV files, figures) numbers tips from 1, as the scene
file lists them.

What only one method has is in :attr:`ContactResult.details`: :class:`TwoScaleDetails`
(macro step, micro step) or :class:`ReferenceDetails`; see :mod:`twoscale.details`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Iterable, Iterator, Mapping, Sequence

import numpy as np

from .grid import Grid

if TYPE_CHECKING:
    from numpy.typing import ArrayLike, DTypeLike

    from .details import ReferenceDetails, TwoScaleDetails
    from .setting import Body


def frozen_array(a: ArrayLike, dtype: DTypeLike = float) -> np.ndarray:
    """A read-only copy of ``a`` (results never share writable arrays with the caller)."""
    a = np.array(a, dtype=dtype, copy=True)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class PressureField:
    """Pressure and related fields on one grid.

    Attributes
    ----------
    grid : Grid
    pressure : (ny, nx) array, MPa (>= 0).
    owner : (ny, nx) int array: owning asperity, -1 where no indenter has material.
    gap : (ny, nx) array, mm: ``z + u - d`` (indenter height + displacement - approach);
        0 in contact, > 0 outside; ``inf`` where no indenter has material.
    """

    grid: Grid
    pressure: np.ndarray
    owner: np.ndarray
    gap: np.ndarray

    def __post_init__(self) -> None:
        for name in ("pressure", "gap"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))
        object.__setattr__(self, "owner", frozen_array(self.owner, np.int64))
        for name in ("pressure", "owner", "gap"):
            if getattr(self, name).shape != self.grid.shape:
                raise ValueError(f"{name} has shape {getattr(self, name).shape}, grid is {self.grid.shape}")


@dataclass(frozen=True)
class AsperitySummary:
    """Per-asperity integrals of the final pressure (arrays in scene order).

    forces (N), contact_areas (mm^2), max_pressures (MPa).
    """

    forces: np.ndarray
    contact_areas: np.ndarray
    max_pressures: np.ndarray


def summarise(fields: Sequence[PressureField], n_asperities: int) -> AsperitySummary:
    """Force, contact area and peak pressure of each asperity from its owned cells."""
    forces = np.zeros(n_asperities)
    areas = np.zeros(n_asperities)
    pmax = np.zeros(n_asperities)
    for f in fields:
        # the owned cells that carry pressure: an unloaded cell adds exactly nothing (a road's
        # 10^6-cell box is 17 % loaded; ``maximum.at`` over every owned cell took 25 ms),
        # found once as flat indices (a mask gathered six times: 608 x 320 cells 7 % loaded,
        # 0.73 against 1.7 ms; the same cells in the same order)
        at = np.flatnonzero(f.pressure)
        own = f.owner.ravel()[at]
        if np.count_nonzero(own < 0):
            at, own = at[own >= 0], own[own >= 0]
        p = f.pressure.ravel()[at]
        h2 = f.grid.h**2
        forces += h2 * np.bincount(own, weights=p, minlength=n_asperities)
        areas += h2 * np.bincount(own, weights=(p > 0).astype(float), minlength=n_asperities)
        if at.size:
            np.maximum.at(pmax, own, p)
    return AsperitySummary(frozen_array(forces), frozen_array(areas), frozen_array(pmax))


class FrozenMapping(Mapping):
    """A read-only copy of a dict (stage names of iterations, residuals, timings; a policy's
    estimates). Unlike ``types.MappingProxyType`` it pickles, so results cross processes."""

    __slots__ = ("_data",)

    def __init__(self, data: Mapping | Iterable[tuple] = ()) -> None:
        self._data = dict(data)

    def __getitem__(self, key: Any) -> Any:
        return self._data[key]

    def __iter__(self) -> Iterator:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return repr(self._data)


def _read_only(d: Mapping | None) -> Mapping:
    return d if isinstance(d, FrozenMapping) else FrozenMapping(d or {})


@dataclass(frozen=True)
class Reuse:
    """What a :class:`~twoscale.solver.ContactSolver` solve took over from its earlier solves.

    Attributes
    ----------
    solve : int
        This solve's number in the solver object's life (1: the first).
    body_kept : bool
        The body was kept from an earlier solve.
    macro_start : bool
        The macro step started from the previous answer's forces, approach and tilt.
    pressure_start : int
        Tips whose micro step started from the previous answer's pressure.
    kept_bytes : int
        Bytes the solver object keeps for its next solve's start (the answer's pressure and
        tips; its caches are ``cache_bytes``).
    operators_kept : Mapping
        Operators between patches (or of a patch on itself) this solve took over from
        earlier ones, by kind: ``"fft"`` (kernel spectra), ``"separated"`` (low-rank
        blocks), ``"factor"`` (a dense block's factorisation on an active set), ``"points"`` (the far
        field's point operator, kept for the same points), ``"shape"`` (the coarse
        correction's local solve on a patch's active set); on a half-space a pair translated by whole cells counts (its operator
        depends on the pair's relative position only).
    operators_built : Mapping
        The same, built by this solve.
    cache_bytes : int
        Bytes in the solver object's caches after this solve (offset tables, interpolation
        matrices, pair operators), at most ``cache_max_bytes``.
    cache_max_bytes : float
        Their bound.
    """

    solve: int
    body_kept: bool
    macro_start: bool
    pressure_start: int
    kept_bytes: int
    operators_kept: Mapping = field(default_factory=dict)
    operators_built: Mapping = field(default_factory=dict)
    cache_bytes: int = 0
    cache_max_bytes: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "operators_kept", _read_only(self.operators_kept))
        object.__setattr__(self, "operators_built", _read_only(self.operators_built))

    def __str__(self) -> str:
        if self.solve == 1 and not self.body_kept:
            return "first solve: nothing to reuse"
        parts = ["body kept" if self.body_kept else "body built"]
        if self.macro_start:
            parts.append("macro step started from the previous answer")
        if self.pressure_start:
            parts.append(f"micro step started from the previous pressure on {self.pressure_start} tips")
        if not self.macro_start and not self.pressure_start:
            parts.append("cold start")
        kept, built = sum(self.operators_kept.values()), sum(self.operators_built.values())
        if kept or built:
            parts.append(f"{kept} patch operators kept, {built} built")
        text = f"solve {self.solve}: " + ", ".join(parts)
        if self.cache_max_bytes:
            text += f" (caches {self.cache_bytes / 1e6:.1f} of {self.cache_max_bytes / 1e6:.0f} MB)"
        return text


@dataclass(frozen=True)
class ContactResult:
    """What every solver returns.

    Attributes
    ----------
    method : str
        The method that ran: ``"twoscale"`` or ``"reference"`` (the full-grid solvers).
    fields : tuple of PressureField
        Pressure on the grid(s) the solver used.
    penetration : float
        Rigid approach d, mm (given or solved).
    tilt : (alpha, beta) or None
        Tilt angles, radians, when the load was applied through a ball-and-socket joint.
    total_load : float
        Integral of the pressure, N.
    asperities : AsperitySummary
        Per-asperity forces, areas, peak pressures, in scene order (0-based indices).
    converged : bool
        Whether every stopping criterion was met. A solver that hits its iteration
        limit returns ``converged=False`` with ``message`` saying why.
    message : str
    iterations : mapping
        Iteration counts by stage, e.g. {"outer": 12} or {"macro": 5, "micro": 7} (read-only).
    residuals : mapping
        Residual histories by stage (tuples of floats; read-only).
    timings_s : mapping
        Wall-clock seconds by stage; ``"total"`` always (read-only).
    details : TwoScaleDetails, ReferenceDetails or None
        What only this method has (typed; :mod:`twoscale.details`).
    solver : str
        The algorithm that ran: ``"twoscale"``, or for the reference method ``"dense"``
        (Johnson's matrix inversion) or ``"cg"`` (Polonsky-Keer); defaults to ``method``.
    caches : tuple of CacheUsage
        What the on-disk caches (block corrections, surface laws) gave and took during this
        solve (:class:`twoscale.io.cache_entry.CacheUsage`); empty when none was used.
    body : Body or None
        The elastic body solved (:class:`twoscale.setting.Body`: kind, block size and base,
        and ``body.label`` for titles, e.g. ``"block 60 x 60 x 10 mm, bonded base"``); set
        by :func:`twoscale.solve`.
    nominal_area : float or None
        Area the contact area is compared with, mm2 (:func:`twoscale.setting.nominal_area`:
        the height map's area, or the box of the tips' bases, cut to a block's top face);
        ``nominal_area_basis`` says which. Set by :func:`twoscale.solve`.
    nominal_area_basis : str
    scene_name : str
        The scene's name where known (a scene file's stem, a study's scene name), for titles.
    reuse : Reuse or None
        What a :class:`~twoscale.solver.ContactSolver` solve reused from earlier solves
        (None from ``twoscale.solve``).
    """

    method: str
    fields: tuple
    penetration: float
    tilt: tuple | None
    total_load: float
    asperities: AsperitySummary
    converged: bool
    message: str = ""
    iterations: Mapping = field(default_factory=dict)
    residuals: Mapping = field(default_factory=dict)
    timings_s: Mapping = field(default_factory=dict)
    details: TwoScaleDetails | ReferenceDetails | None = None
    solver: str = ""
    caches: tuple = ()
    body: Body | None = None
    nominal_area: float | None = None
    nominal_area_basis: str = ""
    scene_name: str = ""
    reuse: Reuse | None = None

    def __post_init__(self) -> None:
        for name in ("iterations", "residuals", "timings_s"):
            object.__setattr__(self, name, _read_only(getattr(self, name)))
        object.__setattr__(self, "fields", tuple(self.fields))
        if not self.solver:
            object.__setattr__(self, "solver", self.method)

    @property
    def n_asperities(self) -> int:
        """Number of tips (asperities) of the scene solved."""
        return len(self.asperities.forces)

    @property
    def n_cells(self) -> int:
        """Number of cells the solver carried (its problem size)."""
        return sum(f.grid.size for f in self.fields)

    @property
    def contact_area(self) -> float:
        """Total contact area, mm2: the loaded cells' area, summed over the tips."""
        return float(np.sum(self.asperities.contact_areas))

    @property
    def contact_ratio(self) -> float | None:
        """Real-to-nominal contact area ratio, ``contact_area / nominal_area`` (None when the
        nominal area is not known or zero)."""
        if not self.nominal_area:
            return None
        return self.contact_area / self.nominal_area

    @property
    def title(self) -> str:
        """What was solved, for a figure title: ``"S1 on half-space"``, ``"block 60 x 60 x 10 mm,
        bonded base"`` (the scene's name when known, then the body's label)."""
        body = self.body.label if self.body is not None else ""
        if self.scene_name and body:
            return f"{self.scene_name} on {body}"
        return self.scene_name or body

    def to_dataframe(self, tips: Any = None) -> Any:
        """The per-tip table as a pandas DataFrame (needs pandas): one row per tip, numbered
        from 1 (``asperity``), with force (N), contact area (mm2), peak and mean pressure
        (MPa) and the macro step's force; with ``tips`` (the Scene solved or its
        asperities) also the tip's position, recess, radius and shape. The columns of
        ``asperities.csv``."""
        from .display import result_frame

        return result_frame(self, tips)

    def _repr_html_(self) -> str:
        """Compact notebook display: the headline numbers and the most loaded tips."""
        from .display import result_html

        return result_html(self)

    @property
    def forces(self) -> np.ndarray:
        """Force of each asperity, N, in scene order (``asperities.forces``)."""
        return self.asperities.forces

    @property
    def macro_forces(self) -> np.ndarray | None:
        """Tip forces of the macro step, N (scene order), when the method has one (two-scale); else None."""
        macro = getattr(self.details, "macro", None)
        return None if macro is None else macro.forces

    def pressure_on(self, grid: Grid) -> np.ndarray:
        """The pressure assembled onto an aligned ``grid`` (zero where no field covers it)."""
        out = np.zeros(grid.shape)
        for f in self.fields:
            di, dj = f.grid.offset_in(grid)
            i0, j0 = max(di, 0), max(dj, 0)
            i1, j1 = min(di + f.grid.nx, grid.nx), min(dj + f.grid.ny, grid.ny)
            if i1 <= i0 or j1 <= j0:
                continue
            out[j0:j1, i0:i1] += f.pressure[j0 - dj : j1 - dj, i0 - di : i1 - di]
        return out

    def __repr__(self) -> str:
        solver = "" if self.solver == self.method else f" ({self.solver})"
        state = "converged" if self.converged else "NOT converged"
        from .display import tilt_text

        tilt = "" if self.tilt is None else f", tilt ({tilt_text(self, '.3g')}) rad"
        total_s = self.timings_s.get("total")
        time_txt = "" if total_s is None else f", {total_s:.3g} s"
        tips = f"{self.n_asperities} tip" + ("" if self.n_asperities == 1 else "s")
        on = f", {self.body.label}" if self.body is not None else ""
        return (
            f"<ContactResult {self.method}{solver}: {tips}, total load "
            f"{self.total_load:.6g} N, approach {self.penetration:.6g} mm{tilt}, "
            f"contact area {self.contact_area:.4g} mm2{on}, {state}, {self.n_cells} cells{time_txt}>"
        )

    __str__ = __repr__
