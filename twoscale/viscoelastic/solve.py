"""Solving a load history: the time-stepping driver.

Each step (:mod:`twoscale.viscoelastic.memory`) is an elastic contact problem at the
compliance ``J_eff`` with the known history displacement ``u_H = K H`` on the memory grid
(the reference grid of the scene at its relaxed modulus and peak load: every place contact
can reach), solved by the two-scale method or the full-grid reference
(:mod:`twoscale.viscoelastic.steps`), warm-started from the step before. The steps are
chosen by :mod:`twoscale.viscoelastic.stepping`. ``twoscale.solve`` calls
:func:`solve_history` for a scene with a history.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from ..indenters import surface_on
from ..options import MicroOptions
from ..scene import Scene, default_h
from .history import LoadHistory
from .memory import Memory, effective_compliance
from .prony import creep_compliance
from .result import HistoryResult, StepRecord
from .stepping import Controller, TimeSteps, fixed_times, largest_values, local_error
from .steps import ReferenceStep, StepProblem, TwoScaleStep

#: A step that is not reported solves its micro step to this fraction of the time steps'
#: tolerance (when looser than the solver's own): its error reaches the reported answers
#: only through the memory, and is then far below the time-stepping error.
INNER_FRACTION = 1e-2

#: The default cell size resolves the glassy contact, but is at most this factor finer
#: than the relaxed one's (a glassy modulus 1,000 times the relaxed one would otherwise ask
#: for 100 times the cells).
MAX_REFINE = 1.5


def elastic_scene(scene: Scene) -> Scene:
    """The scene at its relaxed modulus and peak value, without history (grid sizing)."""
    hist = scene.history
    load = (
        {"penetration": hist.peak, "total_load": None}
        if hist.kind == "penetration"
        else {"total_load": hist.peak, "penetration": None}
    )
    return dataclasses.replace(scene, material=scene.material.relaxed(), history=None, **load)


def history_h(scene: Scene) -> float:
    """Default cell size of a history (:data:`MAX_REFINE`)."""
    if scene.h is not None:
        return float(scene.h)
    relaxed = elastic_scene(scene)
    glassy = dataclasses.replace(relaxed, material=scene.material.at_modulus(scene.material.E_glassy))
    return max(default_h(glassy), default_h(relaxed) / MAX_REFINE)


def _memory_grid(scene: Scene, h: float):
    from ..reference.on_scene import reference_grid

    relaxed = elastic_scene(scene)
    if scene.surface is not None:
        return scene.surface.hmap.grid
    return reference_grid(relaxed, h, grow=1.2)


def _step_solver(scene: Scene, provider, grid, h: float, method: str, options: dict):
    kind = scene.history.kind
    if method == "twoscale":  # a height map's basins too (the history displacement lifts their map)
        return TwoScaleStep(
            provider, scene.asperities, grid, h=h, kind=kind, tilt=scene.tilt, pivot=scene.pivot, options=options
        )
    if method in ("reference", "dense", "cg"):
        return ReferenceStep(
            provider,
            surface_on(grid, scene.asperities),
            kind=kind,
            tilt=scene.tilt,
            pivot=scene.pivot,
            solver="auto" if method == "reference" else method,
            options=options,
        )
    raise ValueError(f"method must be 'twoscale', 'reference', 'dense' or 'cg' for a history, got {method!r}")


def solve_history(
    scene: Scene,
    *,
    method: str = "twoscale",
    provider=None,
    h: float | None = None,
    steps: TimeSteps | None = None,
    progress=None,
    provider_options=None,
    **options,
) -> HistoryResult:
    """Solve the scene's load history (``scene.history``).

    Parameters
    ----------
    scene : Scene
        With a :class:`~twoscale.viscoelastic.history.LoadHistory`; its material may have
        Prony branches (``Material(E, nu, prony=...)``) or none (quasi-static elastic).
    method : {"twoscale", "reference", "dense", "cg"}, default "twoscale"
        The solver of every step.
    provider : InfluenceProvider, optional
        The body at the relaxed modulus (``scene.material.relaxed()``); default the scene's.
    h : float, optional
        Cell size, mm; default :func:`history_h`.
    steps : TimeSteps, optional
        Overrides ``scene.history.steps``.
    progress : callable, optional
        Called with a line per step.
    provider_options : mapping, optional
        Passed to the scene's provider when it is built here.
    **options
        Passed to the step solver (two-scale or reference options).

    Returns
    -------
    HistoryResult
    """
    t_start = time.perf_counter()
    hist: LoadHistory = scene.history
    if hist is None:
        raise ValueError("the scene has no load history (load.total or load.penetration as [[t, value], ...])")
    steps = steps or hist.steps
    h = float(h) if h is not None else history_h(scene)
    relaxed = elastic_scene(scene)
    from ..io.cache_entry import solve_caches, usage_since

    caches_before = () if provider is None else solve_caches(provider, relaxed)
    provider = provider if provider is not None else relaxed.provider(**(provider_options or {}))
    if provider.material.relaxed() != relaxed.material:
        raise ValueError(
            f"the provider's material {provider.material!r} is not the scene's relaxed {relaxed.material!r}"
        )
    grid = _memory_grid(scene, h)
    run = _Run(scene, provider, grid, _step_solver(scene, provider, grid, h, method, options), steps, progress)
    run.go()
    result = run.result(method, time.perf_counter() - t_start)
    # what the body's caches gave and took, its build here included (for result.json)
    return dataclasses.replace(result, caches=usage_since(caches_before, solve_caches(provider, relaxed)))


class _Run:
    """The state of one history solve (memory, step solver, records)."""

    def __init__(self, scene, provider, grid, solver, steps: TimeSteps, progress):
        self.scene, self.hist, self.grid, self.solver = scene, scene.history, grid, solver
        self.steps, self.progress = steps, progress
        self.J = creep_compliance(scene.material)
        self.memory = Memory(self.J, grid.size)
        self.E0 = float(provider.material.E)
        self.op = provider.grid_operator(grid)
        self.records: list[StepRecord] = []
        self.outputs: list = []  # (t, ContactResult)
        self.rejected = 0
        self.last = self.prev = None
        self.largest: list = []  # the largest |x| of each stepped quantity so far
        self.converged, self.messages = True, []

    # ------------------------------------------------------------ one step
    def _solve(self, t: float, dt: float):
        J_eff = effective_compliance(self.J, dt)
        H = self.memory.history_field(dt)
        u_H = self.E0 * self.op.apply(H.reshape(self.grid.shape)) if np.any(H) else np.zeros(self.grid.shape)
        value = float(self.hist.value(t))
        t0 = time.perf_counter()
        result = self.solver.solve(StepProblem(value, self.E0 * J_eff, u_H, self.last, tol=self._inner_tol(t)))
        return result, J_eff, time.perf_counter() - t0

    def _inner_tol(self, t: float) -> float | None:
        """The micro tolerance of the step ending at ``t``: the solver's own at a reported
        time, else :data:`INNER_FRACTION` of the time steps' tolerance if that is looser."""
        own = float(self.solver.options.get("tol", MicroOptions.tol))
        out = self.hist.output
        if (
            self.solver.name != "twoscale"
            or INNER_FRACTION is None
            or out is None
            or np.any(np.isclose(out, t, rtol=1e-12, atol=1e-300))
        ):
            return None
        return max(own, INNER_FRACTION * self.steps.tol)

    def _commit(self, t, dt, result, J_eff, error, seconds) -> None:
        self.memory.advance(dt, result.pressure_on(self.grid).ravel())
        self.prev, self.last = self.last, result
        self.largest = largest_values(self.largest, self._quantities(result))
        if not result.converged:
            self.converged = False
            self.messages.append(f"t = {t:.6g} s: {result.message or 'not converged'}")
        its = int(sum(v for v in result.iterations.values() if isinstance(v, (int, np.integer))))
        self.records.append(StepRecord(float(t), float(dt), float(J_eff), error, its, float(seconds)))
        if self.hist.output is None or np.any(np.isclose(self.hist.output, t, rtol=1e-12, atol=1e-300)):
            self.outputs.append((float(t), result))
        if self.progress is not None:
            self.progress(
                f"t = {t:.4g} s, dt = {dt:.3g} s, load {result.total_load:.4g} N, approach {result.penetration:.4g} mm"
            )

    # ------------------------------------------------------------ the march
    def go(self) -> None:
        hist = self.hist
        t = float(hist.times[0])
        marks = np.unique(np.concatenate([hist.times, np.asarray(hist.output or (), dtype=float)]))
        res, J_eff, sec = self._solve(t, 0.0)  # the glassy instant (or the zero state)
        self._commit(t, 0.0, res, J_eff, None, sec)
        if self.steps.fixed:
            for t_new in fixed_times(self.steps, hist.end, marks):
                if t_new <= t:
                    continue
                res, J_eff, sec = self._solve(t_new, t_new - t)
                self._commit(t_new, t_new - t, res, J_eff, self._estimate(t_new - t, res), sec)
                t = t_new
            return
        self._automatic(t, marks)

    def _automatic(self, t: float, marks: np.ndarray) -> None:
        hist, kinks = self.hist, set(self.hist.times.tolist())
        taus = [t for _, t in self.scene.material.prony]  # relaxation is faster than retardation
        ctl = Controller(self.steps, marks, min(taus, default=math.inf), hist.end)
        ctl.restart(t)
        since_kink = 0
        while t < hist.end and len(self.records) < self.steps.max_steps:
            t_new = ctl.propose(t)
            dt = t_new - t
            res, J_eff, sec = self._solve(t_new, dt)
            err = self._estimate(dt, res) if since_kink >= 2 else None
            if not ctl.accept(dt, err):
                self.rejected += 1
                if ctl.stuck is not None:
                    self.converged = False
                    self.messages.append(f"stopped at t = {t:.6g} s: {ctl.stuck}")
                    return
                continue
            self._commit(t_new, dt, res, J_eff, err, sec)
            t, since_kink = t_new, since_kink + 1
            if t in kinks:
                ctl.restart(t)
                since_kink = 0 if self.J.lambdas.size else since_kink
        if t < hist.end:
            self.converged = False
            self.messages.append(f"stopped at t = {t:.6g} s after time.max_steps = {self.steps.max_steps} steps")

    def _estimate(self, dt: float, res) -> float | None:
        """Relative local error of the step (:mod:`twoscale.viscoelastic.stepping`), from it
        and the two steps before; None without two earlier step ends on the same linear
        piece of the history (a kink or the glassy instant between them)."""
        if self.prev is None or not self.records or self.records[-1].dt <= 0:
            return None
        t_prev, t_now = self.records[-2].t, self.records[-1].t
        if np.any((self.hist.times > t_prev) & (self.hist.times <= t_now)):
            return None
        x = [self._quantities(r) for r in (self.prev, self.last, res)]
        return max(local_error(a, b, c, self.records[-1].dt, dt, m) for a, b, c, m in zip(*x, self.largest))

    def _quantities(self, res) -> tuple:
        """The approach (load control) or total load (penetration control), and the forces."""
        conj = res.penetration if self.hist.kind == "total" else res.total_load
        return (np.array([conj]), np.asarray(res.forces, dtype=float))

    # ------------------------------------------------------------ the answer
    def result(self, method: str, seconds: float) -> HistoryResult:
        ts = np.array([t for t, _ in self.outputs])
        rs = tuple(r for _, r in self.outputs)
        tilt = np.array([r.tilt for r in rs]) if self.scene.tilt else None
        errors = [s.error for s in self.records if s.error is not None]
        nb = int(self.J.lambdas.size)
        memory = {
            "branches": nb,
            "peak_cells": int(self.memory.peak_cells),
            "bytes_per_cell": 8 * (2 + nb),
            "peak_bytes": int(8 * (2 + nb) * self.memory.peak_cells),
            "grid_cells": int(self.grid.size),
        }
        solve_s = float(sum(s.seconds for s in self.records))
        return HistoryResult(
            times=ts,
            penetration=np.array([r.penetration for r in rs]),
            total_load=np.array([r.total_load for r in rs]),
            contact_area=np.array([float(np.sum(r.asperities.contact_areas)) for r in rs]),
            tilt=tilt,
            forces=np.array([r.forces for r in rs]),
            results=rs,
            steps=tuple(self.records),
            rejected=int(self.rejected),
            error_estimate=float(max(errors, default=0.0)),
            method=method,
            material=self.scene.material,
            history=self.hist,
            memory=memory,
            converged=bool(self.converged),
            message="; ".join(self.messages),
            timings_s={"total": float(seconds), "steps": solve_s},
        )
