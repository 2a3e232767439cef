"""Two-scale multi-asperity contact on elastic bodies (units: mm, N, MPa).

>>> import twoscale
>>> mat = twoscale.Material(E=10.0, nu=0.5)
>>> res = twoscale.solve([[0.0, 0.0, 10.0], [3.0, 0.0, 10.0]], material=mat, total_load=5.0)
>>> res.converged, round(float(res.forces.sum()), 6)
(True, 5.0)

* the scene: :class:`Material`, :class:`Grid`, :class:`Asperity` (one rigid tip; or
  :func:`asperities` from arrays), :class:`Scene` (body, tips and load);
* the bodies: :class:`HalfSpace`, and :class:`FiniteBlock` (the rubber block on a rigid
  base, from the separate ``fem_influence`` package, imported on first use);
* :func:`solve`: one entry, ``method`` = "twoscale" (default), "reference", "dense",
  "cg" or a callable, a prebuilt ``provider=`` accepted; returns a :class:`ContactResult`
  (a ``HistoryResult`` for a scene with a :class:`LoadHistory`: viscoelastic rubber,
  ``Material(E, nu, prony=...)``; :mod:`twoscale.viscoelastic`);
* a height map (a road scan) as the indenter: :class:`RawMap` (heights, spacing in mm,
  units), :func:`build_surface` with :class:`SurfaceOptions` (:mod:`twoscale.surface`),
  then ``solve(surface, material=..., total_load=...)``: the same scene, and the same
  answer, as a scene file's ``[surface]`` table;
* a road rolling under the body (signals per position: loads, drag, the stones' forces):
  ``twoscale.rolling.roll(scene)`` on a scene with a ``[rolling]`` table;
* many solves on one body (a load history, a track, a study): :class:`ContactSolver`
  (``ContactSolver(body, SolverOptions(...))``, then ``solver.solve(scene)``) keeps the
  body, bounded caches and its last answer as the next start (``result.reuse`` says what
  was reused); options are frozen :class:`SolverOptions`, listed by :func:`list_options`.

Indices are 0-based in Python (numpy); files and tables written for people number tips
from 1. Light on import: the solvers, scipy and the finite block (scikit-fem) are imported
when first used.
"""

from ._version import __version__
from .api import METHODS, as_asperities, asperities, solve
from .grid import Grid
from .indenters import Asperity
from .material import Material
from .results import ContactResult
from .options import MacroOptions, MicroOptions, ReferenceOptions, ResolutionOptions, SolverOptions, list_options
from .scene import Scene, SceneError

#: Names imported on first use (module, attribute): the bodies and the height maps pull in
#: scipy / scikit-fem / scikit-image.
_LAZY = {
    "HalfSpace": ("twoscale.influence.halfspace", "HalfSpace"),
    "RawMap": ("twoscale.surface.reading", "RawMap"),
    "SurfaceOptions": ("twoscale.surface.measured", "SurfaceOptions"),
    "build_surface": ("twoscale.surface.measured", "build_surface"),
    "LoadHistory": ("twoscale.viscoelastic.history", "LoadHistory"),
    "TimeSteps": ("twoscale.viscoelastic.stepping", "TimeSteps"),
    "ContactSolver": ("twoscale.solver", "ContactSolver"),
    "WarmStart": ("twoscale.warm_start", "WarmStart"),
}

__all__ = [
    "__version__",
    "solve",
    "METHODS",
    "asperities",
    "as_asperities",
    "Material",
    "Grid",
    "Asperity",
    "Scene",
    "SceneError",
    "ContactResult",
    "HalfSpace",
    "FiniteBlock",
    "RawMap",
    "SurfaceOptions",
    "build_surface",
    "LoadHistory",
    "TimeSteps",
    "ContactSolver",
    "WarmStart",
    "SolverOptions",
    "MacroOptions",
    "MicroOptions",
    "ReferenceOptions",
    "ResolutionOptions",
    "list_options",
]


def __getattr__(name: str):
    if name == "FiniteBlock":  # through the body registry: twoscale never imports fem_influence itself
        from .influence.registry import body_class

        return body_class("block")
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'twoscale' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
