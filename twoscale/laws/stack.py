"""Many asperity laws evaluated as one vector law (entry k by law k).

Closed-form laws of one type (:class:`HertzLaw`, :class:`SphereLaw`) are merged into
a single law with array parameters; any other law is evaluated once per distinct
object on the entries that use it (asperities sharing one tabulated law cost one call).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from .base import AsperityLaw, as_force, as_penetration


class LawStack:
    """Vector of laws: ``force(delta)[k] = laws[k].force(delta[k])``.

    Parameters
    ----------
    laws : sequence of AsperityLaw, length N
    """

    def __init__(self, laws: Sequence[AsperityLaw]):
        laws = list(laws)
        for k, law in enumerate(laws):
            if not isinstance(law, AsperityLaw):
                raise ValueError(f"laws[{k}] is not an AsperityLaw: {law!r}")
        self.size = len(laws)
        self._groups = _groups(laws)

    def _map(self, method: str, values: np.ndarray) -> np.ndarray:
        if values.shape != (self.size,):
            raise ValueError(f"expected an array of shape ({self.size},), got {values.shape}")
        out = np.empty(self.size)
        for law, index in self._groups:
            out[index] = getattr(law, method)(values[index])
        return out

    def force(self, delta) -> np.ndarray:
        """Forces (N) at local penetrations ``delta`` (mm), shape (N,)."""
        return self._map("force", as_penetration(delta))

    def stiffness(self, delta) -> np.ndarray:
        """Tangent stiffnesses (N/mm) at ``delta`` (mm), shape (N,)."""
        return self._map("stiffness", as_penetration(delta))

    def penetration(self, P) -> np.ndarray:
        """Penetrations (mm) carrying forces ``P`` (N), shape (N,)."""
        return self._map("penetration", as_force(P))

    def complementary_energy(self, P) -> np.ndarray:
        """Complementary energies (N mm) at forces ``P`` (N), shape (N,)."""
        return self._map("complementary_energy", as_force(P))


def _groups(laws: list) -> list[tuple[AsperityLaw, np.ndarray]]:
    by_key: dict = {}
    for k, law in enumerate(laws):
        key = type(law) if hasattr(type(law), "stacked") else id(law)
        by_key.setdefault(key, []).append(k)
    groups = []
    for key, index in by_key.items():
        members = [laws[k] for k in index]
        law = type(members[0]).stacked(members) if isinstance(key, type) else members[0]
        groups.append((law, np.asarray(index, dtype=np.int64)))
    return groups
