"""A bounded, owned cache of precomputed arrays.

Read-only quantities recur across the patches of a solve and across the solves of a solver
object (the half-space's Love offset tables and Chebyshev interpolation matrices, the
operators between patches). Each such cache is a :class:`BoundedCache` held by the object
that owns it (a solver's :class:`~twoscale.influence.cached.OperatorCaches`, never the body),
keyed by values (grid shapes, offsets, ``h``, ``rtol``), and bounded in bytes by a running
total: an insertion costs O(1) plus the evictions it causes, whatever the number of entries
(a module-global dict whose size was re-summed at every insertion made a 200-tip scene
quadratic in its patch pairs).
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any, Hashable

__all__ = ["BoundedCache"]


class BoundedCache:
    """Least-recently-used cache whose entries' sizes add up to at most ``max_bytes``.

    Parameters
    ----------
    max_bytes : float
        Bound on the sum of the sizes given to :meth:`put`, bytes. An entry larger than the
        bound is not stored.
    name : str, optional
        For :meth:`stats` and ``repr``.

    Attributes
    ----------
    nbytes : int
        Running total of the stored entries' sizes, bytes.
    hits, misses, evictions : int
        Counters of :meth:`get` / :meth:`pop` outcomes and of entries dropped to keep the bound.
    """

    def __init__(self, max_bytes: float, *, name: str = ""):
        if not max_bytes >= 0:
            raise ValueError(f"max_bytes must be >= 0 (bytes), got {max_bytes!r}")
        self.max_bytes = float(max_bytes)
        self.name = name
        self._entries: OrderedDict = OrderedDict()  # key -> (value, nbytes)
        self.nbytes = 0
        self.hits = self.misses = self.evictions = 0

    def __len__(self) -> int:
        return len(self._entries)

    def __contains__(self, key: Hashable) -> bool:
        return key in self._entries

    def __repr__(self) -> str:
        return (
            f"BoundedCache({self.name!r}, {len(self)} entries, {self.nbytes} / "
            f"{self.max_bytes:.0f} bytes, {self.hits} hits, {self.misses} misses)"
        )

    def get(self, key: Hashable, default: Any = None) -> Any:
        """The value stored under ``key`` (now the most recently used), else ``default``."""
        hit = self._entries.get(key)
        if hit is None:
            self.misses += 1
            return default
        self.hits += 1
        self._entries.move_to_end(key)
        return hit[0]

    def pop(self, key: Hashable, default: Any = None) -> Any:
        """Remove and return the value stored under ``key``, else ``default``."""
        hit = self._entries.pop(key, None)
        if hit is None:
            self.misses += 1
            return default
        self.hits += 1
        self.nbytes -= hit[1]
        return hit[0]

    def put(self, key: Hashable, value: Any, nbytes: int) -> Any:
        """Store ``value`` (of ``nbytes`` bytes) under ``key``, evicting the least recently
        used entries beyond the bound; returns ``value``."""
        nbytes = int(nbytes)
        if nbytes < 0:
            raise ValueError(f"nbytes must be >= 0, got {nbytes!r}")
        old = self._entries.pop(key, None)
        if old is not None:
            self.nbytes -= old[1]
        if nbytes > self.max_bytes:
            return value
        self._entries[key] = (value, nbytes)
        self.nbytes += nbytes
        while self.nbytes > self.max_bytes:
            _, (_, size) = self._entries.popitem(last=False)
            self.nbytes -= size
            self.evictions += 1
        return value

    def sizes(self) -> dict:
        """Size (bytes) of every stored entry, least recently used first."""
        return {key: size for key, (_, size) in self._entries.items()}

    def clear(self) -> None:
        """Drop every entry (the counters are kept)."""
        self._entries.clear()
        self.nbytes = 0

    def stats(self) -> dict:
        """Entries, bytes, bound and counters, for reports."""
        return {
            "name": self.name,
            "entries": len(self),
            "nbytes": self.nbytes,
            "max_bytes": self.max_bytes,
            "hits": self.hits,
            "misses": self.misses,
            "evictions": self.evictions,
        }
