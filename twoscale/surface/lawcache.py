"""On-disk cache of tabulated asperity laws, keyed by the surface, the body and the cell size.

Tabulating the laws of a road's asperities costs thousands of small contact solves; the
same surface on the same body at the same cell size gives the same laws, so each
asperity's table is kept in a directory as one small ``.npz`` file, named by its key
(:func:`law_key` and the asperity's index). The cache is an object its caller owns
(the command line makes one per run; the library makes none by itself), with a bound on
the directory's size kept by a running total: the oldest tables go first.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

from .laws import LawTable

#: Bumped when the tabulation changes what a key's table holds.
FORMAT_VERSION = 1
#: Default bound on the cache directory, bytes.
MAX_BYTES = 256e6
ENV_VAR = "TWOSCALE_CACHE_DIR"


def default_law_cache_dir() -> Path:
    """``$TWOSCALE_CACHE_DIR/surface-laws``, else ``$XDG_CACHE_HOME/twoscale/surface-laws``,
    else ``~/.cache/twoscale/surface-laws``."""
    if os.environ.get(ENV_VAR):
        return Path(os.environ[ENV_VAR]) / "surface-laws"
    root = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(root) / "twoscale" / "surface-laws"


def law_key(surface_digest: str, *, E_star: float, h: float, delta_max, levels: int, tol: float) -> str:
    """Hex digest of every input a law table depends on."""
    d = hashlib.sha256()
    d.update(f"v{FORMAT_VERSION}|{surface_digest}|E*={float(E_star)!r}|h={float(h)!r}|L={levels}|tol={tol!r}".encode())
    d.update(np.ascontiguousarray(delta_max, dtype=np.float64).tobytes())
    return d.hexdigest()


class LawCache:
    """Law tables on disk, at most ``max_bytes`` in ``directory``.

    Attributes
    ----------
    hits, misses : int
    nbytes : int
        Running total of the tables' file sizes, bytes.
    """

    def __init__(self, directory: str | os.PathLike | None = None, *, max_bytes: float = MAX_BYTES):
        self.directory = Path(directory) if directory is not None else default_law_cache_dir()
        self.max_bytes = float(max_bytes)
        self.hits = self.misses = 0
        self._files = None   # name -> size, read on first use
        self.nbytes = 0

    def _index(self) -> dict:
        if self._files is None:
            files = sorted(self.directory.glob("*.npz"), key=lambda p: p.stat().st_mtime) \
                if self.directory.is_dir() else []
            self._files = {p.name: p.stat().st_size for p in files}
            self.nbytes = sum(self._files.values())
        return self._files

    def get(self, key: str) -> LawTable | None:
        path = self.directory / f"{key}.npz"
        if f"{key}.npz" not in self._index() or not path.is_file():
            self.misses += 1
            return None
        try:
            with np.load(path, allow_pickle=False) as data:
                table = LawTable(data["delta"], data["P"], float(data["E_star"]), float(data["h"]),
                                 bool(data["converged"]))
        except (OSError, ValueError, KeyError):   # a damaged entry is a miss
            self.misses += 1
            return None
        self.hits += 1
        return table

    def put(self, key: str, table: LawTable) -> None:
        files = self._index()
        self.directory.mkdir(parents=True, exist_ok=True)
        path = self.directory / f"{key}.npz"
        tmp = self.directory / f".{key}.tmp.npz"
        np.savez(tmp, delta=table.delta, P=table.P, E_star=table.E_star, h=table.h, converged=table.converged)
        os.replace(tmp, path)
        size = path.stat().st_size
        self.nbytes += size - files.pop(path.name, 0)
        files[path.name] = size
        for name in list(files):   # oldest first
            if self.nbytes <= self.max_bytes or name == path.name:
                break
            (self.directory / name).unlink(missing_ok=True)
            self.nbytes -= files.pop(name)
