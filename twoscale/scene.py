"""A scene: the body, the indenters and the load, as plain validated data.

:class:`Scene` holds the same fields as the scene file (``twoscale.io.scene_file``);
the library reads no files itself. :func:`twoscale.solve` solves it (the two-scale
method, or the classical reference solver on a full grid). Units: mm, N, MPa.

Invalid data raise :class:`SceneError` (a ``ValueError``) whose one-line message names
the field by its path in the scene file (``load.total``, ``asperity 4: R``; asperities
numbered from 1 in file order) and the bad value.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from collections.abc import Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .control import check_control
from .errors import SceneError
from .indenters import Asperity, tip_positions
from .material import Material
from .values import check_number, check_pair, is_number  # noqa: F401 (re-exported: scene and study readers)

if TYPE_CHECKING:
    from .influence.base import InfluenceProvider

#: Influence kinds a scene may ask for.
INFLUENCE_KINDS = ("halfspace", "block")
#: Bases of the finite block (``fem_influence``): bonded (u = 0) or sliding (u_z = 0).
BLOCK_BASES = ("bonded", "sliding")
#: Default finite block (paper's rubber block): width x depth x thickness, mm.
BLOCK_DEFAULT_SIZE = (140.0, 140.0, 20.0)


@dataclass(frozen=True, eq=False)
class Influence(Mapping):
    """The elastic body of a scene: read-only, and read as the mapping it was given as.

    ``Influence()`` is the half-space, ``{"kind": "halfspace"}``; a finite block reads as
    ``{"kind": "block", "size": (Lx, Ly, t) mm, "base": "bonded" | "sliding", "origin":
    (x0, y0) mm, "source_spacing": mm}`` (the spacing of the block's correction lattice,
    default 5 mm: the block answers up to one spacing inside its sides). Compares equal to
    that dict. Build it with :func:`normalise_influence`,
    which checks the values.
    """

    kind: str = "halfspace"
    size: tuple | None = None
    base: str | None = None
    origin: tuple | None = None
    source_spacing: float | None = None

    def _as_dict(self) -> dict:
        if self.kind == "halfspace":
            return {"kind": "halfspace"}
        return {
            "kind": self.kind,
            "size": self.size,
            "base": self.base,
            "origin": self.origin,
            "source_spacing": self.source_spacing,
        }

    def __getitem__(self, key: str) -> Any:
        return self._as_dict()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._as_dict())

    def __len__(self) -> int:
        return len(self._as_dict())

    def __hash__(self) -> int:
        return hash(tuple(self._as_dict().items()))

    def __repr__(self) -> str:
        return f"Influence({self._as_dict()!r})"


def normalise_influence(influence: Mapping | None) -> Influence:
    """Validated influence options with defaults filled in.

    ``{"kind": "halfspace"}`` (default) or ``{"kind": "block", "size": (Lx, Ly, t) mm,
    "base": "bonded" | "sliding", "origin": (x0, y0) mm}`` where ``origin`` is where the
    scene's (0, 0) sits, measured from the centre of the block's top face.
    """
    if influence is None or isinstance(influence, Influence):
        return influence or Influence()
    if not isinstance(influence, Mapping):
        raise SceneError(f"influence must be a table, got {influence!r}")
    kind = influence.get("kind", "halfspace")
    if kind not in INFLUENCE_KINDS:
        raise SceneError(f"influence.kind must be one of {INFLUENCE_KINDS}, got {kind!r}")
    allowed = {"kind"} if kind == "halfspace" else {"kind", "size", "base", "origin", "source_spacing"}
    for key in influence:
        if key not in allowed:
            raise SceneError(
                f"influence.{key if str(key).isprintable() else repr(key)} is not a known key for kind = {kind!r} "
                f"(allowed: {sorted(allowed)}), got {influence[key]!r}"
            )
    if kind == "halfspace":
        return Influence()
    base = influence.get("base", "bonded")
    if base not in BLOCK_BASES:
        raise SceneError(f"influence.base must be one of {BLOCK_BASES}, got {base!r}")
    return Influence(
        kind="block",
        size=check_pair("influence.size", influence.get("size", BLOCK_DEFAULT_SIZE), 3, positive=True, unit="mm"),
        base=base,
        origin=check_pair("influence.origin", influence.get("origin", (0.0, 0.0)), unit="mm"),
        source_spacing=check_number(
            "influence.source_spacing", influence.get("source_spacing", 5.0), positive=True, unit="mm"
        ),
    )


# ---------------------------------------------------------------- the scene
@dataclass(frozen=True)
class Scene:
    """Body, indenters and load: the content of a scene file.

    Parameters
    ----------
    material : Material
        E (MPa) and nu of the elastic body.
    asperities : sequence of Asperity
        The rigid indenters, in scene order (stored as a tuple; at least one; no two
        tips at the same (x, y)); leave out with ``surface``.
    penetration : float, optional
        Rigid approach d, mm (displacement control). Exactly one of ``penetration``
        and ``total_load``; it must exceed the lowest tip recess z so that something
        touches.
    total_load : float, optional
        Total normal load, N (> 0; load control).
    tilt : bool, default False
        With ``total_load`` only: the load goes through a ball-and-socket joint and the
        tilt angles (alpha about x, beta about y) are unknowns (paper eq. 11-12).
    pivot : (float, float), default (0, 0)
        Joint position, mm; only with ``tilt=True``.
    h : float, optional
        Micro-scale cell size, mm (> 0). ``None``: chosen by :func:`default_h`.
    influence : mapping, optional
        ``{"kind": "halfspace"}`` (default) or the finite block,
        ``{"kind": "block", "size": (140, 140, 20), "base": "bonded", "origin": (0, 0)}``;
        stored as a read-only :class:`Influence` (see :func:`normalise_influence`).
    load_cases : sequence of float, default ()
        With ``total_load`` only: the scene's load cases, total loads in N (each finite
        and > 0, no repeats; stored as a tuple). ``twoscale compare`` runs each of them
        in turn in place of ``total_load``; ``twoscale solve`` and :func:`twoscale.api.solve_scene`
        use ``total_load`` (conventionally the first case). ``()``: no list, one load.
    surface : MeasuredSurface, optional
        A height map as indenters (:func:`twoscale.surface.build_surface`, what a scene
        file's ``[surface]`` table builds), instead of ``asperities``: the asperities are
        then its basins, conditioned at the cell size ``h`` (its own spacing when ``h``
        is None: the default cell size of a map), and ``h`` is that cell size. The basins
        of a map (its ``asperities``) are refused without it: they need the map to be
        resampled to ``h``.
    history : LoadHistory, optional
        A load history in time (:class:`twoscale.viscoelastic.LoadHistory`); then
        ``total_load`` or ``penetration`` (whichever it prescribes) is its peak value and
        may be left out. Required when the material has Prony branches (unless rolling).
    rolling : RollingSpec, optional
        The road rolls under the body (:class:`twoscale.rolling.RollingSpec`, a scene
        file's ``[rolling]`` table; :func:`twoscale.rolling.roll` solves every position):
        the time is the rolling's, so no load history, no tilt, no load cases.

    Raises
    ------
    SceneError
        Naming the field path (as in the scene file) and the bad value.
    """

    material: Material
    asperities: tuple = ()
    penetration: float | None = None
    total_load: float | None = None
    tilt: bool = False
    pivot: tuple = (0.0, 0.0)
    h: float | None = None
    influence: Influence = field(default_factory=Influence)
    load_cases: tuple = ()
    surface: Any = None
    history: Any = None
    rolling: Any = None

    def __post_init__(self) -> None:
        if not isinstance(self.material, Material):
            raise SceneError(f"material must be a Material, got {self.material!r}")
        if self.surface is not None:  # the basins of a height map, at the scene's cell size
            if not callable(getattr(self.surface, "at", None)):
                raise SceneError(
                    f"surface must be a MeasuredSurface (twoscale.surface.build_surface(RawMap(heights, "
                    f"spacing=..., units=...))), got {type(self.surface).__name__}"
                )
            if len(self.asperities) and tuple(self.asperities) != tuple(self.surface.asperities):
                raise SceneError(
                    "a scene needs exactly one of asperities and a surface (a height map), got both "
                    "(with surface=, leave asperities out)"
                )
            object.__setattr__(self, "surface", self.surface.at(self.h))
            object.__setattr__(self, "asperities", tuple(self.surface.asperities))
            object.__setattr__(self, "h", self.surface.h)
        self._check_asperities()
        self._take_history()
        self._check_load()
        if self.h is not None:
            object.__setattr__(self, "h", check_number("grid.h", self.h, positive=True, unit="mm"))
        object.__setattr__(self, "influence", normalise_influence(self.influence))

    def _check_asperities(self) -> None:
        if isinstance(self.asperities, (str, bytes)) or not isinstance(self.asperities, (Sequence, np.ndarray)):
            raise SceneError(f"asperity must be a list of asperities, got {self.asperities!r}")
        asps = tuple(self.asperities)
        if not asps:
            raise SceneError("asperity list is empty, got [] (a scene needs at least one [[asperity]])")
        for k, a in enumerate(asps):
            if not isinstance(a, Asperity):
                raise SceneError(f"asperity {k + 1} must be an Asperity, got {a!r}")
            if a.shape == "map" and self.surface is None:  # a basin of a height map, without its map
                raise SceneError(
                    f"asperity {k + 1} is a basin of a height map: give the surface itself, "
                    f"twoscale.solve(surface, material=..., total_load=...) or Scene(surface=surface, ...), "
                    f"not surface.asperities (the map is then resampled to h, its spacing is the default "
                    f"h, and the result reports it)"
                )
        seen: dict[tuple[float, float], int] = {}
        for k, a in enumerate(asps):
            key = (a.x + 0.0, a.y + 0.0)  # + 0.0 folds -0.0 into 0.0
            if key in seen:
                raise SceneError(
                    f"asperity {k + 1} is at the same place (x, y) = ({a.x!r}, {a.y!r}) "
                    f"as asperity {seen[key] + 1}; two tips cannot share a position"
                )
            seen[key] = k
        object.__setattr__(self, "asperities", asps)

    def _take_history(self) -> None:
        """A load history sets ``total_load`` or ``penetration`` to its peak (what sizes
        grids); Prony branches need a history (their answer is one in time)."""
        from .viscoelastic.history import LoadHistory

        hist = self.history
        if self.rolling is not None:
            _check_rolling(self)
        if hist is None:
            if self.material.viscoelastic and self.rolling is None:
                given = (
                    f"load cases {list(self.load_cases)!r}"
                    if len(self.load_cases)
                    else f"a single value {self.total_load if self.total_load is not None else self.penetration!r}"
                )
                raise SceneError(
                    "material.prony needs a load history: write load.total (or load.penetration) "
                    f"as [[t, value], ...] (s; N or mm), got {given}"
                )
            return
        if not isinstance(hist, LoadHistory):
            raise SceneError(f"history must be a twoscale.viscoelastic.LoadHistory, got {hist!r}")
        name = "total_load" if hist.kind == "total" else "penetration"
        other = "penetration" if hist.kind == "total" else "total_load"
        if getattr(self, other) is not None:
            raise SceneError(
                f"a history of load.{hist.kind} and load.{'penetration' if other == 'penetration' else 'total'} "
                f"= {getattr(self, other)!r}: give one of the two"
            )
        if getattr(self, name) not in (None, hist.peak):
            raise SceneError(f"{name} = {getattr(self, name)!r} is not the history's peak {hist.peak!r}: leave it out")
        object.__setattr__(self, name, hist.peak)

    def _check_load(self) -> None:
        d, W = self.penetration, self.total_load
        check_control(d, W, names=("load.penetration", "load.total"), error=SceneError)
        if not isinstance(self.tilt, (bool, np.bool_)):
            raise SceneError(f"load.tilt must be true or false, got {self.tilt!r}")
        object.__setattr__(self, "tilt", bool(self.tilt))
        pivot = check_pair("load.pivot", self.pivot, unit="mm")
        object.__setattr__(self, "pivot", pivot)
        if d is not None:
            d = check_number("load.penetration", d, unit="mm")
            zmin = min(a.z for a in self.asperities)
            if not d > zmin:
                raise SceneError(
                    f"load.penetration must exceed the lowest tip recess z = {zmin!r} mm "
                    f"(otherwise nothing touches), got {d!r}"
                )
            object.__setattr__(self, "penetration", d)
            if self.tilt:
                raise SceneError(
                    "load.tilt = true needs load.total (the tilt is solved from the "
                    f"moment balance under a given load), got penetration = {d!r}"
                )
        else:
            object.__setattr__(self, "total_load", check_number("load.total", W, positive=True, unit="N"))
        if not self.tilt and pivot != (0.0, 0.0):
            raise SceneError(f"load.pivot is only used with load.tilt = true, got pivot = {list(pivot)!r}")
        object.__setattr__(self, "load_cases", self._checked_load_cases())

    def _checked_load_cases(self) -> tuple:
        cases = self.load_cases
        if isinstance(cases, (str, bytes, Mapping)) or not isinstance(cases, (Sequence, np.ndarray)):
            raise SceneError(f"load.cases must be a list of total loads (N), got {cases!r}")
        if len(cases) == 0:
            return ()
        if self.total_load is None:
            raise SceneError(
                f"load.cases = {list(cases)!r} needs load.total (the cases are total loads), "
                f"got penetration = {self.penetration!r}"
            )
        out = tuple(check_number(f"load.cases[{i}]", w, positive=True, unit="N") for i, w in enumerate(cases))
        if len(set(out)) != len(out):
            raise SceneError(f"load.cases has repeated values, got {list(cases)!r}")
        return out

    # ------------------------------------------------------------ derived data
    @property
    def tips(self) -> np.ndarray:
        """Tip positions, shape (N, 2), mm."""
        return tip_positions(self.asperities)

    def provider(self, **options: Any) -> InfluenceProvider:
        """The influence provider the scene asks for (:mod:`twoscale.influence.registry`).

        Parameters
        ----------
        **options
            Extra keyword arguments for the finite-block provider (e.g.
            ``progress=False``, ``cache_dir``); none are accepted by the half-space.

        Raises
        ------
        SceneError
            For ``kind = "block"`` when the ``fem_influence`` package is not available.
        """
        from .influence.registry import make_body

        opts = dict(self.influence)
        kind = opts.pop("kind")
        try:
            return make_body(kind, self.material, **opts, **options)
        except ImportError as exc:
            raise SceneError(f'influence.kind = "{kind}": {exc}; use kind = "halfspace"') from exc


def _check_rolling(scene: Scene) -> None:
    """A rolling scene: a :class:`~twoscale.rolling.RollingSpec`, its time its own (no load
    history), the load through the axle (no tilt)."""
    from .rolling.spec import RollingSpec

    if not isinstance(scene.rolling, RollingSpec):
        raise SceneError(f"rolling must be a twoscale.rolling.RollingSpec, got {scene.rolling!r}")
    if scene.history is not None:
        raise SceneError(
            "a [rolling] scene has the rolling's time: give load.total or load.penetration as one "
            f"value, not a history ({scene.history.kind} history given)"
        )
    if scene.tilt:
        raise SceneError("load.tilt = true cannot go with [rolling] (the axle holds the body level)")
    if scene.load_cases:
        raise SceneError(f"load.cases cannot go with [rolling], got {list(scene.load_cases)!r}")


#: Methods of the scene-file workflow (``twoscale solve --method``); :func:`twoscale.solve`
#: also takes the reference solvers by name ("dense", "cg").
SCENE_METHODS = ("twoscale", "reference")


# the cell size a scene needs lives in .resolution; kept importable from here
from .resolution import (  # noqa: E402,F401
    CELL_BUDGET,
    CELLS_ACROSS,
    MIN_FORCE_FRACTION,
    PATCH_MARGIN,
    _hertz_level,
    default_h,
    expected_approaches,
    expected_contact_radii,
    expected_contacts,
    patch_cells,
    round_up,
)
