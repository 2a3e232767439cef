"""Cache entries on disk: one ``.npz`` file per entry, written atomically, with a checksum.

Every on-disk cache of the program (the finite block's correction fields, the surface's
asperity laws) keeps its entries through this module, so a damaged entry is found and
handled the same way everywhere:

* :func:`write_entry` writes the arrays and the SHA-256 of their names, dtypes, shapes
  and bytes (``_sha256``) into a temporary file beside the entry, renamed over it at the
  end: a reader sees the old entry or the new one, never half of one, and two processes
  writing the same entry at once both succeed and leave one whole entry (the last
  rename's).
* :func:`read_entry` checks the checksum; a file that is empty, truncated, not an npz,
  or whose arrays do not match their checksum raises :class:`BadEntry` with the reason.
* :class:`EntryFolder` is a cache's folder as its owner sees it: a bad entry is deleted,
  counted, and named in one ``CacheWarning`` line (``load`` then answers "absent", so the
  owner computes it again and stores it anew); a folder that cannot be written (read-only,
  full, a file in its place) gives one warning and the solve goes on without storing
  (entries already there are still read). :meth:`EntryFolder.usage` says what came from
  the cache, for ``result.json``.

The files stay plain ``.npz`` (``numpy.load`` reads them; no pickle).
"""

from __future__ import annotations

import hashlib
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import BadEntry, CacheWarning
from .atomic import atomic_output

__all__ = ["BadEntry", "CacheUsage", "CacheWarning", "EntryFolder", "read_entry", "write_entry"]

#: Name of the checksum array inside an entry.
CHECKSUM = "_sha256"
#: The first bytes of every npz (a zip archive).
ZIP_MAGIC = b"PK\x03\x04"
#: Bad entries named one line each per folder object; the others are counted in its usage.
MAX_WARNED = 5


def _checksum(arrays: dict) -> str:
    d = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        d.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        d.update(a.tobytes())
    return d.hexdigest()


def write_entry(path: str | os.PathLike, arrays: dict) -> int:
    """Write ``arrays`` (name -> array) as the entry ``path`` atomically, with their
    checksum; returns the file's size in bytes. Raises OSError when it cannot be written
    (nothing is left behind then)."""
    arrays = {k: np.asarray(v) for k, v in arrays.items()}
    if CHECKSUM in arrays:
        raise ValueError(f"{CHECKSUM!r} is reserved for the checksum")
    with atomic_output(path) as tmp, open(tmp, "wb") as f:
        np.savez(f, **arrays, **{CHECKSUM: np.array(_checksum(arrays))})
    return Path(path).stat().st_size


def read_entry(path: str | os.PathLike) -> dict:
    """The arrays of the entry ``path``, checked against their checksum.

    Raises
    ------
    FileNotFoundError
        No entry there.
    BadEntry
        The file is empty, truncated, not an npz, lacks its checksum or does not match it.
    """
    path = Path(path)
    try:
        if path.stat().st_size == 0:
            raise BadEntry("empty file")
        with open(path, "rb") as fh:  # closed on any error
            if fh.read(len(ZIP_MAGIC)) != ZIP_MAGIC:  # numpy would try it as a pickle and say so
                raise BadEntry("not an npz file (no zip header)")
            fh.seek(0)
            with np.load(fh, allow_pickle=False) as data:
                arrays = {name: data[name] for name in data.files}
    except (FileNotFoundError, BadEntry):
        raise
    except Exception as exc:  # noqa: BLE001 - numpy and zipfile raise many kinds for a damaged file
        raise BadEntry(f"unreadable: {type(exc).__name__}: {exc}") from None
    stored = arrays.pop(CHECKSUM, None)
    if stored is None:
        raise BadEntry("no checksum (written by another program or version)")
    if str(stored) != _checksum(arrays):
        raise BadEntry("checksum mismatch")
    return arrays


@dataclass(frozen=True)
class CacheUsage:
    """What one cache gave and took during a solve (or a run).

    Attributes
    ----------
    name : str
        The cache ("block-corrections", "surface-laws").
    folder : str
        Its folder ("" for a cache kept in memory only).
    read : int
        Entries read from disk (work not done again).
    saves : tuple of str
        The file name of every entry stored, in order, once per store: an entry that
        grows (a block's corrections, stored again as each batch of fields is added)
        appears once per store.
    dropped : tuple of str
        File names of damaged entries deleted (and computed again).
    disabled : str
        Why new entries were not stored ("" when they were).
    """

    name: str
    folder: str
    read: int = 0
    saves: tuple = ()
    dropped: tuple = ()
    disabled: str = ""

    @property
    def written(self) -> int:
        """Entries written: the files stored, each counted once however often it was stored."""
        return len(set(self.saves))

    def since(self, before: CacheUsage) -> CacheUsage:
        """The usage between ``before`` (an earlier snapshot of the same cache) and this one."""
        return CacheUsage(
            self.name,
            self.folder,
            self.read - before.read,
            self.saves[len(before.saves) :],
            self.dropped[len(before.dropped) :],
            self.disabled,
        )

    def as_dict(self) -> dict:
        return {
            "name": self.name,
            "folder": self.folder,
            "read": self.read,
            "written": self.written,
            "dropped": list(self.dropped),
            "disabled": self.disabled,
        }


class EntryFolder:
    """The folder of one cache: reads that survive damaged entries, writes that survive an
    unwritable folder, and counters of both (see the module docstring).

    Parameters
    ----------
    name : str
        The cache's name, in warnings and :meth:`usage`.
    directory : path
        The folder (created on the first write).
    """

    def __init__(self, name: str, directory: str | os.PathLike):
        self.name = name
        self.directory = Path(directory)
        self.read = 0
        self.saves: list[str] = []
        self.dropped: list[str] = []
        self.disabled = ""

    def path(self, filename: str) -> Path:
        return self.directory / filename

    def load(self, filename: str) -> dict | None:
        """The entry's arrays, or None when it is absent or was damaged (then deleted and
        named in a warning: the caller computes it again)."""
        path = self.path(filename)
        try:
            arrays = read_entry(path)
        except (FileNotFoundError, NotADirectoryError):
            return None
        except PermissionError as exc:
            self._drop(path, f"unreadable: {exc.strerror}")
            return None
        except BadEntry as exc:
            self._drop(path, str(exc))
            return None
        self.read += 1
        return arrays

    def reject(self, filename: str, reason: str) -> None:
        """Drop an entry that read well but does not hold what its name promises (e.g. a
        key that differs: a file copied under another name)."""
        self._drop(self.path(filename), reason)
        self.read -= 1

    def _drop(self, path: Path, reason: str) -> None:
        try:
            path.unlink()
        except OSError:
            pass  # a read-only folder: the entry is rewritten (or skipped) by save
        self.dropped.append(path.name)
        if len(self.dropped) <= MAX_WARNED:
            warnings.warn(
                CacheWarning(f"cache entry {path} was damaged ({reason}): dropped and computed again"), stacklevel=3
            )
        elif len(self.dropped) == MAX_WARNED + 1:
            warnings.warn(
                CacheWarning(
                    f"more damaged entries in {self.directory}: dropped and computed again, "
                    f"counted in result.json (caches), not listed"
                ),
                stacklevel=3,
            )

    def save(self, filename: str, arrays: dict) -> int | None:
        """Store the entry; returns its size in bytes, or None when the folder cannot be
        written (the first failure warns once and stops further attempts)."""
        if self.disabled:
            return None
        try:
            size = write_entry(self.path(filename), arrays)
        except OSError as exc:
            self.disabled = f"{type(exc).__name__}: {exc.strerror or exc}"
            warnings.warn(
                CacheWarning(
                    f"cache folder {self.directory} cannot be written ({self.disabled}): "
                    f"the {self.name} cache is not kept for this run (the results do not "
                    f"change, only the time)"
                ),
                stacklevel=3,
            )
            return None
        self.saves.append(filename)
        return size

    def usage(self) -> CacheUsage:
        return CacheUsage(
            self.name, str(self.directory), self.read, tuple(self.saves), tuple(self.dropped), self.disabled
        )


def usage_since(before: tuple, after: tuple) -> tuple:
    """The usage of each cache in ``after`` since its snapshot in ``before`` (a cache
    absent from ``before``: all of it)."""
    earlier = {(u.name, u.folder): u for u in before}
    return tuple(u.since(earlier[(u.name, u.folder)]) if (u.name, u.folder) in earlier else u for u in after)


def with_construction(usage: tuple, built: tuple) -> tuple:
    """``usage`` (a solve's) with ``built`` (what the body's caches did while the body was
    built, before its first solve: a block reads, or drops, its corrections then) added to
    the entries of the same cache; a cache only ``built`` touched is appended."""
    extra = {(u.name, u.folder): u for u in built}
    out = []
    for u in usage:
        e = extra.pop((u.name, u.folder), None)
        out.append(
            u
            if e is None
            else CacheUsage(
                u.name,
                u.folder,
                u.read + e.read,
                e.saves + u.saves,
                e.dropped + u.dropped,
                u.disabled or e.disabled,
            )
        )
    return tuple(out) + tuple(extra.values())


def solve_caches(provider, scene) -> tuple:
    """The usage so far of the caches a solve of ``scene`` on ``provider`` can use: the
    body's (:meth:`~twoscale.influence.base.InfluenceProvider.cache_usage`) and the law
    cache of the scene's height map, if any."""
    out = list(provider.cache_usage())
    book = getattr(getattr(scene, "surface", None), "book", None)
    if book is not None and book.cache is not None:
        out.append(book.cache.usage())
    return tuple(out)
