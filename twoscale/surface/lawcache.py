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

from ..caches import LAWS, law_cache_dir
from ..io.cache_entry import CacheUsage, EntryFolder
from .laws import LawTable

#: Bumped when the tabulation changes what a key's table holds (2: entries with a checksum
#: and their key, :mod:`twoscale.io.cache_entry`).
FORMAT_VERSION = 2
#: Default bound on the cache directory, bytes.
MAX_BYTES = 256e6
#: Name of this cache (warnings, result.json, ``twoscale cache``).
NAME = LAWS


def default_law_cache_dir() -> Path:
    """``$TWOSCALE_CACHE_DIR/surface-laws``, else ``$XDG_CACHE_HOME/twoscale/surface-laws``,
    else ``~/.cache/twoscale/surface-laws`` (:func:`twoscale.caches.law_cache_dir`)."""
    return law_cache_dir()


def law_key(surface_digest: str, *, E_star: float, h: float, delta_max, levels: int, tol: float) -> str:
    """Hex digest of every input a law table depends on."""
    d = hashlib.sha256()
    d.update(f"v{FORMAT_VERSION}|{surface_digest}|E*={float(E_star)!r}|h={float(h)!r}|L={levels}|tol={tol!r}".encode())
    d.update(np.ascontiguousarray(delta_max, dtype=np.float64).tobytes())
    return d.hexdigest()


class LawCache:
    """Law tables on disk, at most ``max_bytes`` in ``directory``.

    Entries are written and checked by :class:`twoscale.io.cache_entry.EntryFolder`: a
    damaged one is dropped with one warning line and tabulated again; a folder that cannot
    be written leaves the laws in memory only, with one warning.

    Attributes
    ----------
    hits, misses : int
    nbytes : int
        Running total of the tables' file sizes, bytes.
    """

    def __init__(self, directory: str | os.PathLike | None = None, *, max_bytes: float = MAX_BYTES):
        self.directory = Path(directory) if directory is not None else default_law_cache_dir()
        self._dirname = os.fspath(self.directory)  # (``os.path``'s look-up: pathlib's costs 10x as much)
        self.max_bytes = float(max_bytes)
        self.hits = self.misses = 0
        self._files = None  # name -> size, read on first use
        self.nbytes = 0
        self._folder = EntryFolder(NAME, self.directory)

    def _index(self) -> dict:
        if self._files is None:
            files = []
            if self.directory.is_dir():
                for p in self.directory.glob("*.npz"):
                    try:
                        st = p.stat()
                    except OSError:  # removed meanwhile by another run
                        continue
                    files.append((st.st_mtime, p.name, st.st_size))
            self._files = {name: size for _, name, size in sorted(files)}
            self.nbytes = sum(self._files.values())
        return self._files

    def usage(self) -> CacheUsage:
        """What this cache read, wrote and dropped so far."""
        return self._folder.usage()

    def get(self, key: str) -> LawTable | None:
        """The table of ``key``, or None. Before a law is put, the folder is not listed: the
        entry's file is looked up by its name (the listing stats every entry, and a map's
        laws are looked up stone by stone when a solve starts: 100 entries 8 ms against
        a look-up each of 178 stones' 1 ms)."""
        name = f"{key}.npz"
        files = self._files
        table = None
        if (name in files) if files is not None else os.path.isfile(os.path.join(self._dirname, name)):
            data = self._folder.load(name)
            if data is not None:
                try:
                    if str(data["key"]) != key:
                        raise ValueError(f"it holds the key {str(data['key'])[:16]}...")
                    table = LawTable(
                        data["delta"], data["P"], float(data["E_star"]), float(data["h"]), bool(data["converged"])
                    )
                except (KeyError, ValueError, TypeError) as exc:  # whole, but not this key's law
                    self._folder.reject(name, f"not this law table: {exc}")
            if table is None and files is not None:  # gone, or dropped as damaged
                self.nbytes -= files.pop(name)
        if table is None:
            self.misses += 1
            return None
        self.hits += 1
        return table

    def put(self, key: str, table: LawTable) -> None:
        files = self._index()
        name = f"{key}.npz"
        size = self._folder.save(
            name,
            {
                "key": np.array(key),
                "delta": table.delta,
                "P": table.P,
                "E_star": table.E_star,
                "h": table.h,
                "converged": table.converged,
            },
        )
        if size is None:  # the folder cannot be written: the law stays in memory only
            return
        self.nbytes += size - files.pop(name, 0)
        files[name] = size
        for old in list(files):  # oldest first
            if self.nbytes <= self.max_bytes or old == name:
                break
            (self.directory / old).unlink(missing_ok=True)
            self.nbytes -= files.pop(old)
