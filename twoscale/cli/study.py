"""Run a parameter study: scenes x bodies x loads x positions, on Dask, resumable.

``twoscale study STUDY.toml --out DIR [--workers N] [--scheduler ADDRESS] [--batch B] [--quiet]``

The study file (TOML) lists scene files, bodies, loads (or penetrations), positions (a list
of shifts or a straight track) and solver options; see :mod:`twoscale.studies.spec`. A study
file with a ``[rolling]`` table rolls road sections under bodies instead (sections x bodies x
materials x loads x speeds, each case a rolling run's files; :mod:`twoscale.studies.rolling_spec`),
and writes ``cases.csv`` and ``bands.csv`` across its cases. Each
case is solved as a task on ``dask.distributed``: a local cluster of N worker processes
(``--workers``, default the number of CPUs; 0 solves in this process, one case after the
other), or an existing cluster (``--scheduler tcp://host:8786``); ``--batch B`` puts B
consecutive cases in one task (default 1). Each finished case is
written at once to ``DIR/cases/<key>/`` (atomically, under a hash of its inputs), so
rerunning the same command skips the finished cases and solves the rest (and the failed
ones again); Ctrl-C leaves the finished cases in place (exit code 130).

When the cases are done: ``DIR/cases.csv``, ``asperities.csv``, ``indicators.csv`` (each
with its ``.csv-metadata.json`` and ``.parquet``), ``summary.json`` and
``DIR/figures/*.png``, covering every finished case; the terminal shows the headline numbers
per scene, body and load (:mod:`twoscale.studies.report`) and where the files are. The
cell size is one per scene and body across the loads (:mod:`twoscale.studies.cases`).

Needs the ``study`` extra (``pip install ".[study]"`` in the repository: dask.distributed, pyarrow).

One run at a time works in DIR: a second one started while the first is alive is refused
with one line naming the first (its pid and host) and exit code 3. The lock
(``DIR/.twoscale-study.lock``, :mod:`twoscale.studies.lock`) is the kernel's, freed when
its process ends in any way, so a run killed with SIGKILL never blocks the next; rerunning
the same command then resumes (finished cases are kept, a half-written case folder is
removed, the tables cover every case).

Exit codes: 0 every case converged; 1 some case did not converge or failed (each is
recorded with its reason, the others still run); 2 bad input (one ``error: ...`` line,
nothing run or written), a missing dependency, or a ``--scheduler`` that cannot be reached
within 20 s; 3 DIR is in use by another live run; 130 interrupted (Ctrl-C); 143 terminated
(SIGTERM, as batch schedulers send before killing a job): one line, the finished cases
kept, nothing half-written, the same command resumes.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import shutil
import sys
from pathlib import Path

#: What ``twoscale study`` needs beyond the core, as (module, pip name).
NEEDS = (("distributed", "dask[distributed]"), ("pyarrow", "pyarrow"))
#: Exit code when another live run holds the output folder (``DIR/.twoscale-study.lock``).
EXIT_BUSY = 3
#: Failed or non-converged cases listed on stderr before the list is cut short.
MAX_LISTED = 10


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``twoscale study``."""
    parser.add_argument("study", metavar="STUDY.toml", help="study file (TOML; units mm, N, MPa)")
    parser.add_argument("--out", metavar="DIR", required=True, help="output folder (created; a rerun resumes in it)")
    parser.add_argument(
        "--workers",
        metavar="N",
        default=None,
        help="worker processes of the local Dask cluster (default: the number of CPUs, "
        f"here {os.cpu_count()}); 0 solves in this process without Dask",
    )
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="address of an existing Dask scheduler (e.g. tcp://host:8786) instead of a local cluster",
    )
    parser.add_argument(
        "--batch",
        metavar="B",
        default="1",
        help="cases per Dask task (default 1; more for large clusters: fewer, longer "
        "tasks; a batch's cases are written when the whole batch is done)",
    )
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace another study's tables and figures in DIR (its finished cases are kept "
        "and reused where the inputs match); a folder of this study resumes without it",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")


def missing_dependencies() -> list[str]:
    """pip names of the study's dependencies that are not installed."""
    return [pip for module, pip in NEEDS if importlib.util.find_spec(module) is None]


def _count(text: str | None, option: str, *, least: int, default: int) -> int:
    """An integer option >= ``least`` (``default`` when not given); ValueError naming it."""
    if text is None:
        return default
    try:
        n = int(text)
    except ValueError:
        n = least - 1
    if n < least:
        raise ValueError(f"{option} must be an integer >= {least}, got {text!r}")
    return n


def run(args: argparse.Namespace) -> int:
    """Run ``twoscale study``; returns the exit code (see the module doc)."""
    missing = missing_dependencies()
    if missing:
        print(
            f'error: twoscale study needs {" and ".join(missing)}: pip install ".[study]" in the repository '
            f"(or pip install {' '.join(repr(m) if '[' in m else m for m in missing)})",
            file=sys.stderr,
        )
        return 2
    from ..studies.folder import check_study_folder
    from ..studies.lock import StudyBusy, study_lock
    from ..studies.spec import read_study

    out = Path(args.out)
    try:
        workers = _count(args.workers, "--workers", least=0, default=os.cpu_count() or 1)
        batch = _count(args.batch, "--batch", least=1, default=1)
        study = read_study(args.study)
        if out.exists() and not out.is_dir():
            raise ValueError(f"--out {str(out)!r} exists and is not a folder")
    except ValueError as exc:  # StudyError and SceneError included
        print(f"error: {exc}", file=sys.stderr)
        return 2
    created = not out.exists()
    try:
        with study_lock(out):  # one run per folder; the kernel frees it when the run dies
            try:
                digest = check_study_folder(out, study, overwrite=args.overwrite)
            except ValueError:
                if created:  # nothing has run: leave no folder behind
                    shutil.rmtree(out, ignore_errors=True)
                raise
            return _run_locked(args, study, out, digest, created, workers, batch)
    except StudyBusy as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_BUSY
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


def _run_locked(args, study, out: Path, digest: str, created: bool, workers: int, batch: int) -> int:
    """The study's run in its locked folder: solve the unfinished cases, write the tables."""
    from ..studies.dask_backend import SchedulerError
    from ..studies.execute import run_study
    from ..studies.folder import mark_study_folder
    from ..studies.outputs import write_outputs
    from ..studies.rolling_run import run_rolling_study
    from ..studies.rolling_spec import RollingStudy
    from ..studies.rolling_tables import write_rolling_outputs

    rolling = isinstance(study, RollingStudy)
    if rolling:  # road sections x bodies x materials x loads x speeds
        run_study, write_outputs = run_rolling_study, write_rolling_outputs
    mark_study_folder(out, study, digest)
    try:
        run_info = run_study(study, out, workers=workers, scheduler=args.scheduler, batch=batch, quiet=args.quiet)
    except SchedulerError as exc:  # the scheduler's address: nothing has run
        if created:  # nothing has run: leave no folder behind
            shutil.rmtree(out, ignore_errors=True)
        print(f"error: {exc}", file=sys.stderr)
        return 2
    summary = write_outputs(out, study, run_info)
    return _report(summary, run_info, out, quiet=args.quiet, rolling=rolling)


def _report(summary: dict, run_info, out: Path, *, quiet: bool, rolling: bool = False) -> int:
    c = summary["counts"]
    for what, key in (("failed", "failed"), ("did not converge", "not_converged")):
        for item in summary[key][:MAX_LISTED]:
            print(f"warning: {item['case']} {what}: {item['reason']}", file=sys.stderr)
        if len(summary[key]) > MAX_LISTED:
            print(
                f"warning: ... and {len(summary[key]) - MAX_LISTED} more (see {out / 'summary.json'})", file=sys.stderr
            )
    if not quiet:
        from ..studies.report import study_table
        from ..studies.rolling_tables import rolling_table

        print(
            f"{summary['cases']} cases: {c['converged']} converged, {c['not-converged']} not converged, "
            f"{c['failed']} failed; this run solved {run_info.ran} ({run_info.where}, "
            f"{run_info.seconds:.1f} s) and skipped {run_info.skipped} finished"
        )
        print(rolling_table(out) if rolling else study_table(out))
    return 0 if c["converged"] == summary["cases"] else 1
