"""How patches act on each other: the coupling objects, each building its product engine.

A coupling is a small frozen object that an iteration (:mod:`.strategies`) composes with;
:meth:`build` makes the engine that computes ``sum_{l != k} A_kl v_l`` for the patches of
one solve:

* :class:`Exact`: every pair through the provider's operators (:class:`.blocks.Coupling`:
  dense, separated or spectral route per pair). For the two-level iteration every pair is
  *near* and no far field is held (:class:`ExactProducts`);
* :class:`FarField`: pairs farther apart than ``(r_k + r_l) / sqrt(tol)`` through their
  resultants, evaluated per block (:class:`.farfield.FarFieldCoupling`, block Gauss-Seidel)
  or for every block at once and held for a sweep (:class:`.farfield.LaggedFarField`, the
  two-level iteration: ``held=True``).

Every engine answers ``rhs``, ``patch_displacement``, ``append``, ``replace``,
``route_counts``; an engine built with ``held=True`` also ``near(k)`` and ``refresh(values)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .blocks import Coupling
from .farfield import FarFieldCoupling, LaggedFarField


class ExactProducts(Coupling):
    """:class:`.blocks.Coupling` as an iteration with a held far field sees it: every other
    patch is near (:meth:`near`) and there is no far field to refresh."""

    def near(self, k: int) -> np.ndarray:
        """Every patch but ``k``, ascending."""
        return np.array([l for l in range(len(self.patches)) if l != k], dtype=np.int64)

    def refresh(self, values: list) -> None:
        """Nothing is held: every product is made when asked."""


@dataclass(frozen=True)
class Exact:
    """Every pair of patches coupled exactly."""

    name: str = "exact"

    @property
    def far_tol(self) -> None:
        """No far field (the attempt's record)."""
        return None

    def build(
        self, provider, patches, *, held: bool, dense_max_entries: int, separated_rtol: float | None
    ) -> ExactProducts:
        """The engine for ``patches`` (``held`` changes nothing: no far field; the other
        keywords as :class:`.blocks.Coupling`'s)."""
        return ExactProducts(provider, patches, dense_max_entries=dense_max_entries, separated_rtol=separated_rtol)


@dataclass(frozen=True)
class FarField:
    """Patches farther apart than ``(r_k + r_l) / sqrt(tol)`` act through their resultants
    (relative error per far pair about ``tol``, 0 < tol < 1)."""

    tol: float
    name: str = "far field"

    def __post_init__(self) -> None:
        if not (isinstance(self.tol, (int, float)) and 0.0 < self.tol < 1.0):
            raise ValueError(f"far-field tol must be a number in (0, 1), got {self.tol!r}")

    @property
    def far_tol(self) -> float:
        """The tolerance (the attempt's record)."""
        return float(self.tol)

    def build(
        self, provider, patches, *, held: bool, dense_max_entries: int, separated_rtol: float | None
    ) -> FarFieldCoupling:
        """The engine for ``patches``: the far field evaluated per block, or (``held``) for
        every block at once and held until refreshed (the other keywords as
        :class:`.blocks.Coupling`'s)."""
        kind = LaggedFarField if held else FarFieldCoupling
        return kind(
            provider, patches, far_tol=self.far_tol, dense_max_entries=dense_max_entries, separated_rtol=separated_rtol
        )


def coupling_for(far_tol: float | None) -> Exact | FarField:
    """The coupling a far-field tolerance names: None exact, a number in (0, 1) far field."""
    return Exact() if far_tol is None else FarField(far_tol)
