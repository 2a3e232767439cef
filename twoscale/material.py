"""Material of the body (the indenters are rigid): linear elastic, or linear viscoelastic
with a Prony series (generalized Maxwell model) at constant Poisson's ratio."""

from __future__ import annotations

from typing import Any

import math
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Material:
    """Isotropic linear elastic or viscoelastic body.

    Parameters
    ----------
    E : float
        Young's modulus, MPa (> 0, finite). With ``prony`` it is the relaxed modulus
        ``E_inf`` (the long-time value).
    nu : float
        Poisson's ratio, -1 < nu <= 0.5 (0.5 = incompressible, allowed); constant in time.
    prony : tuple of (E_k, tau_k), default ()
        Prony branches of the relaxation modulus
        ``E(t) = E + sum_k E_k exp(-t / tau_k)`` (E_k MPa > 0, tau_k s > 0, no two equal
        tau_k). ``()``: elastic. The glassy (instantaneous) modulus is ``E + sum E_k``.
        See :mod:`twoscale.viscoelastic.prony` for the creep compliance.
    """

    E: float
    nu: float
    prony: tuple = field(default=(), repr=False)

    def __post_init__(self) -> None:
        if not (isinstance(self.E, (int, float)) and math.isfinite(self.E) and self.E > 0):
            raise ValueError(f"material.E must be a finite number > 0 (MPa), got {self.E!r}")
        if not (isinstance(self.nu, (int, float)) and math.isfinite(self.nu) and -1.0 < self.nu <= 0.5):
            raise ValueError(f"material.nu must satisfy -1 < nu <= 0.5, got {self.nu!r}")
        if self.prony != ():
            object.__setattr__(self, "prony", check_prony(self.prony))

    def __repr__(self) -> str:
        extra = f", prony={self.prony!r}" if self.prony else ""
        return f"Material(E={self.E!r}, nu={self.nu!r}{extra})"

    @property
    def E_star(self) -> float:
        """Plane-strain modulus E* = E / (1 - nu^2), MPa (rigid indenter); with ``prony``
        the relaxed one."""
        return self.E / (1.0 - self.nu**2)

    @property
    def viscoelastic(self) -> bool:
        """True when the material has Prony branches."""
        return bool(self.prony)

    @property
    def E_glassy(self) -> float:
        """Instantaneous modulus ``E + sum E_k``, MPa (``E`` when elastic)."""
        return self.E + sum(e for e, _ in self.prony)

    def relaxed(self) -> "Material":
        """The elastic material at the relaxed modulus (no branches)."""
        return Material(self.E, self.nu)

    def at_modulus(self, E: float) -> "Material":
        """The elastic material of Young's modulus ``E`` (MPa) and this Poisson's ratio."""
        return Material(float(E), self.nu)


def check_prony(prony: Any) -> tuple:
    """The branches as a tuple of ``(E_k, tau_k)`` float pairs, or ``ValueError`` naming the
    bad entry (``material.prony[2]: tau_k must be > 0 (s), got -1.0``; indices from 0 as in
    the list written in the scene file)."""
    if isinstance(prony, (str, bytes)) or not hasattr(prony, "__len__"):
        raise ValueError(f"material.prony must be a list of [E_k, tau_k] pairs (MPa, s), got {prony!r}")
    out = []
    for k, row in enumerate(prony):
        if isinstance(row, (str, bytes)) or not hasattr(row, "__len__") or len(row) != 2:
            raise ValueError(f"material.prony[{k}] must be a pair [E_k, tau_k] (MPa, s), got {row!r}")
        pair = []
        for name, unit, v in (("E_k", "MPa", row[0]), ("tau_k", "s", row[1])):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
                raise ValueError(f"material.prony[{k}]: {name} must be a finite number ({unit}), got {v!r}")
            if not float(v) > 0:
                raise ValueError(f"material.prony[{k}]: {name} must be > 0 ({unit}), got {v!r}")
            pair.append(float(v))
        out.append(tuple(pair))
    if not out:
        raise ValueError("material.prony is empty, got [] (list at least one [E_k, tau_k] or leave it out)")
    taus = [t for _, t in out]
    for k, t in enumerate(taus):
        if t in taus[:k]:
            raise ValueError(
                f"material.prony[{k}]: tau_k = {t!r} s repeats an earlier branch's (merge the two: add their E_k)"
            )
    return tuple(out)
