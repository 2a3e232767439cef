"""The ``twoscale`` script: holds Ctrl-C while the package imports, then runs the command line.

A console script names a function of a module, and importing ``twoscale.cli.main`` first
runs ``twoscale/__init__.py`` (numpy and the scene classes, 0.2-0.5 s on a loaded machine).
A Ctrl-C in that time would end the program with a ``KeyboardInterrupt`` traceback, or be
swallowed inside Python's import machinery ("Exception ignored in ...") and the command
would run on. This module sits outside the package so that nothing is imported before its
handler holds the interrupt; it answers as the command line does to a Ctrl-C: one line
``interrupted`` on stderr, exit code 130, nothing written. Only the interpreter's own
start-up (its ``site`` module, the first ~0.05 s) is left unguarded. ``python -m twoscale``
imports the package before any of its code runs; its command line holds a Ctrl-C from
there on (``twoscale.cli.main``).
"""

from __future__ import annotations

import signal
import sys

#: Exit code after Ctrl-C: 128 + SIGINT (``twoscale.cli.main.EXIT_INTERRUPTED``).
EXIT_INTERRUPTED = 130


def _import_command():
    """``twoscale.cli.main.main``, imported with SIGINT held; None if a Ctrl-C came meanwhile.
    A SIGINT that the caller ignores (a background job) stays ignored."""
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        from twoscale.cli.main import main

        return main
    caught: list[int] = []
    signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        from twoscale.cli.main import main
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    return None if caught else main


def main() -> int:
    """Run ``twoscale`` with ``sys.argv[1:]``; return the exit code."""
    try:
        command = _import_command()
        if command is not None:
            return command()
    except KeyboardInterrupt:  # between the import and the command's own handling
        pass
    print("interrupted", file=sys.stderr)
    return EXIT_INTERRUPTED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
