"""Running a rolling study: the unfinished cases, grouped by solve, in this process or on
Dask, each case written to ``DIR/cases/<key>/`` the moment its solve returns.

As for the other studies (:mod:`twoscale.studies.execute`): a rerun skips the cases whose
folder says ``converged`` or ``not-converged`` (a failed case is solved again), leftover
temporary folders are removed first, and Ctrl-C keeps what was written. A case folder
holds ``case.json`` (inputs, status, reason, the case's summary numbers and third-octave
levels, version, seconds, the warnings the run raised) and the rolling run's own files (``signals.csv``,
``asperity_signals.csv``, ``bands.csv``, ``texture.json``, ``rolling.json``, figures).
"""

from __future__ import annotations

import contextlib
import math
import time
from pathlib import Path

from .._version import __version__
from ..io.result_json import UNITS
from ..progress import Progress
from .execute import StudyRun
from .providers import ProviderCache
from .rolling_cases import StripCache, case_inputs, case_key, expand, solve_key
from .rolling_solve import RollingRecord, solve_group
from .rolling_spec import RollingStudy
from .store import CaseStore


def pending(study: RollingStudy, store: CaseStore) -> tuple[list, list, list]:
    """(every case, their keys, the solves to run: ``[[(ref, key), ...], ...]``, each the
    unfinished cases of one solve key, in case order)."""
    cases = expand(study)
    keys = [case_key(c, study) for c in cases]
    groups: dict = {}
    seen: set = set()
    for c, k in zip(cases, keys):
        if k not in seen and not store.finished(k):
            groups.setdefault(solve_key(c, study), []).append((c.ref, k))
        seen.add(k)
    return cases, keys, list(groups.values())


def record_content(record: RollingRecord, inputs: dict) -> dict:
    """The JSON content of a rolling case's ``case.json``."""
    return {
        "key": record.key,
        "label": record.label,
        "status": record.status,
        "reason": record.reason,
        "seconds": _finite(record.seconds),
        "cpu_seconds": _finite(record.cpu_seconds),
        "version": __version__,
        "units": dict(UNITS),
        "inputs": inputs,
        "numbers": record.numbers,
        "bands": list(record.bands),
        "warnings": [dict(w) for w in record.warnings],  # category, one-line message, count
    }


def run_rolling_study(
    study: RollingStudy,
    out: str | Path,
    *,
    workers: int = 0,
    scheduler: str | None = None,
    batch: int = 1,
    quiet: bool = False,
    timeout: float = 20.0,
) -> StudyRun:
    """Solve the unfinished cases of ``study`` into ``out/cases`` (arguments as
    :func:`twoscale.studies.execute.run_study`; ``batch`` counts solves per task)."""
    if isinstance(batch, bool) or not isinstance(batch, int) or batch < 1:
        raise ValueError(f"batch must be an integer >= 1 (solves per task), got {batch!r}")
    store = CaseStore(out)
    store.clean()
    cases, keys, groups = pending(study, store)
    by_key = {k: c for c, k in zip(cases, keys)}
    todo = sum(len(g) for g in groups)
    unique = len(set(keys))
    with contextlib.ExitStack() as stack:
        t0 = time.perf_counter()
        client = None
        if groups and (scheduler is not None or workers > 0):
            from .dask_backend import dask_client

            client = stack.enter_context(dask_client(workers=workers, scheduler=scheduler, timeout=timeout))
        startup = time.perf_counter() - t0
        bar = stack.enter_context(Progress(unique, label="rolling study", quiet=quiet, delay=0.0))
        bar.update(unique - todo)

        def on_record(record: RollingRecord) -> None:
            store.write_folder(record.key, record_content(record, case_inputs(by_key[record.key], study)), record.files)
            bar.update(note=f"{record.label}: {record.status}")

        if not groups:
            where = "nothing to solve"
        elif client is None:
            strips, providers = StripCache(), ProviderCache()
            for group in groups:
                for record in solve_group(study, group, strips, providers):
                    on_record(record)
            where = "serial"
        else:
            from .dask_backend import rolling_task, run_tasks

            def failed(group, reason):
                return [RollingRecord(key, by_key[key].label, "failed", reason) for _, key in group]

            run_tasks(client, study, groups, rolling_task, on_record, failed, batch=batch)
            where = scheduler if scheduler is not None else f"local cluster of {workers} workers"
    return StudyRun(tuple(keys), todo, unique - todo, where, time.perf_counter() - t0, {}, startup)


def _finite(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None
