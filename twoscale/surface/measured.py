"""A measured surface ready for the solvers: the conditioned map, its segmentation, its
asperities, and the book of their laws.

:func:`load_surface` runs the pipeline read -> condition -> segment -> asperities; the
laws are tabulated when a solver first asks for one (:meth:`MapAsperity.law`, through
:func:`twoscale.laws.law_for`) and kept by the surface's :class:`LawBook` (per ``E*``) and,
when given, a :class:`~twoscale.surface.lawcache.LawCache` on disk. They do not depend on
the load: each asperity is tabulated down to ``law_depth`` below its summit and the
power-law continuation of :class:`~twoscale.laws.TabulatedLaw` goes beyond.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

from ..influence import HalfSpace
from ..laws import HertzLaw, TabulatedLaw
from ..laws.base import AsperityLaw, as_force, as_penetration
from .conditioning import FILL_MODES, MM_PER_UNIT, condition
from .heightmap import HeightMap, SurfaceError
from .indenter import map_asperities
from .lawcache import LawCache, law_key
from .laws import LEVELS, SOLVE_TOL, LawTable, sphere_law_error, stack_tables, tabulate_law
from .reading import RawMap, read_heightmap
from .segmentation import MIN_DISTANCE, PROMINENCE, Segmentation, segment
from .sphere_fit import CAP_DEPTH, SphereFit

#: Default depth below each summit down to which its law is tabulated, mm.
LAW_DEPTH = 0.5
#: Law kinds: tabulated from single-asperity solves, or the equivalent sphere's Hertz law.
LAW_KINDS = ("auto", "tabulated", "sphere")
#: Asperity laws a book keeps in memory (one per asperity and E*).
BOOK_ROWS = 100_000


@dataclass(frozen=True)
class SurfaceOptions:
    """How a height map becomes indenters (the ``[surface]`` table of a scene, less
    ``file``); units mm. See :func:`twoscale.surface.conditioning.condition`,
    :func:`twoscale.surface.segmentation.segment`, :mod:`.sphere_fit` and :mod:`.laws`."""

    spacing: float | None = None
    units: str | None = None
    fill: str = "nearest"
    detrend: bool = False
    crop: tuple | None = None
    invert: bool = False
    min_distance: float = MIN_DISTANCE
    prominence: float = PROMINENCE
    cap_depth: float = CAP_DEPTH
    law: str = "auto"
    law_depth: float = LAW_DEPTH
    law_levels: int = LEVELS

    def __post_init__(self) -> None:
        self._check_conditioning()
        if self.law not in LAW_KINDS:
            raise SurfaceError(f"surface.law must be one of {', '.join(LAW_KINDS)}, got {self.law!r}")
        for name in ("cap_depth", "law_depth"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
                raise SurfaceError(f"surface.{name} must be a number > 0 (mm), got {v!r}")
        if isinstance(self.law_levels, bool) or not isinstance(self.law_levels, int) or self.law_levels < 2:
            raise SurfaceError(f"surface.law_levels must be an integer >= 2, got {self.law_levels!r}")

    def _check_conditioning(self) -> None:
        """The map's conditioning and segmentation options, checked when the options are
        made (as the build checks them): ``detrend="yes"`` was taken as true, a bad ``fill``
        or ``units`` met only when a surface was built."""
        if self.fill not in FILL_MODES:
            raise SurfaceError(f"surface.fill must be one of {', '.join(FILL_MODES)}, got {self.fill!r}")
        if self.units is not None and self.units not in MM_PER_UNIT:
            raise SurfaceError(f"surface.units must be one of {', '.join(MM_PER_UNIT)}, got {self.units!r}")
        for name in ("detrend", "invert"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise SurfaceError(f"surface.{name} must be true or false, got {getattr(self, name)!r}")
        for name, low in (("spacing", 0.0), ("min_distance", None), ("prominence", None)):
            v = getattr(self, name)
            if v is None and name == "spacing":
                continue
            ok = not isinstance(v, (bool, np.bool_)) and isinstance(v, (int, float, np.integer, np.floating))
            ok = ok and math.isfinite(v)
            if not ok or (v <= low if low is not None else v < 0):
                bound = "> 0" if low is not None else ">= 0"
                raise SurfaceError(f"surface.{name} must be a number {bound} (mm), got {v!r}")


class LawBook:
    """The laws of one surface's asperities, each tabulated when first needed (a solve
    asks for every law, but only the asperities its macro step presses get tabulated: see
    :class:`LazyLaw`), kept per ``(E*, asperity)`` and, with ``cache``, on disk under the
    key of the surface (``digest``), ``E*``, ``h`` and the law options. Owned by its
    surface; ``asperities`` is set once they exist (they refer to the book).

    Attributes
    ----------
    tabulated : int
        Asperity laws computed (not read from the cache).
    """

    def __init__(self, digest: str, h: float, options: SurfaceOptions, cache: LawCache | None = None):
        self.digest, self.h, self.options, self.cache = digest, float(h), options, cache
        self.asperities: tuple = ()
        self._rows: dict = {}  # (E*, label) -> one-row LawTable
        self._providers: dict = {}  # E* -> HalfSpace
        self._keys: dict = {}  # E* -> the book's law key (its asperities' keys add their label)
        self.tabulated = 0

    def _key(self, E_star: float, label: int) -> str:
        if E_star not in self._keys:  # (a digest a stone: 178 stones, 6 ms of a solve's start)
            opts = self.options
            self._keys[E_star] = law_key(
                self.digest, E_star=E_star, h=self.h, delta_max=opts.law_depth, levels=opts.law_levels, tol=SOLVE_TOL
            )
        return f"{self._keys[E_star]}-{label}"

    def _provider(self, material) -> HalfSpace:
        """The half-space of the single-asperity solves, one per ``E*`` (its kernel tables
        serve every asperity)."""
        E_star = float(material.E_star)
        if E_star not in self._providers:
            self._providers[E_star] = HalfSpace(material)
        return self._providers[E_star]

    def row(self, label: int, material) -> LawTable:
        """The tabulated law of asperity ``label`` (computed, or read from the cache)."""
        E_star = float(material.E_star)
        table = self._held(E_star, label)
        if table is None:
            table = tabulate_law(
                self.asperities[label],
                self._provider(material),
                h=self.h,
                delta_max=self.options.law_depth,
                levels=self.options.law_levels,
            )
            self.tabulated += 1
            if self.cache is not None:
                self.cache.put(self._key(E_star, label), table)
            self._keep(E_star, label, table)
        return table

    def _held(self, E_star: float, label: int) -> LawTable | None:
        """The law if held or on disk (then held), else None."""
        table = self._rows.get((E_star, label))
        if table is None and self.cache is not None:
            table = self.cache.get(self._key(E_star, label))
            if table is not None:
                self._keep(E_star, label, table)
        return table

    def _keep(self, E_star: float, label: int, table: LawTable) -> None:
        """Hold ``table``, dropping the oldest held law past ``BOOK_ROWS``."""
        if len(self._rows) >= BOOK_ROWS:
            self._rows.pop(next(iter(self._rows)))
        self._rows[(E_star, label)] = table

    def table(self, material, *, progress=None) -> LawTable:
        """The laws of every asperity for ``material``."""
        rows = []
        for k in range(len(self.asperities)):
            if progress is not None and k % 50 == 0:
                progress(f"asperity laws: {k} of {len(self.asperities)}")
            rows.append(self.row(k, material))
        return stack_tables(rows)

    def known(self, label: int, material) -> bool:
        """Whether the tabulated law of ``label`` costs nothing now (held, or on disk)."""
        return self._held(float(material.E_star), label) is not None

    def law(self, label: int, material):
        """Law of asperity ``label``, by the ``law`` option: ``"tabulated"`` (computed when
        first pressed), ``"sphere"`` (the equivalent sphere's Hertz law) or ``"auto"``: the
        tabulated law when it is already known (e.g. cached by ``twoscale surface`` or an
        earlier solve), else the sphere's. The macro forces only start the micro step, which
        solves on the true heights: on a 100 mm road (314 stones) both laws gave the same
        forces against the full-grid reference (largest error 0.064 % of the largest force)
        and the sphere law's start saved the 3-13 s of tabulation for one more sweep."""
        kind = self.options.law
        if kind == "auto":
            kind = "tabulated" if self.known(label, material) else "sphere"
        if kind == "sphere":
            return HertzLaw(self.asperities[label].R, material.E_star)
        return LazyLaw(self, label, material)


class LazyLaw(AsperityLaw):
    """The tabulated law of one asperity, tabulated on the first evaluation that needs it
    (a penetration or force > 0): asperities the macro step never presses cost nothing."""

    def __init__(self, book: LawBook, label: int, material):
        self.book, self.label, self.material = book, label, material
        self._tabulated: TabulatedLaw | None = None

    def _law(self) -> TabulatedLaw:
        if self._tabulated is None:  # built once: its interpolant costs more than an evaluation
            self._tabulated = self.book.row(self.label, self.material).law(0)
        return self._tabulated

    def _call(self, method: str, values: np.ndarray) -> np.ndarray:
        # zero penetration or force needs no table: the law is 0 there
        return getattr(self._law(), method)(values) if np.any(values > 0) else np.zeros_like(values)

    def force(self, delta):
        return self._call("force", as_penetration(delta))

    def stiffness(self, delta):
        return self._call("stiffness", as_penetration(delta))

    def penetration(self, P):
        return self._call("penetration", as_force(P))

    def complementary_energy(self, P):
        return self._call("complementary_energy", as_force(P))


@dataclass(frozen=True, eq=False)
class MeasuredSurface:
    """A height map as indenters; see the module docstring. Solve it whole,
    ``twoscale.solve(surface, material=..., total_load=...)`` (or as
    ``twoscale.Scene(material=..., surface=surface, ...)``), not its ``asperities``.

    Attributes
    ----------
    raw : RawMap
        The file as read (kept to condition again at another cell size: :meth:`at`).
    options : SurfaceOptions
    hmap : HeightMap
        The conditioned map (mm, centred, spacing = the solver's cell size).
    segmentation : Segmentation
    asperities : tuple of MapAsperity
    spheres : SphereFit
        The equivalent spheres of the summit caps.
    book : LawBook
    segment_seconds : float
        Wall seconds :func:`build_surface` took to segment the map (a rolling run reports
        its strip's: ``RollingResult.timings_s["segment"]``).
    """

    raw: RawMap
    options: SurfaceOptions
    hmap: HeightMap
    segmentation: Segmentation
    asperities: tuple
    spheres: SphereFit
    book: LawBook = field(repr=False)
    segment_seconds: float = 0.0

    @property
    def h(self) -> float:
        """Spacing of the conditioned map = cell size of the solves, mm."""
        return self.hmap.h

    def at(self, h: float | None, *, h_name: str = "h") -> "MeasuredSurface":
        """This surface conditioned at cell size ``h`` (mm) from the raw map; itself when
        ``h`` is None or its own spacing. ``h_name``: where ``h`` came from, as a refusal
        names it (the size is checked before the resampled map is allocated)."""
        if h is None or math.isclose(h, self.h, rel_tol=1e-12):
            return self
        return build_surface(self.raw, self.options, h=h, cache=self.book.cache, h_name=h_name)

    def sphere_error(self, material):
        """Error of the equivalent-sphere laws against the tabulated ones
        (:func:`twoscale.surface.laws.sphere_law_error`)."""
        return sphere_law_error(self.book.table(material), self.asperities)


def build_surface(
    raw: RawMap,
    options: SurfaceOptions | None = None,
    *,
    h: float | None = None,
    cache: LawCache | None = None,
    h_name: str = "h",
) -> MeasuredSurface:
    """Condition, segment and make the asperities of a raw map (resampled to ``h`` mm
    when given): what a scene file's ``[surface]`` table builds.

    To solve it, pass the surface itself, ``twoscale.solve(surface, material=...,
    total_load=...)`` or ``twoscale.Scene(material=..., surface=surface, ...)``: its
    spacing is then the default cell size, another ``h`` resamples the raw map, and the
    result reports the map (missing samples, units, contacts at its edge). Its
    ``asperities`` alone are not a scene (:func:`twoscale.solve` refuses them).

    Parameters
    ----------
    raw : RawMap
        The heights (a file read by :func:`read_heightmap`, or ``RawMap(heights,
        spacing=..., units=...)`` made in Python).
    options : SurfaceOptions, optional
        Conditioning, segmentation and law options (default ``SurfaceOptions()``).
    h : float, optional
        Cell size, mm; default the map's spacing.
    cache : LawCache, optional
        On-disk cache of the asperity laws (the scene file's reader makes one in the
        user's cache folder; default here: none).
    h_name : str, default "h"
        Where ``h`` came from, as a size refusal names it.
    """
    options = options or SurfaceOptions()
    hmap: HeightMap = condition(
        raw,
        spacing=options.spacing,
        units=options.units,
        fill=options.fill,
        detrend=options.detrend,
        crop=options.crop,
        h=h,
        invert=options.invert,
        h_name=h_name,
    )
    t0 = time.perf_counter()
    seg: Segmentation = segment(hmap, min_distance=options.min_distance, prominence=options.prominence)
    seconds = time.perf_counter() - t0
    # the laws' key: the map and every option but which law the macro step uses
    digest = hashlib.sha256((hmap.digest() + repr(dataclasses.replace(options, law="tabulated"))).encode())
    digest.update(memoryview(np.ascontiguousarray(seg.labels)).cast("B"))
    book = LawBook(digest.hexdigest(), hmap.h, options, cache)
    asperities, fit = map_asperities(hmap, seg, cap_depth=options.cap_depth, book=book)
    book.asperities = asperities
    return MeasuredSurface(raw, options, hmap, seg, asperities, fit, book, seconds)


def load_surface(
    path: str | os.PathLike,
    options: SurfaceOptions | None = None,
    *,
    h: float | None = None,
    cache: LawCache | None = None,
    h_name: str = "h",
) -> MeasuredSurface:
    """Read ``path`` (:func:`twoscale.surface.reading.read_heightmap`) and build the surface
    (:func:`build_surface`)."""
    return build_surface(read_heightmap(path), options, h=h, cache=cache, h_name=h_name)
