"""Finite-block influence provider: Love/Boussinesq half-space + smooth scikit-fem correction.

Entry point: :class:`BlockProvider` (``material``, ``size``, ``base``, ``origin``).
Closed forms used as references live beside it: :mod:`fem_influence.boussinesq`
(interior point-force fields) and :mod:`fem_influence.layer` (layer on a rigid base).
scikit-fem and meshio are imported only when a block is built.
"""

from .direct import DirectResult, solve_cell_load
from .provider import BlockGridOperator, BlockProvider

__all__ = ["BlockProvider", "BlockGridOperator", "DirectResult", "solve_cell_load"]
