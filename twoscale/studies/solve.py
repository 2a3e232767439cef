"""Solving one case: the solver call, the one adapter that reads its result, and the
record of the outcome (a failure is an outcome too).

:func:`run_case` never raises for a case that cannot be solved: it returns a
:class:`CaseRecord` with ``status = "failed"`` and the reason, so one bad case does not
stop the others. Ctrl-C (``KeyboardInterrupt``) still goes through.
"""

from __future__ import annotations

import time
import traceback
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..io.warning_log import WarningLog
from ..sensor import Sensor
from .cases import case_at, case_scene, kept_tips
from .providers import ProviderCache
from .spec import Study


@dataclass(frozen=True)
class Outcome:
    """What a study keeps of one solve (scene order of the kept tips).

    forces (N), contact_areas (mm^2), max_pressures (MPa) per kept tip; sensor_map
    (ny, nx) MPa in the body frame; total_load N; penetration mm; tilt (alpha, beta) rad
    or None; h mm; iterations and timings as the solver reports them.
    """

    converged: bool
    message: str
    total_load: float
    penetration: float
    tilt: tuple | None
    forces: np.ndarray
    contact_areas: np.ndarray
    max_pressures: np.ndarray
    sensor_map: np.ndarray
    h: float
    strategy: str
    iterations: dict = field(default_factory=dict)
    timings_s: dict = field(default_factory=dict)


def read_result(result: Any, sensor: Sensor) -> Outcome:
    """The solver's result as an :class:`Outcome`: the only place that reads a result
    object (its fields and typed ``details``)."""
    s = result.asperities
    micro = getattr(result.details, "micro", None)
    return Outcome(
        converged=bool(result.converged),
        message=str(result.message),
        total_load=float(result.total_load),
        penetration=float(result.penetration),
        tilt=None if result.tilt is None else (float(result.tilt[0]), float(result.tilt[1])),
        forces=np.array(s.forces, dtype=float),
        contact_areas=np.array(s.contact_areas, dtype=float),
        max_pressures=np.array(s.max_pressures, dtype=float),
        sensor_map=sensor.average(result),
        h=float(result.fields[0].grid.h) if result.fields else float("nan"),
        strategy=str(micro.strategy if micro is not None else result.solver),
        iterations={k: int(v) for k, v in result.iterations.items()},
        timings_s={k: float(v) for k, v in result.timings_s.items()},
    )


def solve_case(scene: Any, *, method: str, options: dict, providers: ProviderCache, sensor: Sensor) -> Outcome:
    """Solve one case's scene through :func:`twoscale.solve` with the provider of its body
    taken from ``providers`` (the memory check and the body's region check are the
    entry's own)."""
    from ..api import solve

    opts = {k: v for k, v in options.items() if k != "h"}
    return read_result(solve(scene, method=method, provider=providers.get(scene), **opts), sensor)


@dataclass(frozen=True)
class CaseRecord:
    """A case's outcome as stored: status, reason, kept tips and the solve's numbers.

    Attributes
    ----------
    key : str
    label : str
    status : {"converged", "not-converged", "failed"}
    reason : str
        The solver's message, or the error of a failed case ("" when converged).
    tips : (K,) int array
        Scene indices of the kept tips (empty when the case failed before solving).
    outcome : Outcome or None
        None for a failed case.
    seconds : float
        Wall time of the case on its worker, s.
    cpu_seconds : float
        CPU time of the thread that ran the case, s (on a shared machine the wall time
        also counts the waits for a core; this does not, as long as the case's own
        numerical libraries run in that thread: one BLAS thread).
    warnings : tuple of dict
        The warnings the case raised (:meth:`twoscale.io.warning_log.WarningLog.entries`),
        also when it failed.
    """

    key: str
    label: str
    status: str
    reason: str
    tips: np.ndarray
    outcome: Outcome | None
    seconds: float
    cpu_seconds: float = float("nan")
    warnings: tuple = ()


def run_case(
    key: str,
    label: str,
    make_scene,
    tips: np.ndarray,
    *,
    method: str,
    options: dict,
    providers: ProviderCache,
    sensor: Sensor,
) -> CaseRecord:
    """Build the case's scene (``make_scene()``), solve it and record the outcome; any
    error but Ctrl-C becomes a failed record with its reason."""
    t0, c0 = time.perf_counter(), time.thread_time()
    log = WarningLog()
    try:
        with log:  # shown as ever, and kept for case.json
            outcome = solve_case(make_scene(), method=method, options=options, providers=providers, sensor=sensor)
    except Exception as exc:  # noqa: BLE001 - a failing case is recorded, the study goes on
        reason = f"{type(exc).__name__}: {exc}"
        if not isinstance(exc, ValueError):  # an unexpected error: keep where it came from
            reason += " | " + traceback.format_exc(limit=-3).replace("\n", " ")
        return CaseRecord(
            key,
            label,
            "failed",
            reason,
            np.asarray(tips, dtype=int),
            None,
            time.perf_counter() - t0,
            time.thread_time() - c0,
            tuple(log.entries()),
        )
    status = "converged" if outcome.converged else "not-converged"
    return CaseRecord(
        key,
        label,
        status,
        outcome.message,
        np.asarray(tips, dtype=int),
        outcome,
        time.perf_counter() - t0,
        time.thread_time() - c0,
        tuple(log.entries()),
    )


def solve_ref(study: Study, ref: tuple, key: str, providers: ProviderCache) -> CaseRecord:
    """Solve the case of ``study`` at ``ref`` (see ``Case.ref``) and record it."""
    case = case_at(study, *ref)
    return run_case(
        key,
        case.label,
        lambda: case_scene(case, study),
        kept_tips(case),
        method=study.method,
        options=study.solver,
        providers=providers,
        sensor=study.sensor,
    )
