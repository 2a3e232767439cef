"""Influence providers: "displacement here from pressure there".

Every solver takes an :class:`InfluenceProvider` and never knows which body it has.
"""

from .base import InfluenceProvider, GridOperator
from .halfspace import HalfSpace
from .points import DensePointOperator, PointOperator

__all__ = ["InfluenceProvider", "GridOperator", "HalfSpace", "PointOperator", "DensePointOperator"]
