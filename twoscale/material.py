"""Linear elastic material of the body (the indenters are rigid)."""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Material:
    """Isotropic linear elastic body.

    Parameters
    ----------
    E : float
        Young's modulus, MPa (> 0, finite).
    nu : float
        Poisson's ratio, -1 < nu <= 0.5 (0.5 = incompressible, allowed).
    """

    E: float
    nu: float

    def __post_init__(self) -> None:
        if not (isinstance(self.E, (int, float)) and math.isfinite(self.E) and self.E > 0):
            raise ValueError(f"material.E must be a finite number > 0 (MPa), got {self.E!r}")
        if not (isinstance(self.nu, (int, float)) and math.isfinite(self.nu) and -1.0 < self.nu <= 0.5):
            raise ValueError(f"material.nu must satisfy -1 < nu <= 0.5, got {self.nu!r}")

    @property
    def E_star(self) -> float:
        """Plane-strain modulus E* = E / (1 - nu^2), MPa (rigid indenter)."""
        return self.E / (1.0 - self.nu**2)
