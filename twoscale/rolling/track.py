"""The track of a rolling scene, prepared once: the body, the face window, the road on its
lattice, the control, and the checks that refuse a run before it starts.

:func:`prepare` turns a :class:`~twoscale.scene.Scene` with ``rolling`` into a
:class:`Track`: on a height map the strip is resampled (when the step is not a multiple
of its spacing) and segmented once; the shifts are put on the map's lattice; the strip
must be longer than the footprint plus the run; under penetration control something must
touch at the first position.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError, SurfaceWarning
from ..influence.cached import with_caches
from ..scene import Scene
from .first_contact import check_contact
from .road import Road
from .spec import RollingSpec
from .stepcheck import check_step, warn_if_coarse

#: Factor on the Hertz line-contact estimate of a tyre's footprint length under load
#: control (the texture's tips carry the load on less than the whole face, so the real
#: footprint is a little longer than the smooth one).
FOOTPRINT_MARGIN = 1.5


@dataclass(frozen=True, eq=False)
class Track:
    """Everything the positions share (see the module docstring)."""

    scene: Scene
    spec: RollingSpec
    provider: object
    road: Road
    h: float
    shifts: np.ndarray
    times: np.ndarray
    control: str
    body: str
    step_check: object = None
    #: Whether the body's surface can rise beside a contact (a finite block: bonded, nearly
    #: incompressible rubber bulges), so that a stone whose summit lies below the road's
    #: reach can touch all the same (:func:`twoscale.rolling.run.step` then hands every
    #: stone under the face to the solver).
    rises: bool = False
    #: Seconds (wall) :func:`prepare` took: the checks, the body and the segmented road's boxes.
    seconds: float = 0.0

    @property
    def segment_seconds(self) -> float:
        """Wall seconds the strip's segmentation took (0 for tips: nothing segmented): done
        when the scene was read, before :func:`prepare`, or within it when the strip was
        resampled to the step's lattice."""
        surface = self.scene.surface
        return float(getattr(surface, "segment_seconds", 0.0)) if surface is not None else 0.0

    def timings(self, positions: float) -> dict:
        """A run's ``timings_s`` (wall seconds): ``segment`` (:attr:`segment_seconds`),
        ``prepare`` (:attr:`seconds`), ``positions`` (given) and ``total`` (prepare and
        positions: the run's own clock)."""
        return {
            "segment": self.segment_seconds,
            "prepare": self.seconds,
            "positions": positions,
            "total": self.seconds + positions,
        }


def lattice(spec: RollingSpec, spacing: float) -> tuple[float, np.ndarray]:
    """The spacing (mm) the road is sampled at, at most ``spacing``, of which the step is a
    whole multiple (``step / ceil(step / spacing)``), and the shifts on its lattice (the
    start rounded to the nearest multiple of it: a road point at x then always meets a
    cell centre)."""
    n = max(1, math.ceil(spec.step / spacing * (1 - 1e-9)))
    h = spec.step / n
    start = round(spec.start / h) * h
    return h, start + spec.step * np.arange(spec.count)


def prepare(scene: Scene, *, h: float | None = None, provider=None) -> Track:
    """The :class:`Track` of ``scene`` (a scene with ``rolling``); ``h``: the cell size for
    a scene of tips (default :func:`twoscale.scene.default_h` of the scene unshifted),
    ignored on a height map (its spacing, made a divisor of the step)."""
    from ..resolution import default_h

    t0 = time.perf_counter()
    spec = scene.rolling
    if not isinstance(spec, RollingSpec):
        raise SceneError(f"rolling is missing: the scene has no [rolling] table (got {spec!r})")
    if scene.material.viscoelastic:
        _viscoelastic_available()
    # the road's own sample spacing, before any resampling to the step's lattice
    check = _step_check(scene)
    if scene.surface is not None:
        cell, shifts = lattice(spec, scene.surface.h)
        if not math.isclose(cell, scene.surface.h, rel_tol=1e-9):
            scene = dataclasses.replace(
                scene, surface=scene.surface.at(cell, h_name="rolling.step"), h=cell, asperities=()
            )
        cell = scene.surface.h
    else:
        cell = float(h) if h is not None else default_h(dataclasses.replace(scene, rolling=None))
        shifts = spec.shifts()
    # the body through caches kept for the whole run (tables, operators between patches)
    provider = with_caches(provider if provider is not None else scene.provider())
    window = face_window(scene, spec, provider, cell)
    road = Road(scene, window)
    control = "penetration" if scene.penetration is not None else "load"
    times = (shifts - shifts[0]) / spec.speed_mm_s
    rises = provider.domain() is not None
    track = Track(scene, spec, provider, road, cell, shifts, times, control, body_label(scene), check, rises)
    if spec.tyre_radius is not None and tyre_contact_length(track) < 2.0 * cell:
        held = (
            f"load.penetration = {scene.penetration!r} mm"
            if control == "penetration"
            else f"load.total = {scene.total_load!r} N"
        )
        raise SceneError(
            f"rolling.tyre_radius = {spec.tyre_radius!r} mm with {held} leaves no contact wider than a cell "
            f"(footprint about {tyre_contact_length(track):.2g} mm at h = {cell:g} mm)"
        )
    if scene.surface is not None:
        check_length(track)
    if control == "penetration":
        check_contact(road, scene.penetration, float(shifts[0]))
    warn_if_coarse(check)  # after every refusal: a run refused says only why
    if scene.surface is not None:
        warn_if_wider(track)
    return dataclasses.replace(track, seconds=time.perf_counter() - t0)


def _step_check(scene: Scene):
    """The step of ``scene``'s run against its road's own samples (before any resampling to
    the step's lattice) and its Prony branches (:mod:`twoscale.rolling.stepcheck`)."""
    if scene.surface is None:
        return check_step(scene.rolling, scene.material, None)
    nx = scene.surface.hmap.heights.shape[1]
    return check_step(scene.rolling, scene.material, scene.surface.h, nx * scene.surface.h)


def _viscoelastic_available() -> None:
    """A viscoelastic material rolls through :func:`twoscale.viscoelastic.moving.solve_moving`
    (:mod:`twoscale.rolling.viscous`); without it, refuse in one line naming the field
    rather than roll the material as if it were elastic."""
    import importlib.util

    if importlib.util.find_spec("twoscale.viscoelastic.moving") is None:
        raise SceneError(
            "material.prony with [rolling]: the viscoelastic rolling (twoscale.viscoelastic.moving) "
            "is not in this version; give an elastic material (no prony)"
        )


def face_window(scene: Scene, spec: RollingSpec, provider, h: float) -> tuple:
    """The body's face window (x0, x1, y0, y1), mm, body frame: the footprint when given,
    else a block's region, else unbounded. On a block the window stays inside the region
    the block answers for (its top face less one correction spacing) by a stone's patch
    (:func:`block_margin`), so that no patch reaches beyond it."""
    domain = provider.domain()
    if domain is not None:
        m = block_margin(scene, h)
        domain = (domain[0] + m, domain[1] - m, domain[2] + m, domain[3] - m)
        if domain[1] <= domain[0] or domain[3] <= domain[2]:
            raise SceneError(
                f"influence.size: the block answers for too small a region for the road's stones "
                f"(patches up to {m:.3g} mm around a summit)"
            )
    if spec.footprint is not None:
        L, W = spec.footprint
        box = (-L / 2, L / 2, -W / 2, W / 2)
        if domain is not None:
            box = (max(box[0], domain[0]), min(box[1], domain[1]), max(box[2], domain[2]), min(box[3], domain[3]))
        return box
    if domain is not None:
        return tuple(float(v) for v in domain)
    if spec.tyre_radius is None:
        raise SceneError(
            "rolling.footprint is missing: a flat face on the half-space needs the footprint "
            "[length, width] (mm) that touches the road (or give rolling.tyre_radius)"
        )
    return (-math.inf, math.inf, -math.inf, math.inf)


def block_margin(scene: Scene, h: float) -> float:
    """How far a stone's patch may reach beyond the window, mm: the patch margin (1.3) times
    the largest stone's reach from its summit, plus two cells (a map's stones; 0 for tips,
    whose patches :func:`twoscale.api.check_domain` sizes from their contacts)."""
    from ..resolution import PATCH_MARGIN

    if scene.surface is None:
        return 0.0
    extent = max(float(getattr(a, "extent", 0.0)) for a in scene.asperities)
    return PATCH_MARGIN * extent + 2.0 * h


def footprint_length(track: Track) -> float:
    """Length of the footprint along x, mm: the window's, or the tyre's estimated contact
    when shorter (:func:`tyre_contact_length`)."""
    x0, x1, _, _ = track.road.window
    if track.spec.tyre_radius is None:
        return x1 - x0
    return min(x1 - x0, tyre_contact_length(track))


def tyre_contact_length(track: Track) -> float:
    """The tyre's estimated contact length along x, mm: under penetration control where the
    face is below the approach; under load control the Hertz line contact of the load over
    the window's (or the strip's) width, times :data:`FOOTPRINT_MARGIN`."""
    _, _, y0, y1 = track.road.window
    spec, scene = track.spec, track.scene
    R = spec.tyre_radius
    if track.control == "penetration":
        depth = max(scene.penetration - float(track.road.z.min()), 0.0)
        return 2.0 * math.sqrt(depth * (2.0 * R - depth)) if depth < R else 2.0 * R
    width = y1 - y0 if math.isfinite(y1 - y0) else float(track.road.box[:, 3].max() - track.road.box[:, 2].min())
    a = math.sqrt(4.0 * scene.total_load * R / (math.pi * scene.material.E_star * width))
    return 2.0 * FOOTPRINT_MARGIN * a


class StripTooShort(SceneError):
    """The strip does not cover the footprint at every shift of the run (:func:`check_length`);
    ``strip`` its x range and ``contact`` the footprint's length along x, mm, so that a
    caller that moved the run (a study's section offset) can say which shifts would fit."""

    def __init__(self, message: str, strip: tuple, contact: float):
        super().__init__(message)
        self.strip, self.contact = strip, contact

    def shifts_that_fit(self) -> tuple:
        """The first and last shift (mm) between which the strip covers the footprint."""
        return self.contact / 2 - self.strip[1], -self.contact / 2 - self.strip[0]


def check_length(track: Track) -> None:
    """Refuse a strip shorter than the footprint plus the run (:class:`StripTooShort`)."""
    rx0, rx1 = track.road.extent_x
    L = footprint_length(track)
    s0, s1 = float(track.shifts[0]), float(track.shifts[-1])
    if rx0 + s1 > -L / 2 or rx1 + s0 < L / 2:
        raise StripTooShort(
            f"surface: the strip is {rx1 - rx0:.6g} mm long along x, shorter than the contact length (about {L:.4g} mm, "
            f"{_length_source(track, L)}) "
            f"plus the run from rolling.start = {track.spec.start!r} to rolling.end = {track.spec.end!r} mm "
            f"(a road point at x appears at body x + shift: the strip must cover the footprint at every shift)",
            (rx0, rx1),
            L,
        )


def _length_source(track: Track, length: float) -> str:
    """What sets the contact length ``length`` (mm) of :func:`footprint_length`, in words."""
    x0, x1, _, _ = track.road.window
    if track.spec.tyre_radius is not None and length < x1 - x0:
        return "the tyre's estimated contact along x"
    if track.spec.footprint is not None:
        return "the footprint along x"
    return "the part of the block's face the road may touch, set by influence.size"


def warn_if_wider(track: Track) -> None:
    """Warn where the face window (a footprint, or a block's face without one) reaches across
    y beyond the strip by more than a cell: the face there meets no road, so the load is
    carried by the strip's width alone."""
    _, _, w0, w1 = track.road.window
    if track.spec.footprint is not None:
        L, W = track.spec.footprint
        field = f"rolling.footprint = [{L:g}, {W:g}] mm"
    elif math.isfinite(w1 - w0):
        Lx, Ly, _ = track.scene.influence["size"]
        field = f"influence.size = [{Lx:g}, {Ly:g}, ...] mm (the part of the block's face the road may touch, {w1 - w0:.4g} mm across y)"
    else:
        return
    y0, y1 = float(track.road.box[:, 2].min()), float(track.road.box[:, 3].max())
    if w0 < y0 - track.h or w1 > y1 + track.h:
        warnings.warn(
            f"{field} is wider than the strip ({y1 - y0:.4g} mm across y, "
            f"from {y0:.4g} to {y1:.4g} mm): the face beyond it touches no road",
            SurfaceWarning,
            stacklevel=2,
        )


def cut_positions(track: Track, result) -> np.ndarray:
    """Indices of the positions at which a tyre's contact reaches the face window's ends
    along x (load on the window's first or last cell column): the window, not the tyre,
    ends the contact there. Empty without a tyre (a flat face is the window itself), for an
    unbounded window, or where the run kept no line loads."""
    x0, x1, _, _ = track.road.window
    lx, load = result.line_x, result.line_load
    if track.spec.tyre_radius is None or not (math.isfinite(x0) and math.isfinite(x1)) or not lx.size:
        return np.zeros(0, dtype=int)
    ends = (lx <= x0 + 0.5 * track.h) | (lx >= x1 - 0.5 * track.h)
    return np.flatnonzero((load[:, ends] > 0).any(axis=1))


def warn_if_cut(track: Track, result) -> None:
    """Warn, naming the field that set the window, where the tyre's contact reaches its ends
    (:func:`cut_positions`): the approach and the pressure there are a shorter face's."""
    cut = cut_positions(track, result)
    if not cut.size:
        return
    x0, x1, _, _ = track.road.window
    field = (
        f"rolling.footprint = [{track.spec.footprint[0]:g}, {track.spec.footprint[1]:g}] mm"
        if track.spec.footprint is not None
        else "influence.size (the block's face)"
    )
    warnings.warn(
        f"{field}: the tyre's contact reaches the window's ends (x = {x0:.4g} and {x1:.4g} mm) at "
        f"{cut.size} of {len(result.shifts)} positions, so the window, not the tyre, ends it there "
        f"(the approach and the pressure are a shorter face's): give a window longer than the contact",
        SurfaceWarning,
        stacklevel=3,
    )


def body_label(scene: Scene) -> str:
    """The body in words, for titles and ``rolling.json``."""
    inf = scene.influence
    if inf["kind"] == "block":
        Lx, Ly, t = inf["size"]
        return f"block {Lx:g} x {Ly:g} x {t:g} mm, {inf['base']} base"
    return "half-space"
