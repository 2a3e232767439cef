"""A solver object that keeps its state between solves: :class:`ContactSolver`.

Load histories, rolling and parameter studies solve many nearly identical contact problems
in a row. ``twoscale.solve`` starts each from nothing; a :class:`ContactSolver`, built once
for a body and options, keeps what stays valid from one solve to the next:

* **the body** (an influence provider): built at the first solve from the scene when not
  given (the finite block keeps its corrections);
* **its caches** (:class:`~twoscale.influence.cached.OperatorCaches`, bounded by
  ``max_cache_bytes``): the half-space's Love offset tables and interpolation matrices, and
  the operators between patches (kernel spectra of FFT products, separated low-rank
  blocks) and of a patch on itself, dense blocks' factorisations per active set and the
  coarse correction's local solves, kept by relative position: the same scene again, or
  moved by whole cells (a rolling road's next position), finds them built; and the far
  field's point operator, kept for the same points.
  The body itself keeps nothing; the solver passes it to the solves seen through these
  caches (:class:`~twoscale.influence.cached.CachedBody`);
* **the previous answer** as the next solve's start (:mod:`twoscale.warm_start`): the macro
  step starts from its forces, approach and tilt; the micro step from its pressure around
  each tip, moved with the tip and scaled to the tip's new macro force. The answer does not
  depend on the start (the same equations, the same tolerances), only the work does. The
  kept pressure is bounded (``max_start_bytes``); above it only the macro start is kept.

Every result says what it reused (``result.reuse``, a :class:`~twoscale.results.Reuse`).
Tips are matched by position in the scene (the same tips in the same order, moved or not);
give ``index=`` when tips enter or leave (each new tip's position among the previous ones,
-1 for a new one).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from .influence.base import InfluenceProvider
from .io.cache_entry import with_construction
from .influence.cached import OPERATOR_CACHE_BYTES, TABLE_CACHE_BYTES, CachedBody, OperatorCaches
from .options import SolverOptions
from .results import ContactResult, Reuse
from .scene import Scene, default_h
from .collector import frozen_objects
from .threads import single_threads, thread_controller
from .warm_start import WarmStart, warm_start

#: Bytes of pressure a solver object keeps from its last solve as the next one's start.
MAX_START_BYTES = 256e6
#: Bound of a solver object's caches (offset tables and pair operators), bytes.
MAX_CACHE_BYTES = TABLE_CACHE_BYTES + OPERATOR_CACHE_BYTES


@dataclasses.dataclass(frozen=True)
class _Previous:
    """What the last solve leaves for the next: its tips, cell size and result."""

    tips: np.ndarray
    h: float
    result: ContactResult


class ContactSolver:
    """Solves contact problems on one body with one set of options, keeping state between solves.

    Parameters
    ----------
    body : InfluenceProvider, optional
        The elastic body (``twoscale.HalfSpace(material)``, ``twoscale.FiniteBlock(...)``, or
        your own provider). Default: the first scene's (``scene.provider()``), kept for the
        solves after it (a later scene asking for another body is refused).
    options : SolverOptions, optional
        Every option of the solves (:mod:`twoscale.options`); default the documented defaults.
    method : {"twoscale", "reference"}, default "twoscale"
        The solver. The reference keeps the body only (it has no warm start).
    max_start_bytes : float, default 256e6
        Bound on the pressure kept from the last solve as the next one's start.
    max_cache_bytes : float, default 256e6
        Bound on the caches kept between solves (a quarter for offset tables and
        interpolation matrices, the rest for operators between patches); 0 keeps none.

    Examples
    --------
    >>> solver = twoscale.ContactSolver(options=SolverOptions(micro=MicroOptions(tol=1e-7)))
    >>> first = solver.solve(scene)
    >>> moved = solver.solve(scene_moved_by_one_cell)    # starts from ``first``
    >>> print(moved.reuse)
    """

    def __init__(
        self,
        body: InfluenceProvider | None = None,
        options: SolverOptions | None = None,
        *,
        method: str = "twoscale",
        max_start_bytes: float = MAX_START_BYTES,
        max_cache_bytes: float = MAX_CACHE_BYTES,
    ) -> None:
        if options is None:
            options = SolverOptions()
        if not isinstance(options, SolverOptions):
            raise ValueError(
                f"options must be a twoscale.SolverOptions, got {type(options).__name__} "
                f"(SolverOptions.from_mapping turns a mapping into one)"
            )
        if method not in ("twoscale", "reference"):
            raise ValueError(f"method must be 'twoscale' or 'reference', got {method!r}")
        if body is not None and not isinstance(body, InfluenceProvider):
            raise ValueError(f"body must be an influence provider, got {type(body).__name__}")
        for name, value in (("max_start_bytes", max_start_bytes), ("max_cache_bytes", max_cache_bytes)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
                raise ValueError(f"{name} must be a number >= 0 (bytes), got {value!r}")
        self.options, self.method = options, method
        self.max_start_bytes = float(max_start_bytes)
        share = TABLE_CACHE_BYTES / MAX_CACHE_BYTES
        self.caches = OperatorCaches(share * max_cache_bytes, (1.0 - share) * max_cache_bytes)
        self._body = body
        self._body_given = body is not None
        self._influence: Any = None  # the scene's influence the body was built from
        self._previous: _Previous | None = None
        self._solves = 0
        self._built: tuple = ()
        self._threads: Any = None  # a threadpoolctl controller, kept from the first solve

    @property
    def body(self) -> InfluenceProvider | None:
        """The body the solves run on (None before the first solve when none was given)."""
        return self._body

    @property
    def solves(self) -> int:
        """Solves made so far."""
        return self._solves

    def __repr__(self) -> str:
        """One line: method, body, solves made, the caches' bytes against their bound, and
        whether a start is kept (no arrays)."""
        from .setting import Body

        body = "no body yet" if self._body is None else Body.of(self._body).label
        start = "a start kept" if self._previous is not None else "no start kept"
        return (
            f"<ContactSolver {self.method}: {body}, {self._solves} solves, caches "
            f"{self.caches.nbytes / 1e6:.1f} of {self.caches.max_bytes / 1e6:.0f} MB, {start}>"
        )

    def reset(self) -> None:
        """Forget the previous answer (the next solve starts cold); the body and the caches
        (valid for any scene on the body) are kept."""
        self._previous = None

    def solve(
        self, problem: Any, *, start: Any = "previous", index: np.ndarray | None = None, **scene_keywords: Any
    ) -> ContactResult:
        """Solve ``problem`` (what :func:`twoscale.solve` takes: a Scene, tips with
        ``material=`` and a load, or a height map).

        Parameters
        ----------
        start : "previous", None or WarmStart, default "previous"
            "previous": start from this solver's last answer when it is still valid (same
            cell size and body; tips matched by ``index`` or by order); None: cold;
            a :class:`~twoscale.warm_start.WarmStart` of your own.
        index : (N,) int array, optional
            Each tip's position among the previous solve's tips, -1 for a new tip.
        **scene_keywords
            ``material``, ``penetration``, ``total_load``, ``tilt``, ``pivot``, ``shape``
            when ``problem`` is tips (as :func:`twoscale.solve`).
        """
        from .api import _scene_of, _solve as solve_once

        given = {k: scene_keywords.pop(k, None) for k in ("material", "penetration", "total_load", "tilt", "pivot")}
        given["tilt"] = bool(given["tilt"])
        shape = scene_keywords.pop("shape", "sphere")
        if scene_keywords:
            raise ValueError(_unknown_keyword(sorted(scene_keywords)[0]))
        res = self.options.resolution
        scene = _scene_of(problem, self._body, res.h, shape, given)
        body_kept = self._body is not None
        body = self._bind_body(scene)
        h = default_h(scene) if scene.history is None else scene.h
        ws = self._start(scene, h, start, index)
        keywords = self.options.twoscale_keywords() if self.method == "twoscale" else self.options.reference.keywords()
        if self.method == "twoscale" and ws is not None and scene.history is None:
            keywords["start"] = ws
        self.caches.start_solve()
        # h=None when the scene chose it: the solve then works on this very scene object and
        # finds what choosing h estimated (the Hertz level) already solved
        if self._threads is None:  # the libraries loaded now, looked up once (twoscale.threads)
            self._threads = thread_controller()
        with single_threads(controller=self._threads), frozen_objects():  # (twoscale.collector)
            cell = res.h if scene.history is None else h
            result = solve_once(
                scene, self.method, CachedBody(body, self.caches), cell, memory_limit=res.memory_limit, **keywords
            )
        self._solves += 1
        if self._built:  # a load history's result records them too
            result = dataclasses.replace(result, caches=with_construction(result.caches, self._built))
        self._built = ()
        if not isinstance(result, ContactResult):  # a load history: its own steps warm-start each other
            return result
        self._remember(scene, h, result)
        micro_started = (
            0
            if ws is None or ws.micro is None
            else int(np.count_nonzero([ws.micro.pressure.loaded(int(k)) for k in ws.micro.index if k >= 0]))
        )
        caches = self.caches
        reuse = Reuse(
            solve=self._solves,
            body_kept=body_kept,
            macro_start=ws is not None and ws.macro is not None,
            pressure_start=micro_started,
            kept_bytes=self._kept_bytes(),
            operators_kept=dict(caches.kept),
            operators_built=dict(caches.built),
            cache_bytes=caches.nbytes,
            cache_max_bytes=caches.max_bytes,
        )
        return dataclasses.replace(result, reuse=reuse)

    # ------------------------------------------------------------------ state
    def _bind_body(self, scene: Scene) -> InfluenceProvider:
        """The kept body; built from the first scene, whose influence and modulus every later
        scene must share (checked whatever was kept: after :meth:`reset` and load histories too)."""
        if self._body is None:
            self._body = scene.provider()
            self._influence = scene.influence
            self._built = self._body.cache_usage()  # recorded by the first solve on it
        elif not self._body_given:
            built, asked = self._body.material, scene.material
            if scene.influence != self._influence or (built.E, built.nu) != (asked.E, asked.nu):
                raise ValueError(
                    f"this solver's body was built for influence {self._influence!r} and "
                    f"{built.relaxed()!r}; the scene asks for {scene.influence!r} and "
                    f"{asked.relaxed()!r}: make another ContactSolver"
                )
        return self._body

    def _start(self, scene: Scene, h: float, start: Any, index) -> WarmStart | None:
        if start is None or self.method != "twoscale" or scene.history is not None or scene.surface is not None:
            return None
        if isinstance(start, WarmStart):
            return start
        if start != "previous":
            raise ValueError(f"start must be 'previous', None or a WarmStart, got {start!r}")
        prev = self._previous
        if prev is None or not prev.result.converged:
            return None
        n = len(scene.asperities)
        if index is None and n != len(prev.tips):
            return None  # different tips and no map between them: a cold start
        keep_pressure = abs(prev.h - h) <= 1e-12 * h
        return warm_start(prev.result, prev.tips, n, h, index=index, pressure=keep_pressure)

    def _remember(self, scene: Scene, h: float, result: ContactResult) -> None:
        tips = np.array([[a.x, a.y] for a in scene.asperities], dtype=float).reshape(-1, 2)
        if _fields_bytes(result) > self.max_start_bytes:
            result = dataclasses.replace(result, fields=())  # the macro start only
        self._previous = _Previous(tips, float(h), result)

    def _kept_bytes(self) -> int:
        prev = self._previous
        if prev is None:
            return 0
        return int(prev.tips.nbytes + _fields_bytes(prev.result))


def _fields_bytes(result: ContactResult) -> int:
    """Bytes of a result's fields (pressure, owner, gap): what keeping it as a start holds."""
    return int(sum(f.pressure.nbytes + f.owner.nbytes + f.gap.nbytes for f in result.fields))


def _unknown_keyword(key: str) -> str:
    """One line for a keyword ``ContactSolver.solve`` does not take, with the option it may mean."""
    import difflib

    from .options import KEYWORDS

    scene = ("material", "penetration", "total_load", "tilt", "pivot", "shape")
    close = difflib.get_close_matches(key, sorted(set(KEYWORDS) | set(scene)), n=1)
    if close and close[0] in KEYWORDS:
        group, name = KEYWORDS[close[0]]
        hint = f" (did you mean the option {group}.{name}? options go in SolverOptions)"
    elif close:
        hint = f" (did you mean {close[0]!r}?)"
    else:
        hint = ": options go in SolverOptions, scene data in the scene"
    return f"unknown keyword {key!r}{hint}"


__all__ = ["ContactSolver", "MAX_CACHE_BYTES", "MAX_START_BYTES"]
