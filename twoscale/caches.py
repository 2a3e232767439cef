"""The program's on-disk caches: where each lives, and what it holds (for ``twoscale cache``).

Two caches keep work between runs, each in its own folder of ``.npz`` entries
(:mod:`twoscale.io.cache_entry`):

* ``block-corrections``: the finite block's FEM correction fields, one file per mesh,
  nu and base (``block-*.npz``), in ``$TWOSCALE_CACHE_DIR``, else
  ``$XDG_CACHE_HOME/twoscale/fem``, else ``~/.cache/twoscale/fem``;
* ``surface-laws``: the tabulated law of each asperity of a height map, one file per
  asperity, in ``$TWOSCALE_CACHE_DIR/surface-laws``, else ``.../twoscale/surface-laws``.

Removing either folder is always safe: the entries are computed again when needed (a
block's first solve then takes the FEM solves' time again).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

#: Environment variable overriding the cache root.
ENV_VAR = "TWOSCALE_CACHE_DIR"
#: The caches' names (in warnings, result.json and ``twoscale cache``).
BLOCK = "block-corrections"
LAWS = "surface-laws"


def _user_root() -> Path:
    root = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(root) / "twoscale"


def block_cache_dir() -> Path:
    """``$TWOSCALE_CACHE_DIR``, else ``$XDG_CACHE_HOME/twoscale/fem``, else ``~/.cache/twoscale/fem``."""
    if os.environ.get(ENV_VAR):
        return Path(os.environ[ENV_VAR])
    return _user_root() / "fem"


def law_cache_dir() -> Path:
    """``$TWOSCALE_CACHE_DIR/surface-laws``, else ``$XDG_CACHE_HOME/twoscale/surface-laws``,
    else ``~/.cache/twoscale/surface-laws``."""
    if os.environ.get(ENV_VAR):
        return Path(os.environ[ENV_VAR]) / "surface-laws"
    return _user_root() / "surface-laws"


@dataclass(frozen=True)
class CacheFolder:
    """One cache as found on disk.

    Attributes
    ----------
    name : str
    description : str
    folder : Path
    pattern : str
        Glob of its entries in ``folder`` (other files there are not its own).
    """

    name: str
    description: str
    folder: Path
    pattern: str

    def entries(self) -> list[Path]:
        """Its entry files (and the temporary files of interrupted writes), sorted."""
        if not self.folder.is_dir():
            return []
        own = set(self.folder.glob(self.pattern)) | set(self.folder.glob(f".{self.pattern}.*.tmp"))
        return sorted(p for p in own if p.is_file())

    def size(self) -> int:
        """Bytes of its entries."""
        total = 0
        for p in self.entries():
            try:
                total += p.stat().st_size
            except OSError:  # removed meanwhile by another run
                pass
        return total

    def clear(self) -> tuple[int, int]:
        """Delete its entries; returns (files removed, bytes freed). Other files stay."""
        n = freed = 0
        for p in self.entries():
            try:
                size = p.stat().st_size
                p.unlink()
            except FileNotFoundError:
                continue
            n, freed = n + 1, freed + size
        return n, freed


def caches() -> tuple[CacheFolder, ...]:
    """Every cache of the program, at its folder for the current environment."""
    return (
        CacheFolder(
            BLOCK, "finite block: FEM correction fields per mesh, nu and base", block_cache_dir(), "block-*.npz"
        ),
        CacheFolder(LAWS, "height maps: tabulated law of each asperity", law_cache_dir(), "*.npz"),
    )
