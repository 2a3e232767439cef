"""A reader of stdout that stops early (``twoscale ... | head``) is not bad input.

Python ignores SIGPIPE, so a write to a pipe whose reader has gone raises BrokenPipeError,
an OSError, which the command line reported as ``error: [Errno 32] Broken pipe`` with exit
code 2 (bad input) although nothing was wrong with the input: seen with
``twoscale study examples/study.toml --out DIR | head -1`` on a finished study. It now
stops quietly with 141 (128 + SIGPIPE, as a tool killed by SIGPIPE), with nothing on
stderr and no failed flush at exit.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_a_closed_stdout_ends_the_command_quietly_with_141(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT), TWOSCALE_CACHE_DIR=str(tmp_path))
    proc = subprocess.Popen(
        [sys.executable, "-m", "twoscale", "cache", "list"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    proc.stdout.close()  # the reader is gone before the table is printed
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 141
    assert err == ""
