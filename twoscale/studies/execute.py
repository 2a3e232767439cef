"""Running a study: the cases not yet finished, in this process or on Dask, each
written to its folder as soon as it is done.

Order of work: expand the study into cases and their keys; skip the cases whose folder
says they are finished (a rerun resumes); start the Dask cluster, if any (a local
cluster's workers start in the background); compute once what the block bodies need
(:func:`~twoscale.studies.providers.warm_blocks`); then solve the rest, serially
(``workers=0``) or as Dask tasks, writing each case's folder as its record arrives.
Ctrl-C stops the run: the cases already written stay, the others are solved by the next
run.
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass, field
from pathlib import Path

from .cases import Case, case_scene, expand
from .keys import case_inputs, case_key
from ..progress import Progress
from .providers import ProviderCache, warm_blocks
from .solve import CaseRecord, solve_ref
from .spec import Study
from .store import CaseStore


@dataclass(frozen=True)
class StudyRun:
    """What one run of a study did.

    Attributes
    ----------
    keys : tuple of str
        The study's case keys, in case order (repeated cases share a key).
    ran : int
        Cases solved by this run.
    skipped : int
        Cases found finished and not solved again.
    where : str
        "serial", "local cluster of N workers" or the scheduler's address.
    seconds : float
        Wall time of the solving (after the warm-up) and of starting (or reaching) the
        Dask cluster, s. A local cluster's workers start in the background during the
        warm-up; the solving then includes any wait for them.
    warm_seconds : dict
        Seconds spent computing each block body's correction before the cases.
    startup_seconds : float
        Of ``seconds``, the time to start a local cluster's scheduler (its workers start
        in the background) or to reach a cluster, s (0 serially).
    """

    keys: tuple
    ran: int
    skipped: int
    where: str
    seconds: float
    warm_seconds: dict = field(default_factory=dict)
    startup_seconds: float = 0.0


def pending(study: Study, store: CaseStore) -> tuple[list[Case], list[str], list[Case]]:
    """(every case, their keys, the cases to solve: unfinished, one per key)."""
    cases = expand(study)
    keys = [case_key(c, study) for c in cases]
    todo, seen = [], set()
    for c, k in zip(cases, keys):
        if k not in seen and not store.finished(k):
            todo.append(c)
        seen.add(k)
    return cases, keys, todo


def _warm(study: Study, todo: list[Case], quiet: bool) -> dict:
    scenes = []
    for c in todo:
        if c.body.influence["kind"] == "block":
            try:
                scenes.append(case_scene(c, study))
            except ValueError:  # the case will fail and say why
                continue
    return warm_blocks(scenes, progress=not quiet) if scenes else {}


def run_study(
    study: Study,
    out: str | Path,
    *,
    workers: int = 0,
    scheduler: str | None = None,
    batch: int = 1,
    quiet: bool = False,
    timeout: float = 20.0,
) -> StudyRun:
    """Solve the unfinished cases of ``study`` into ``out/cases``.

    Parameters
    ----------
    study : Study
    out : path
        The study's output folder (created; reused by a rerun, which resumes).
    workers : int, default 0
        0: solve in this process, one case after the other. N >= 1: a local Dask
        cluster of N worker processes. Ignored when ``scheduler`` is given.
    scheduler : str, optional
        Address of an existing Dask scheduler (e.g. ``tcp://host:8786``).
    batch : int, default 1
        Cases per Dask task (consecutive in case order, so a track's positions go
        together): fewer, longer tasks for large clusters whose scheduler would otherwise
        dispatch thousands of short tasks a second. A batch's cases are written when the
        whole batch returns.
    quiet : bool, default False
        No progress bar.
    timeout : float, default 20
        Seconds to reach ``scheduler``.

    Raises
    ------
    OSError
        ``scheduler`` cannot be reached (``dask_backend.SchedulerError``); no case has run.
    """
    if isinstance(batch, bool) or not isinstance(batch, int) or batch < 1:
        raise ValueError(f"batch must be an integer >= 1 (cases per task), got {batch!r}")
    store = CaseStore(out)
    store.clean()
    cases, keys, todo = pending(study, store)
    key_of = {id(c): k for c, k in zip(cases, keys)}
    by_key = {key_of[id(c)]: c for c in todo}
    unique = len(set(keys))
    on_dask = bool(todo) and (scheduler is not None or workers > 0)
    with contextlib.ExitStack() as stack:
        t0 = time.perf_counter()
        client = None
        if on_dask:
            from .dask_backend import dask_client

            # a local cluster's workers start while the blocks warm up
            client = stack.enter_context(dask_client(workers=workers, scheduler=scheduler, timeout=timeout))
        startup = time.perf_counter() - t0
        warm = _warm(study, todo, quiet)
        t1 = time.perf_counter()
        bar = stack.enter_context(Progress(unique, label="study", quiet=quiet, delay=0.0))
        bar.update(unique - len(todo))  # a resumed study starts with its finished cases

        def on_record(record: CaseRecord) -> None:
            store.write(record, case_inputs(by_key[record.key], study))
            bar.update(note=f"{record.label}: {record.status}")

        if not todo:
            where = "nothing to solve"
        elif client is None:
            providers = ProviderCache()
            for c in todo:
                on_record(solve_ref(study, c.ref, key_of[id(c)], providers))
            where = "serial"
        else:
            from .dask_backend import run_on_dask

            run_on_dask(
                client,
                study,
                [(c.ref, key_of[id(c)]) for c in todo],
                {k: c.label for k, c in by_key.items()},
                on_record,
                batch=batch,
            )
            where = scheduler if scheduler is not None else f"local cluster of {workers} workers"
    return StudyRun(
        tuple(keys), len(todo), unique - len(todo), where, time.perf_counter() - t1 + startup, warm, startup
    )
