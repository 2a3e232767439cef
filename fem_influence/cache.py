"""On-disk cache of correction fields (npz, no pickle), keyed by every input.

One file per (mesh, nu, base, source lattice spacing, quadrature, format
version); it holds the top-face node positions and the correction fields of the
source-lattice nodes solved so far. New nodes are merged and the file is
rewritten atomically (temporary file + ``os.replace``), so concurrent readers
never see a partial file.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

#: Bump when the stored quantity or its meaning changes.
FORMAT_VERSION = 1
#: Environment variable overriding the cache directory.
ENV_VAR = "TWOSCALE_CACHE_DIR"


def default_cache_dir() -> Path:
    """``$TWOSCALE_CACHE_DIR``, else ``$XDG_CACHE_HOME/twoscale/fem``, else ``~/.cache/twoscale/fem``."""
    if os.environ.get(ENV_VAR):
        return Path(os.environ[ENV_VAR])
    root = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(root) / "twoscale" / "fem"


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

    def load(self) -> None:
        """Read the file if it exists and carries the same key."""
        if self.path is None or not self.path.exists():
            return
        with np.load(self.path, allow_pickle=False) as d:
            if str(d["key"]) != self.key:
                return
            self.top_xy = d["top_xy"]
            for ij, f in zip(d["nodes"], d["fields"]):
                self.fields[(int(ij[0]), int(ij[1]))] = f
        self.loaded_from_disk = True

    def add(self, nodes, fields: np.ndarray, top_xy: np.ndarray) -> None:
        """Store fields (one row per node) and persist them."""
        self.top_xy = top_xy
        for ij, f in zip(nodes, fields):
            self.fields[(int(ij[0]), int(ij[1]))] = np.asarray(f)
        if self.path is None:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        keys = sorted(self.fields)
        tmp = self.path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(tmp, key=np.array(self.key), top_xy=self.top_xy,
                 nodes=np.array(keys, dtype=np.int64).reshape(-1, 2),
                 fields=np.array([self.fields[k] for k in keys]))
        os.replace(tmp, self.path)
