"""The block iterations' expected sweep count, from what the micro step's policy knows before
they run (:mod:`.costmodel`: a block iteration's predicted seconds are its work for
``gs_sweeps`` sweeps times this count over ``gs_sweeps``).

A block iteration (paper eq. 8) converges as fast as the patches' elastic interaction lets
it: a patch of contact radius ``a`` feels a neighbour at distance ``d`` through the
half-space's ``1 / d`` against its own compliance's ``1 / a``, and patches of radius ``a`` at
spacing ``d`` cover about ``(a / d)^2`` of their bounding box. With ``rho = sqrt(coverage)``
that ratio, an iteration contracting at a rate that grows with ``rho`` takes sweeps growing
as ``log(1 / (1 - rho))``; under load control and with the tilt its coarse corrections of
the approach and the angles add a few.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Largest coverage a :class:`SweepCount` reads (patches that nearly fill their box).
COVERAGE_MAX = 0.9


@dataclass(frozen=True)
class SweepCount:
    """Block sweeps a block iteration is expected to take, from what the policy knows before
    it runs: ``base + interaction x log(1 / (1 - rho))``, plus ``load`` or ``tilt``, with ``rho =
    sqrt(coverage)`` (the coverage at most ``COVERAGE_MAX``) the patches' contact radius over
    their spacing, the strength of their elastic interaction (module docstring); ``load``
    under load control, ``tilt`` instead where the tilt is free too.

    Attributes
    ----------
    base, interaction, load, tilt : float
        Sweeps (fitted).
    """

    base: float
    interaction: float = 0.0
    load: float = 0.0
    tilt: float = 0.0

    def __call__(self, coverage: float, *, load_control: bool = False, tilt: bool = False) -> float:
        rho = math.sqrt(min(max(float(coverage), 0.0), COVERAGE_MAX))
        sweeps = self.base + self.interaction * math.log(1.0 / (1.0 - rho))
        sweeps += self.tilt if tilt else self.load if load_control else 0.0
        return max(sweeps, 1.0)
