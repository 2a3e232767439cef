"""Entry point of the ``twoscale`` command.

Each subcommand is a module of this package exposing ``add_arguments(parser)`` and
``run(args) -> int``. ``solve`` is always present; optional subcommands (``paper``,
``compare``, ``indicators``) are registered when their module exists. The commands that
write an output folder get ``--overwrite`` here (see :mod:`twoscale.cli.staging`).

Exit codes: 0 success; 1 the solve ran but did not converge (result written with
``converged = false``); 2 bad input, or an output that cannot be written (one ``error: ...``
line on stderr, nothing written);
130 interrupted by Ctrl-C (one line ``interrupted`` on stderr; the subcommands write
through a temporary folder renamed at the end, so no partial output is left); 143
terminated by SIGTERM (what batch schedulers and ``kill`` send): handled like Ctrl-C, with
the line ``terminated`` (a second SIGTERM during the clean-up is ignored); 141 the reader of
stdout stopped reading (``twoscale ... | head``): nothing more is printed, no error line, as
a tool killed by SIGPIPE.

Every command runs BLAS and OpenMP single-threaded unless the environment sets a thread
count (:mod:`twoscale.threads`).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import io
import os
import signal
import re
import sys
import threading
import warnings
from typing import Sequence

from .._version import __version__
from .staging import OutputFolderError, Terminated, held_interrupts
from ..threads import single_threads

#: Exit code after Ctrl-C (KeyboardInterrupt): 128 + SIGINT, as shells report it.
EXIT_INTERRUPTED = 130
#: Exit code after SIGTERM: 128 + SIGTERM, as shells report it.
EXIT_TERMINATED = 143
#: Exit code when stdout's reader has gone: 128 + SIGPIPE, as shells report a tool it killed.
EXIT_BROKEN_PIPE = 141


def _on_sigterm(signum, frame) -> None:
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # let the clean-up finish
    raise Terminated()


#: Subcommands: (name, module, required, summary). Optional ones appear when their module
#: exists. The summary is the module docstring's first line (a test keeps them equal): the
#: top-level ``--help`` lists every command without importing one (``solve`` alone pulls in
#: scipy), and a command imports only its own module.
SUBCOMMANDS = (
    (
        "solve",
        "twoscale.cli.solve",
        True,
        "Solve a scene file; print a summary and write DIR/result.json (+ asperities.csv, fields.vtm, figures).",
    ),
    (
        "paper",
        "twoscale.cli.paper",
        False,
        "Reproduce the paper's numerical study (figs. 3-6): CSV files and PNG figures.",
    ),
    (
        "compare",
        "twoscale.cli.compare",
        False,
        "Compare bodies: solve a scene on the half-space and the finite block, and show what changes.",
    ),
    (
        "indicators",
        "twoscale.cli.indicators",
        False,
        "e_M and e_m between two stored solves (twoscale indicators RUN_DIR REF_DIR).",
    ),
    (
        "study",
        "twoscale.cli.study",
        False,
        "Run a parameter study: scenes x bodies x loads x positions, on Dask, resumable.",
    ),
    (
        "surface",
        "twoscale.cli.surface",
        False,
        "Segment the height map of a scene's [surface] and tabulate its asperity laws, without solving.",
    ),
    (
        "cache",
        "twoscale.cli.cache",
        False,
        "List or clear the on-disk caches (block corrections, surface laws): what, where, how large.",
    ),
)


#: Subcommands that write an output folder: they take ``--overwrite`` (see ``cli.staging``).
OUTPUT_COMMANDS = ("solve", "compare", "paper", "surface")


def _available_subcommands():
    """(name, module name, summary) of each subcommand whose module exists (found, not imported)."""
    for name, module, required, summary in SUBCOMMANDS:
        if required or importlib.util.find_spec(module) is not None:
            yield name, module, summary


def command_in(argv: Sequence[str]) -> str | None:
    """The subcommand ``argv`` names: its first word that is not an option (the top level
    takes only ``--help`` and ``--version``, which take no value); None when there is none."""
    return next((word for word in argv if not word.startswith("-")), None)


class _OneLineParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one ``error: ...`` line (exit 2), like
    every other bad input, instead of argparse's usage block."""

    def error(self, message: str):
        print(f"error: {self.prog}: {message}", file=sys.stderr)
        raise SystemExit(2)


def plain(text: str) -> str:
    """Docstring text as a terminal shows it: reStructuredText roles and literals
    (``:func:`name```, double backquotes) reduced to their words."""
    text = re.sub(r":[a-z]+:`~?([^`]+)`", r"\1", text)
    return text.replace("``", "").replace("`", "")


def build_parser(command: str | None = "*") -> argparse.ArgumentParser:
    """The argument parser: every available subcommand is listed; the options of ``command``
    only (``"*"``, the default: of every subcommand; None: of none), so that a run imports
    the module of the command it runs and no other."""
    parser = _OneLineParser(
        prog="twoscale", description="Two-scale multi-asperity contact on elastic bodies (units mm, N, MPa)."
    )
    parser.add_argument("--version", action="version", version=f"twoscale {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_OneLineParser)
    sub.required = True
    for name, module_name, summary in _available_subcommands():
        p = sub.add_parser(name, help=summary, description=summary)
        if command in ("*", name):
            _add_command(p, name, importlib.import_module(module_name))  # a failing import is a bug: raise
    return parser


def _add_command(p: argparse.ArgumentParser, name: str, module) -> None:
    """A subcommand's options (its module's ``add_arguments``, and ``--overwrite`` for those
    that write an output folder) and its ``run``."""
    module.add_arguments(p)
    if name in OUTPUT_COMMANDS:
        p.add_argument(
            "--overwrite",
            action="store_true",
            help="replace an earlier twoscale output in the folder: removes only the files "
            "listed in its .twoscale-manifest.json (a folder holding other files is refused)",
        )
    p.set_defaults(_run=module.run)


def _warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """A library warning (e.g. a coarse cell size) as one ``warning:`` line on stderr."""
    print(f"warning: {message}", file=sys.stderr)


def _silence_stdout() -> None:
    """Point stdout at the null device, so that the interpreter's last flush of what is still
    buffered for the gone reader does not fail again at exit."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError, io.UnsupportedOperation):
        pass  # stdout is not a file (a test's capture): nothing is flushed to a pipe at exit


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); return the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        # imports the command's module (solve's: ~0.6 s); a Ctrl-C meanwhile is held until
        # the import ends: raised inside the import machinery it could be swallowed
        with held_interrupts():
            parser = build_parser(command_in(argv))
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse reports usage errors (code 2) and --help (code 0) this way
        return exc.code if isinstance(exc.code, int) else 2
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _on_sigterm) if main_thread else None
    try:
        with warnings.catch_warnings(), single_threads():
            warnings.showwarning = _warning_line
            return int(args._run(args))
    except Terminated:  # like Ctrl-C: outputs are staged, finished study cases kept
        print("terminated", file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:  # Ctrl-C: outputs are staged, so nothing half-written remains
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # `| head` stopped reading: not bad input, and no error line
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    except (OSError, OutputFolderError) as exc:  # a full disk, no write permission, an output folder
        # changed during the solve: one line, not a traceback
        print(f"error: {exc}", file=sys.stderr)
        return 2
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
