"""Solving the cases of one rolling solve (:func:`~twoscale.studies.rolling_cases.solve_key`):
roll once, then for each case (each speed of an elastic body) write the rolling run's own
files and summarise them.

Runs where the study's tasks run (this process or a Dask worker): the files are written to
a temporary folder there and returned as bytes in the :class:`RollingRecord`, which the
study's process writes into the case's folder, so the output folder need not be shared
with the workers. A failure is a record too (``status = "failed"`` and the reason).
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import io
import tempfile
import time
import traceback
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io.warning_log import entries_of
from .providers import ProviderCache
from .rolling_cases import StripCache, case_at, case_scene, with_speed
from .rolling_spec import RollingStudy


@dataclass(frozen=True)
class RollingRecord:
    """A rolling case's outcome as stored.

    ``files`` maps each file of the run (``signals.csv``, ``bands.csv``, ...) to its bytes;
    ``numbers`` the case's summary (:func:`case_numbers`); ``bands`` the rows of
    ``bands.csv``; ``seconds`` and ``cpu_seconds`` the solve's (shared by the cases of one
    solve) and the writing; ``warnings`` the run's (:func:`twoscale.io.warning_log.entries_of`,
    also in its ``rolling.json``)."""

    key: str
    label: str
    status: str
    reason: str
    files: dict = field(default_factory=dict)
    numbers: dict = field(default_factory=dict)
    bands: tuple = ()
    seconds: float = float("nan")
    cpu_seconds: float = float("nan")
    warnings: tuple = ()


def retimed(result, speed: float):
    """An elastic run's result at another speed (km/h): the same positions, their times
    distance / speed."""
    spec = dataclasses.replace(result.spec, speed=speed)
    return dataclasses.replace(result, spec=spec, times=(result.shifts - result.shifts[0]) / spec.speed_mm_s)


def case_numbers(result) -> dict:
    """One row of the study's cases table from a rolling result: means and rms fluctuations
    of the signals, the drag (hysteresis friction on a viscoelastic body) and, with the
    branches' energy, the dissipation per distance and the balance of the drag's work."""
    n = len(result.shifts)
    load, d = np.asarray(result.total_load), np.asarray(result.penetration)
    distance = float(result.shifts[-1] - result.shifts[0])
    out = {
        "positions": n,
        "converged_positions": int(np.sum(result.converged)),
        "h_mm": float(result.h),
        "distance_mm": distance,
        "duration_s": float(result.times[-1]),
        "mean_load_N": float(load.mean()),
        "load_rms_N": float(load.std()),
        "mean_approach_mm": float(d.mean()),
        "approach_rms_mm": float(d.std()),
        "mean_contact_area_mm2": float(np.mean(result.contact_area)),
        "mean_drag_N": result.mean_drag,
        "friction_coefficient": result.mean_drag / float(load.mean()) if load.mean() > 0 else None,
        "dissipated_per_mm_N": None,
        "energy_balance": None,
        "seconds_per_position": float(np.mean(result.seconds)),
    }
    balance = result.energy_balance()
    if balance is not None and distance > 0:
        out["dissipated_per_mm_N"] = balance["dissipated"] / distance
        out["energy_balance"] = balance["mismatch"]
    return out


def case_files(result, scene, *, figures: bool, name: str, warnings=()) -> tuple[dict, tuple]:
    """The files a rolling run writes (``twoscale solve``'s, less the VTK series), as
    ``{name: bytes}``, and the rows of ``bands.csv``; ``warnings``: the run's, for ``rolling.json``."""
    from ..io.rolling_outputs import write_rolling_tables, write_signal_products

    with tempfile.TemporaryDirectory(prefix="twoscale-rolling-case-") as tmp:
        out = Path(tmp)
        write_rolling_tables(result, scene, out, warnings=warnings)
        write_signal_products(result, scene, out, figures=figures, name=name)
        files = {p.name: p.read_bytes() for p in sorted(out.iterdir()) if p.is_file()}
    bands = ()
    if "bands.csv" in files:
        bands = tuple(
            {k: float(v) for k, v in row.items()}
            for row in csv.DictReader(io.StringIO(files["bands.csv"].decode("utf-8")))
        )
    return files, bands


@contextlib.contextmanager
def _case_warnings(label: str) -> Iterator[list]:
    """The warnings of a case's run (a coarse step: :class:`~twoscale.errors.StepWarning`)
    again, each led by the case's label, so that a study's lines say which case they are
    about; the list it gives is filled with their entries (without the label) for the files."""
    kept: list = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield kept
    kept.extend(entries_of(caught))
    for w in caught:
        warnings.warn(f"{label}: {w.message}", w.category, stacklevel=3)


def offset_reason(exc: Exception, case, study: RollingStudy) -> str:
    """Where the strip does not cover the run that a section's offset moved
    (:class:`~twoscale.rolling.track.StripTooShort`), the reason naming the offset, its
    value and the offsets that fit; else ``""``."""
    from ..rolling.track import StripTooShort

    o = case.section.offset
    if not isinstance(exc, StripTooShort) or o == 0:
        return ""
    lo, hi = exc.shifts_that_fit()
    t = study.track
    fits = t["end"] - hi, t["start"] - lo  # shift = rolling.start (end) - offset
    allowed = f"offsets from {fits[0]:.4g} to {fits[1]:.4g} mm fit" if fits[0] <= fits[1] else "no offset fits"
    return (
        f"section {case.section.name}: offsets value {o:g} mm moves the run to shifts {t['start'] - o:g} ... "
        f"{t['end'] - o:g} mm, off the strip ({exc.strip[0]:.4g} to {exc.strip[1]:.4g} mm along x, the footprint "
        f"about {exc.contact:.4g} mm long on it at every shift): {allowed}"
    )


def solve_group(study: RollingStudy, group: list, strips: StripCache, providers: ProviderCache) -> list:
    """Roll the cases ``group`` = ``[(ref, key), ...]`` of one solve; their records in order.
    Any error but Ctrl-C becomes failed records with the reason."""
    from ..rolling.run import RollingOptions, roll

    t0, c0 = time.perf_counter(), time.thread_time()
    cases = [(case_at(study, *ref), key) for ref, key in group]
    try:
        scene = case_scene(cases[0][0], study, strips)
        provider = None if scene.material.viscoelastic else providers.get(scene)
        with _case_warnings(cases[0][0].label) as raised:
            result = roll(scene, options=RollingOptions(**study.solver), provider=provider)
    except Exception as exc:  # noqa: BLE001 - a failing case is recorded, the study goes on
        reason = f"{type(exc).__name__}: {offset_reason(exc, cases[0][0], study) or exc}"
        if not isinstance(exc, ValueError):
            reason += " | " + traceback.format_exc(limit=-3).replace("\n", " ")
        return [
            RollingRecord(
                key, case.label, "failed", reason, seconds=time.perf_counter() - t0, cpu_seconds=time.thread_time() - c0
            )
            for case, key in cases
        ]
    seconds, cpu = time.perf_counter() - t0, time.thread_time() - c0
    records = []
    for case, key in cases:
        mine = result if case.speed == result.spec.speed else retimed(result, case.speed)
        files, bands = case_files(
            mine, with_speed(scene, case.speed), figures=study.figures, name=case.label, warnings=raised
        )
        bad = int(np.sum(~mine.converged))
        status = "converged" if bad == 0 else "not-converged"
        reason = "" if bad == 0 else f"{bad} of {len(mine.shifts)} positions did not converge (rolling.json lists them)"
        numbers = case_numbers(mine)
        records.append(
            RollingRecord(key, case.label, status, reason, files, numbers, bands, seconds, cpu, tuple(raised))
        )
    return records
