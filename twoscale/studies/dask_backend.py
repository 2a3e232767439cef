"""Cases as tasks on ``dask.distributed``: a local cluster of worker processes, or an
existing cluster by its scheduler's address.

Each worker keeps its own :class:`~twoscale.studies.providers.ProviderCache` (a worker
plugin), so the cases a worker runs share the bodies' influence providers. The study is
sent to every worker once; a task receives only the case's indices and key, and returns
its :class:`~twoscale.studies.solve.CaseRecord` to this process, which writes the case
folder: the output folder need not be shared with the workers. Workers run one thread
each (the solver is Python-heavy, and a block provider is not shared between threads).

Imported only when a study runs on Dask: the library imports without ``distributed``.
"""

from __future__ import annotations

import contextlib
import importlib
import logging
import multiprocessing
import signal
from multiprocessing import resource_tracker
import sys
import uuid
import warnings
from typing import Callable, Iterator

import numpy as np
from distributed import Client, LocalCluster, WorkerPlugin, as_completed, get_worker

from ..errors import SchedulerError
from .providers import MAX_PROVIDERS, ProviderCache
from .rolling_cases import StripCache
from .rolling_solve import solve_group
from .solve import CaseRecord, solve_ref

#: Name of the worker plugin that holds each worker's providers.
PLUGIN = "twoscale-study-providers"
#: glibc's trim threshold in the local workers: None leaves it unset. Dask sets it to
#: 64 KiB, which returns freed memory to the system at once, and any explicit value also
#: stops glibc adapting its mmap threshold, so the arrays of a few MB the solver frees and
#: reallocates at every sweep are mapped afresh each time. On the 12-case S2 study (two
#: workers against one process, contended) the cases' own CPU time was 1.3-1.6x the serial
#: one with 64 MiB and 1.05-1.2x unset; three solves in one process took 3.7 s of wall time
#: with 64 KiB against 2.3-3.2 s unset.
TRIM_THRESHOLD = None
#: Seconds to wait for a first worker before sending the study.
WORKER_WAIT = 120.0
#: Modules a worker imports when it starts rather than in its first case (about 0.5 s).
WORKER_IMPORTS = ("twoscale.api", "twoscale.driver", "twoscale.scene", "twoscale.reference.on_scene")
#: Settings of the local cluster (its workers inherit them through their nannies). Dask's
#: profiler samples each worker's running task every 10 ms, taking the interpreter lock from
#: the solver's thread: the cases' wall time on a one-worker cluster was 1.14x that of the
#: same cases in one process with it (twice), 1.03x without. The memory and system monitors
#: are only slowed: a cluster of two idle workers used 0.79 s of CPU per 10 s with Dask's
#: defaults, 0.48 s with these. Every process of the cluster also wakes its event loop
#: every 20 ms only to warn when the loop was blocked (the "tick"; the local cluster's logs
#: are silenced), taking the interpreter lock from a worker's solver each time: at 1 s, an
#: idle 2-worker cluster used 0.11-0.13 s of CPU per 10 s (this process and the workers)
#: against 0.40-0.62 s. With one thread a worker, each is sent one task at a time (worker
#: saturation 1.0: the next one as it reports the last, a local round trip against cases of
#: about 0.5 s), so there is nothing to rebalance and work stealing, which the scheduler
#: would otherwise run every second, is off.
LOCAL_CONFIG = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": TRIM_THRESHOLD,
    "distributed.worker.profile.enabled": False,
    "distributed.worker.memory.monitor-interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.admin.tick.interval": "1s",
    "distributed.scheduler.worker-saturation": 1.0,
    "distributed.scheduler.work-stealing": False,
}


def warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """A library warning as one ``warning:`` line on stderr, as the command prints its own
    (Python's default adds the warning's source file, line and code)."""
    print(f"warning: {message}", file=sys.stderr)


class ProvidersPlugin(WorkerPlugin):
    """Gives each worker a :class:`ProviderCache` (owned by the worker, dropped with it).
    ``warning_lines``: the worker prints warnings (a case's coarse step or cell size) as
    one ``warning:`` line each; set for the local cluster's workers, which share the
    command's terminal, not for an existing cluster's."""

    name = PLUGIN

    def __init__(self, max_providers: int = MAX_PROVIDERS, *, warning_lines: bool = False):
        self.max_providers = max_providers
        self.warning_lines = warning_lines
        self.cache = None
        self.strips = None

    def setup(self, worker) -> None:
        self.cache = ProviderCache(self.max_providers)
        self.strips = StripCache()  # a rolling study's strips, segmented once per worker
        if self.warning_lines:  # the worker process is the study's own
            warnings.showwarning = warning_line
        try:  # Ctrl-C is the study's (it cancels and closes the cluster), not each worker's
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        except ValueError:  # not the worker process's main thread: leave it
            pass
        # what a case imports on first use, imported while the worker starts (the local
        # cluster's workers start while this process warms the blocks up)
        for module in WORKER_IMPORTS:
            importlib.import_module(module)


def cases_task(study, batch: list) -> list:
    """Solve a batch of cases, ``[(ref, key), ...]``, on a worker (its providers from the
    worker's plugin); returns their records in order."""
    providers = get_worker().plugins[PLUGIN].cache
    return [solve_ref(study, ref, key, providers) for ref, key in batch]


def rolling_task(study, batch: list) -> list:
    """Solve a batch of a rolling study's solves (each ``[(ref, key), ...]``, the cases one
    roll serves) on a worker; returns their records, flat, in order."""
    plugin = get_worker().plugins[PLUGIN]
    return [r for group in batch for r in solve_group(study, group, plugin.strips, plugin.cache)]


def local_cluster() -> LocalCluster:
    """A local cluster with no worker yet, whose worker processes never take Ctrl-C.

    A Ctrl-C at the terminal goes to every process of its group: workers starting then
    (importing Dask and the solver, or registering with the scheduler) each printed a
    traceback (98 lines for 2 workers) before this process's one line ``interrupted``.
    The cluster's event loop thread, which starts the worker processes, is made here with
    SIGINT blocked; threads and processes inherit the mask (through ``exec`` too), so the
    workers never take it and this process alone stops the run, closing the cluster. A
    Ctrl-C while the cluster is made (about a second) is held and raised at the end.
    Multiprocessing's resource tracker is started first: starting it unblocks SIGINT in
    the thread that starts it (the loop thread, for the first worker).
    """
    resource_tracker.ensure_running()
    before = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        cluster = LocalCluster(
            n_workers=0, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.CRITICAL
        )
    except BaseException:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)
        raise
    try:
        signal.pthread_sigmask(signal.SIG_SETMASK, before)  # raises a Ctrl-C held meanwhile
    except BaseException:
        cluster.close()
        raise
    return cluster


@contextlib.contextmanager
def dask_client(*, workers: int = 2, scheduler: str | None = None, timeout: float = 20.0) -> Iterator[Client]:
    """A client of the cluster at ``scheduler`` (reached within ``timeout`` s, else
    :class:`SchedulerError`), or of a new local cluster of ``workers`` single-threaded
    worker processes (closed on exit); its workers get the providers plugin. The local
    cluster's scheduler is up on return, its workers start in the background (about 1-3 s:
    a Python process each, Dask and the solver imported): tasks submitted before they are
    up wait for them."""
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=timeout)
        except (OSError, ValueError, TypeError) as exc:
            raise SchedulerError(f"--scheduler {scheduler!r} cannot be reached: {exc}") from None
        try:
            client.register_plugin(ProvidersPlugin(), name=PLUGIN)
            yield client
        finally:
            client.close()
        return
    import dask

    # the settings stay while the cluster lives: its nannies are made as its workers start
    with dask.config.set(LOCAL_CONFIG):
        cluster = local_cluster()
        try:
            # by address: a client of the cluster object would wait for its workers, and a
            # plugin registered with workers up waits for their setup (1.2-1.5 s each, measured)
            client = Client(cluster.scheduler_address)
            try:
                # workers get it as they start
                client.register_plugin(ProvidersPlugin(warning_lines=True), name=PLUGIN)
                cluster.scale(workers)
                yield client
            finally:
                client.close()
        except BaseException:  # Ctrl-C, SIGTERM, an error: stop now
            kill_starting_workers(cluster)
            raise
        finally:
            cluster.close()


def kill_starting_workers(cluster: LocalCluster) -> None:
    """Kill the local cluster's worker processes that have not joined its scheduler yet.

    Closing the cluster waits for a starting worker to be up before stopping it (its
    imports: 1-4 s, more on a loaded machine), and it holds nothing yet; the workers that
    joined are stopped by the cluster as usual (a case they solve is not written).
    """
    for _ in range(3):
        try:  # the scheduler runs in this process, on the cluster's loop thread
            joined = {ws.pid for ws in list(cluster.scheduler.workers.values())}
            break
        except RuntimeError:  # changed while read
            continue
    else:
        return
    for child in multiprocessing.active_children():
        if child.name.startswith("Dask Worker") and child.pid not in joined:
            child.kill()


def run_on_dask(
    client: Client, study, todo: list, labels: dict, on_record: Callable[[CaseRecord], None], *, batch: int = 1
) -> None:
    """Submit the ``(ref, key)`` of ``todo`` in tasks of ``batch`` consecutive cases (the
    client's workers have the providers plugin: :func:`dask_client`) and hand
    each record to ``on_record`` as its task returns (:func:`run_tasks`)."""

    def failed(item, reason):
        return [CaseRecord(item[1], labels[item[1]], "failed", reason, np.zeros(0, dtype=int), None, float("nan"))]

    run_tasks(client, study, todo, cases_task, on_record, failed, batch=batch)


def run_tasks(
    client: Client, payload, items: list, task: Callable, on_record: Callable, failed: Callable, *, batch: int = 1
) -> None:
    """Submit ``task(payload, items[i:i + batch])`` for every batch of ``items`` (``payload``,
    the study, is sent to each worker once) and hand each record the tasks return to
    ``on_record`` as they come. A task that dies with its worker gives ``failed(item, reason)``
    for each of its items. On any exception (Ctrl-C included) the remaining tasks are
    cancelled (a batch's records arrive when the whole batch is done)."""
    client.wait_for_workers(1, timeout=WORKER_WAIT)
    [shared] = client.scatter([payload], broadcast=True, hash=False)  # later workers fetch it
    batches = [items[i : i + batch] for i in range(0, len(items), batch)]
    run = uuid.uuid4().hex[:12]
    futures = {
        client.submit(task, shared, b, key=f"twoscale-{task.__name__}-{run}-{i}", pure=False): b
        for i, b in enumerate(batches)
    }
    try:
        for fut in as_completed(futures):
            try:
                records = fut.result()
            except Exception as exc:  # noqa: BLE001 - the worker died or the task could not run
                reason = f"{type(exc).__name__} on the cluster: {exc}"
                records = [r for item in futures[fut] for r in failed(item, reason)]
            for record in records:
                on_record(record)
    except BaseException:
        client.cancel(list(futures))
        raise
