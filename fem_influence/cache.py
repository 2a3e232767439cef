"""On-disk cache of correction fields (npz, no pickle), keyed by every input.

One file per (mesh, nu, base, source lattice spacing, quadrature, format
version); it holds the top-face node positions and the correction fields of the
source-lattice nodes solved so far. New nodes are merged and the file is
rewritten through :mod:`twoscale.io.cache_entry` (atomically, with a checksum): a
reader never sees a partial file, a damaged one is dropped with one warning and
its fields solved again, and a folder that cannot be written leaves the fields in
memory with one warning. Two processes solving the same block at once each write
the fields they hold; the last rename's file stays, whole.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from twoscale.caches import BLOCK, ENV_VAR, block_cache_dir
from twoscale.io.cache_entry import CacheUsage, EntryFolder

#: Bump when the stored quantity or its meaning changes (2: entries with a checksum).
FORMAT_VERSION = 2
#: Name of this cache (warnings, result.json, ``twoscale cache``).
NAME = BLOCK

__all__ = ["ENV_VAR", "FORMAT_VERSION", "FieldCache", "cache_key", "default_cache_dir"]


def default_cache_dir() -> Path:
    """``$TWOSCALE_CACHE_DIR``, else ``$XDG_CACHE_HOME/twoscale/fem``, else ``~/.cache/twoscale/fem``
    (:func:`twoscale.caches.block_cache_dir`)."""
    return block_cache_dir()


def cache_key(mesh, *, nu: float, base: str, spacing: float, intorder: int) -> str:
    """Hex digest of every input the stored fields depend on (E enters as 1/E outside)."""
    h = hashlib.sha256()
    h.update(f"v{FORMAT_VERSION}|nu={float(nu)!r}|base={base}|d={float(spacing)!r}|q={intorder}".encode())
    h.update(np.ascontiguousarray(mesh.p, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(mesh.t, dtype=np.int64).tobytes())
    return h.hexdigest()


class FieldCache:
    """Correction fields of source-lattice nodes, in memory and (optionally) on disk.

    Parameters
    ----------
    key : str
        From :func:`cache_key`.
    directory : Path or None
        Where the npz lives; None keeps the cache in memory only.
    """

    def __init__(self, key: str, directory: Path | None):
        self.key = key
        self.path = None if directory is None else Path(directory) / f"block-{key[:32]}.npz"
        self.fields: dict[tuple[int, int], np.ndarray] = {}
        self.top_xy: np.ndarray | None = None
        self.loaded_from_disk = False
        self._folder = None if directory is None else EntryFolder(NAME, directory)

    def usage(self) -> tuple[CacheUsage, ...]:
        """What the disk cache gave and took (empty when kept in memory only)."""
        return () if self._folder is None else (self._folder.usage(),)

    def load(self) -> None:
        """Read the file if it exists, is whole and carries the same key."""
        if self._folder is None:
            return
        data = self._folder.load(self.path.name)
        if data is None:
            return
        try:
            if str(data["key"]) != self.key:
                raise ValueError("another key")
            top_xy, nodes, fields = data["top_xy"], data["nodes"], data["fields"]
            if len(nodes) != len(fields) or nodes.ndim != 2 or nodes.shape[1] != 2:
                raise ValueError(f"{len(nodes)} nodes for {len(fields)} fields")
        except (KeyError, ValueError) as exc:
            self._folder.reject(self.path.name, f"not this block's fields: {exc}")
            return
        self.top_xy = top_xy
        for ij, f in zip(nodes, fields):
            self.fields[(int(ij[0]), int(ij[1]))] = f
        self.loaded_from_disk = True

    def add(self, nodes, fields: np.ndarray, top_xy: np.ndarray) -> None:
        """Store fields (one row per node) and persist them."""
        self.top_xy = top_xy
        for ij, f in zip(nodes, fields):
            self.fields[(int(ij[0]), int(ij[1]))] = np.asarray(f)
        if self._folder is None:
            return
        keys = sorted(self.fields)
        self._folder.save(
            self.path.name,
            {
                "key": np.array(self.key),
                "top_xy": self.top_xy,
                "nodes": np.array(keys, dtype=np.int64).reshape(-1, 2),
                "fields": np.array([self.fields[k] for k in keys]),
            },
        )
