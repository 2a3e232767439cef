"""The one entry point: :func:`solve` (``twoscale.solve``), in the style of ``scipy.optimize.minimize``.

``solve(problem, method=...)`` takes a :class:`~twoscale.scene.Scene`, tips (Asperity
objects, an array, or a mapping of arrays) or a height map (a
:class:`~twoscale.surface.MeasuredSurface` from :func:`twoscale.surface.build_surface`, or
a :class:`~twoscale.surface.RawMap` of heights and spacing) with the material and the load,
and returns a :class:`~twoscale.results.ContactResult`. ``method`` picks the solver:

* ``"twoscale"`` (default): the two-scale method (:func:`twoscale.driver.solve_twoscale`);
  called without options on a scene of a few tips whose full grid has at most
  :data:`twoscale.micro.full_grid_rule.FULL_GRID_MAX_CELLS` cells (``FULL_GRID_MAX_CELLS_PENETRATION`` on
  the half-space under penetration control), or of untilted tips with at most
  :data:`twoscale.micro.full_grid_rule.FULL_GRID_CELLS_PER_TIP` cells each, that grid's one CG
  instead (the cheapest solve there; ``result.method == "reference"`` and
  ``result.message`` says why);
* ``"reference"``: the full-grid reference on a grid covering every place contact can
  reach (:func:`twoscale.reference.on_scene.solve_reference_scene`), dense or CG by size; the result says which
  (``result.method == "reference"``, ``result.solver`` ``"dense"`` or ``"cg"``);
* ``"dense"`` / ``"cg"``: that reference solver;
* a callable ``method(provider, scene, h=h, **options) -> ContactResult``: a solver of
  your own, given the same inputs.

The elastic body is the scene's (half-space by default) unless a prebuilt ``provider`` is
passed (e.g. a finite block built once for several solves). Units: mm, N, MPa. Python
indices are 0-based (numpy); files and tables written for people number tips from 1.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .control import check_control
from .errors import ResolutionWarning
from .material import Material
from .pivot import check_pivot_reach, warn_large_tilt
from .results import ContactResult
from .scene import SCENE_METHODS
from .resolution import check_resolution
from .scene import Scene, SceneError, default_h, expected_contact_radii, expected_contacts
from .collector import frozen_objects
from .threads import single_threads
from .tips import as_asperities, asperities  # noqa: F401 (twoscale.asperities, twoscale.as_asperities)

if TYPE_CHECKING:
    from .influence.base import InfluenceProvider
    from .surface.measured import MeasuredSurface
    from .viscoelastic.result import HistoryResult

#: Names ``method`` accepts (or a callable).
METHODS = ("twoscale", "reference", "dense", "cg")
#: Scene fields that come from ``solve``'s keywords when tips are given instead of a Scene.
_SCENE_KEYWORDS = ("material", "penetration", "total_load", "tilt", "pivot")


def _scene_of(problem: Any, provider: InfluenceProvider | None, h: float | None, shape: str, given: dict) -> Scene:
    """The scene to solve: ``problem`` itself, or one built from tips or a height map and keywords."""
    if isinstance(problem, Scene):
        extra = [k for k in _SCENE_KEYWORDS if given[k] is not None and not (k == "tilt" and given[k] is False)]
        if extra:
            raise ValueError(
                f"a Scene carries its own {', '.join(extra)}; change the scene "
                f"(dataclasses.replace) instead of passing {extra[0]}="
            )
        return problem if h is None else dataclasses.replace(problem, h=h)
    check_control(given["penetration"], given["total_load"])
    material = given["material"]
    if material is None:
        if provider is None:
            raise ValueError("give material= (or a provider=) when the tips are not a Scene")
        material = provider.material
    surface = _height_map(problem, h)
    tips = () if surface is not None else as_asperities(problem, shape=shape)
    return Scene(
        material=material,
        asperities=tips,
        surface=surface,
        penetration=given["penetration"],
        total_load=given["total_load"],
        tilt=bool(given["tilt"]),
        pivot=given["pivot"] if given["pivot"] is not None else (0.0, 0.0),
        h=h,
    )


def _height_map(problem: Any, h: float | None) -> MeasuredSurface | None:
    """``problem`` as a MeasuredSurface conditioned at ``h`` when it is a height map (a
    MeasuredSurface, or a RawMap built with the default SurfaceOptions), else None."""
    if isinstance(problem, (Mapping, Sequence, np.ndarray)):
        return None
    from .surface.measured import MeasuredSurface, build_surface
    from .surface.reading import RawMap

    if isinstance(problem, RawMap):
        return build_surface(problem, h=h)
    return problem.at(h) if isinstance(problem, MeasuredSurface) else None


# ---------------------------------------------------------------- the entry point
#: Keywords of :func:`solve` beside its named ones and the solver's options, with their
#: defaults: the tips' joint and shape, the body's build options, the memory bound.
CALL_KEYWORDS = {"tilt": False, "pivot": None, "shape": "sphere", "provider_options": None, "memory_limit": None}


def solve(
    problem: Any,
    *,
    method: str | Callable[..., ContactResult] = "twoscale",
    provider: InfluenceProvider | None = None,
    material: Material | None = None,
    penetration: float | None = None,
    total_load: float | None = None,
    h: float | None = None,
    **options: Any,
) -> ContactResult | HistoryResult:
    """Solve a multi-asperity contact.

    Parameters
    ----------
    problem : Scene, sequence of Asperity, array, mapping of arrays, MeasuredSurface or RawMap
        A :class:`~twoscale.scene.Scene`, or the tips alone (see :func:`as_asperities`:
        an ``(n, 3)`` array ``x, y, R`` or ``(n, 4)`` ``x, y, R, z``, mm; or
        ``{"x": ..., "y": ..., "R": ..., "z": ...}``), or a height map as the indenter:
        ``twoscale.surface.build_surface(RawMap(heights, spacing=0.1, units="um"),
        SurfaceOptions(...))``, or the ``RawMap`` alone (default options). A map goes
        through the same conditioning, resampling to ``h`` and defaults (``h`` = its
        spacing) as a scene file's ``[surface]`` table and gives the same answer; pass
        the surface, not its ``asperities`` (refused: they need the map). Then give
        ``material`` (or a ``provider``) and exactly one of ``penetration`` and
        ``total_load``.
    method : {"twoscale", "reference", "dense", "cg"} or callable, default "twoscale"
        The solver (module docstring). ``"reference"`` picks dense up to 2,000 cells with
        material, CG above; ``result.solver`` says which ran.
    provider : InfluenceProvider, optional
        A prebuilt elastic body (``twoscale.HalfSpace(material)``,
        ``twoscale.FiniteBlock(material, size=..., base=...)``, or your own), used instead
        of the scene's ``influence``. Its material must be the scene's.
    material : Material, optional
        Tips only: E (MPa) and nu of the body (default: the provider's).
    penetration : float, optional
        Tips only: rigid approach d, mm.
    total_load : float, optional
        Tips only: total load W, N.
    tilt : bool, default False
        Tips only, with ``total_load``: ball-and-socket joint (tilt solved).
    pivot : (float, float), optional
        Tips only, with ``tilt``: joint position, mm (default (0, 0)).
    h : float, optional
        Cell size, mm (> 0); overrides the scene's. Default: ``scene.h`` or
        :func:`twoscale.scene.default_h` (about 32 cells across the smallest loaded
        contact); for a height map its spacing (another ``h`` resamples it, refused
        before allocating when the map would exceed 25 M samples or the memory).
    shape : {"sphere", "paraboloid"}, default "sphere"
        Tips given as arrays: their shape.
    provider_options : mapping, optional
        Passed to the scene's provider when it is built here (finite block: e.g.
        ``{"progress": False}``); not with ``provider``.
    memory_limit : float, optional
        Bytes the solve may use, checked before anything large is allocated
        (:func:`twoscale.resources.check_memory`); default 80 % of the memory available
        now; ``math.inf``: no check.
    **options
        ``tilt``, ``pivot``, ``shape``, ``provider_options`` and ``memory_limit`` (above);
        the rest is passed to the solver: :func:`~twoscale.driver.solve_twoscale` (a
        :class:`~twoscale.options.SolverOptions` as ``options=``, the flat option keywords
        ``tol``, ``iteration``, ``far_tol``, ... of docs/options.md, ``progress``,
        ``start`` a warm start from a neighbouring solve; an unknown or misspelt one is
        refused naming the closest), the reference solvers (``tol``, ``max_iter``), or
        your callable.

    Returns
    -------
    ContactResult or HistoryResult
        A scene with a load history (``scene.history``; needed for Prony branches) gives a
        :class:`~twoscale.viscoelastic.result.HistoryResult` (histories as arrays and each
        output time's ContactResult; :func:`twoscale.viscoelastic.solve.solve_history`).
        ``result.forces[k]`` (N) is the force of the k-th tip (0-based, input order);
        ``result.details`` holds what only the method has (typed, :mod:`twoscale.details`),
        and on a height map ``result.details.surface`` (missing samples, units, contacts
        at the map's edge); ``print(result)`` gives a one-line summary.

    Raises
    ------
    ValueError
        Invalid input (:class:`~twoscale.scene.SceneError` for scene data), naming the bad value.
    """
    # the BLAS and OpenMP libraries one thread each (.threads); the objects alive before the
    # solve out of the collector's full passes (.collector)
    with single_threads(), frozen_objects():
        fields = dict(material=material, penetration=penetration, total_load=total_load)
        return _solve(problem, method, provider, h, **fields, **options)


def _solve(problem: Any, method: Any, provider: Any, h: Any, **options: Any) -> Any:
    """:func:`solve` with the thread counts as they are (a solver object sets its own)."""
    call = {k: options.pop(k, default) for k, default in CALL_KEYWORDS.items()}
    provider_options, memory_limit = call["provider_options"], call["memory_limit"]
    given = {k: options.pop(k, None) for k in ("material", "penetration", "total_load")}
    given.update(tilt=call["tilt"], pivot=call["pivot"])
    scene = _scene_of(problem, provider, h, call["shape"], given)
    _check_call(scene, method, provider, provider_options)
    check_memory = memory_limit is None or memory_limit != math.inf  # a NaN limit is refused there
    if scene.history is not None:  # a load history in time (viscoelastic or elastic): a HistoryResult
        from .viscoelastic.solve import history_h, solve_history

        if callable(method):
            raise ValueError("a scene with a load history runs with method 'twoscale' or 'reference', not a callable")
        cell = history_h(scene)  # the given h: the scene carries it
        if check_memory:  # as for one load: before the history's grids are allocated
            _check_memory(scene, cell, method, options, memory_limit, h is not None)
        _check_history_resolution(scene, cell)
        history = solve_history(
            scene, method=method, provider=provider, h=h, provider_options=provider_options, **options
        )
        if history.tilt is not None and len(history.tilt):  # the largest tilt of the reported times
            warn_large_tilt(history.tilt[int(np.argmax(np.abs(history.tilt).max(axis=1)))])
        return history
    if method == "twoscale":  # a misspelt keyword is refused before the body is built
        from .driver import check_keywords

        check_keywords(options)
    h_given = h is not None
    h = default_h(scene)
    check_pivot_reach(scene, h)
    from .io.cache_entry import solve_caches, usage_since

    caches_before = () if provider is None else solve_caches(provider, scene)
    if provider is None:  # its mesh and cached fields only: what its first answers build is estimated below
        provider = scene.provider(**(provider_options or {}))
    elif provider.material != scene.material:
        raise ValueError(f"the provider's material {provider.material!r} is not the scene's {scene.material!r}")
    if not callable(method) and check_memory:
        _check_memory(scene, h, method, options, memory_limit, h_given, provider)
    force, radius = expected_contacts(scene)
    check_domain(scene, provider, h, radii=radius)
    check_resolution(scene, h, forces=force, radii=radius)
    from .setting import with_setting

    if callable(method):  # the body and the nominal area recorded in the result, whatever the method
        return with_setting(method(provider, scene, h=h, **options), scene, provider)
    from .bulge import warn_lifted_tips  # (its body's modules: not at import)

    result = _with_surface_report(scene, _run_method(scene, provider, h, method, options))
    warn_large_tilt(result.tilt)
    warn_lifted_tips(scene, provider, result)
    result = with_setting(result, scene, provider)
    # what came from the on-disk caches (block corrections, surface laws), for result.json
    return dataclasses.replace(result, caches=usage_since(caches_before, solve_caches(provider, scene)))


def _check_history_resolution(scene: Scene, h: float) -> None:
    """Warn as for one load (:func:`check_resolution`) when ``h`` leaves a history's contacts
    few cells across: they are smallest at the glassy modulus (the answer just after a step),
    checked at the history's peak value. Only a warning: the later answers may be resolved."""
    from .viscoelastic.solve import elastic_scene, history_h

    glassy = dataclasses.replace(elastic_scene(scene), material=scene.material.at_modulus(scene.material.E_glassy))
    rule = f"a history's default rule gives h = {history_h(dataclasses.replace(scene, h=None)):.3g} mm"
    check_resolution(glassy, h, context="at the glassy modulus and the history's peak, ", advice=rule)


def _check_call(scene: Scene, method: Any, provider: Any, provider_options: Any) -> None:
    """Refuse a call :func:`solve` cannot answer, naming what is wrong."""
    if not (callable(method) or method in METHODS):
        raise ValueError(f"method must be one of {METHODS} or a callable, got {method!r}")
    if provider is not None and provider_options:
        raise ValueError(
            f"provider_options apply to a provider built here, not to the one passed (got {sorted(provider_options)!r})"
        )
    if getattr(scene, "rolling", None) is not None:
        raise ValueError(
            "this scene has a [rolling] table: run it with twoscale.rolling.roll(scene) (or "
            "'twoscale solve SCENE --out DIR'); twoscale.solve answers one static position "
            "(dataclasses.replace(scene, rolling=None) for the road at rest)"
        )


def _check_memory(
    scene: Scene, h: float, method: str, options: dict, memory_limit: Any, h_given: bool, provider: Any = None
) -> None:
    """Refuse before anything large is allocated when the solve that will run needs more
    memory than ``memory_limit`` (:func:`twoscale.resources.check_solve_memory`)."""
    from .resources import check_solve_memory

    base = options.get("options")
    iteration = (
        options.get("iteration", base.micro.iteration if base is not None else "auto")
        if method == "twoscale"
        else "auto"
    )
    check_solve_memory(
        scene,
        h,
        "twoscale" if method == "twoscale" else "reference",
        iteration=iteration,
        limit_bytes=memory_limit,
        option="h",  # solve(..., h=) or Scene(h=): the keyword a Python caller gives
        h_given=h_given,
        provider=provider,
    )


def _run_method(scene: Scene, provider: InfluenceProvider, h: float, method: str, options: dict) -> ContactResult:
    """The named solver on ``scene``: the two-scale method (or, called without options on a
    scene of a few tips, its full grid's one CG, said in the result) or a reference."""
    from .resources import full_grid_route

    # any solver option asks for the two-scale solver itself; a progress display alone (the
    # command line's) does not: the command line and Python take the same route
    route = None
    if method == "twoscale" and not set(options) - {"progress"}:
        route = full_grid_route(scene, h, provider.kind)
    if route is not None:  # the smallest scenes: their full grid's one CG, said in the result
        from .full_grid import solve_full_grid

        return solve_full_grid(scene, provider, h, route, progress=options.get("progress"))
    if method == "twoscale":
        from .driver import solve_twoscale

        return solve_twoscale(
            provider,
            scene.asperities,
            h=h,
            penetration=scene.penetration,
            total_load=scene.total_load,
            tilt=scene.tilt,
            pivot=scene.pivot,
            **options,
        )
    from .reference.on_scene import solve_reference_scene

    return solve_reference_scene(scene, provider, h, solver="auto" if method == "reference" else method, **options)


def _with_surface_report(scene: Scene, result: ContactResult) -> ContactResult:
    """On a height map: the map's report (filled samples, units, contacts at its edge) in
    ``result.details.surface``, and a warning when contacts reach the map's edge."""
    if scene.surface is None:
        return result
    from .surface.edges import surface_details, warn_edge_contacts

    report = surface_details(scene.surface, result)
    warn_edge_contacts(report.edge_contacts)
    if result.details is not None and hasattr(result.details, "surface"):
        result = dataclasses.replace(result, details=dataclasses.replace(result.details, surface=report))
    return result


def solve_scene(
    scene: Scene,
    *,
    method: str = "twoscale",
    provider_options: Mapping | None = None,
    memory_limit: float | None = None,
    **options: Any,
) -> ContactResult | HistoryResult:
    """Solve a scene: :func:`solve` with a :class:`Scene`.

    Kept for the scene-file workflow; ``method`` is "twoscale" or "reference" (the
    methods a scene file's user picks), the other arguments are :func:`solve`'s.
    """
    if method not in SCENE_METHODS:
        raise ValueError(f"method must be one of {SCENE_METHODS}, got {method!r}")
    return solve(scene, method=method, provider_options=provider_options, memory_limit=memory_limit, **options)


__all__ = ["METHODS", "solve", "solve_scene", "asperities", "as_asperities", "ResolutionWarning"]


def check_domain(scene: Scene, provider: InfluenceProvider, h: float = 0.0, *, radii: np.ndarray | None = None) -> None:
    """Raise :class:`SceneError` naming the first asperity (numbered from 1) whose expected
    patch (1.5 contact radii and two cells of size ``h``) reaches outside the region the
    body answers for (``provider.domain()``, in the provider contract). ``radii``: the
    expected contact radii, when already known."""
    box = provider.domain()
    if box is None:
        return
    x0, x1, y0, y1 = box
    reach = 1.5 * (expected_contact_radii(scene) if radii is None else radii) + 2.0 * h
    for k, (tip, rk) in enumerate(zip(scene.tips, reach)):
        x, y = tip
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            raise SceneError(
                f"asperity {k + 1} at ({x:.4g}, {y:.4g}) mm lies outside the region the block answers "
                f"for, x in [{x0:.4g}, {x1:.4g}], y in [{y0:.4g}, {y1:.4g}] mm (one "
                f"influence.source_spacing inside its sides): move it, or check influence.origin"
            )
        if x - rk < x0 or x + rk > x1 or y - rk < y0 or y + rk > y1:
            raise SceneError(
                f"asperity {k + 1} at ({x:.4g}, {y:.4g}) mm: its contact patch (about {rk:.2g} mm around "
                f"the tip) reaches outside the region the block answers for, x in [{x0:.4g}, {x1:.4g}], "
                f"y in [{y0:.4g}, {y1:.4g}] mm (one influence.source_spacing inside its sides): "
                f"move it inward, or lower influence.source_spacing (default 5 mm)"
            )
