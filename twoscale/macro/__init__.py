"""Macro step (docs/method.md section 2): Newton-Raphson on the tip forces of interacting
asperities, penetration or load control, ball-and-socket tilt."""

from .result import MacroResult
from .solve import solve_macro
from .start import MacroStart
from .system import MacroSystem

__all__ = ["solve_macro", "MacroResult", "MacroSystem", "MacroStart"]
