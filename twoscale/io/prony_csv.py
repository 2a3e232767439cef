"""Prony branches from a CSV file: two columns ``E_k`` (MPa) and ``tau_k`` (s), one branch
a row, an optional header line, ``#`` comments allowed (what a DMA fit exports)."""

from __future__ import annotations

import csv
import os

from ..scene import SceneError


def read_prony_csv(path, *, base_dir: str | None = None) -> tuple:
    """The branches of ``path`` (relative to ``base_dir``) as ``((E_k, tau_k), ...)``.

    Raises
    ------
    SceneError
        Naming the file, the line and the bad value.
    """
    if not isinstance(path, str):
        raise SceneError(f"material.prony_file must be a file name, got {path!r}")
    full = path if os.path.isabs(path) or base_dir is None else os.path.join(base_dir, path)
    try:
        with open(full, newline="") as fh:
            rows = list(csv.reader(line for line in fh if line.strip() and not line.lstrip().startswith("#")))
    except OSError as exc:
        raise SceneError(f"material.prony_file {path!r}: cannot read it ({exc.strerror})") from None
    out = []
    for n, row in enumerate(rows, start=1):
        cells = [c.strip() for c in row if c.strip()]
        try:
            values = [float(c) for c in cells]
        except ValueError:
            if n == 1 and not out:  # a header line
                continue
            raise SceneError(
                f"material.prony_file {path!r}, row {n}: not two numbers E_k, tau_k, got {row!r}"
            ) from None
        if len(values) != 2:
            raise SceneError(f"material.prony_file {path!r}, row {n}: need two numbers E_k, tau_k, got {row!r}")
        out.append(tuple(values))
    if not out:
        raise SceneError(f"material.prony_file {path!r} holds no branch (rows E_k, tau_k)")
    return tuple(out)
