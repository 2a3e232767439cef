"""Asperity load-penetration laws (docs/method.md section 2): ``P = f(delta)`` for one
asperity alone. Units: delta in mm, P in N, stiffness in N/mm."""

from .base import AsperityLaw
from .compliant import CompliantLaw, compliant
from .hertz import HertzLaw, SphereLaw
from .select import law_for
from .stack import LawStack
from .tabulated import TabulatedLaw

__all__ = ["AsperityLaw", "HertzLaw", "SphereLaw", "TabulatedLaw", "CompliantLaw", "compliant", "law_for", "LawStack"]
