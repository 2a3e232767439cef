"""Energy of the creep-form memory: the work dissipated in the dashpots and the energy
stored in the springs, step by step, exact for a pressure linear in time over a step.

The creep compliance ``J(t) = J0 + sum_j c_j (1 - exp(-t / lambda_j))`` is that of a spring
of compliance ``J0 = J(0)`` in series with Kelvin-Voigt units (spring compliance ``c_j``,
dashpot viscosity ``lambda_j / c_j``), the retardation form of the same material as the
Prony (Maxwell) branches. A unit's strain is ``eps_j = c_j p - m_j`` with the memory ``m_j``
of :mod:`twoscale.viscoelastic.memory`, and its dashpot's rate ``d eps_j / dt = m_j / lambda_j``.
With ``K`` the body's unit-modulus operator (``u = K w``, symmetric positive definite) and
``<f, g> = h^2 sum f g`` over the cells, the power the pressure puts into the body,
``<p, K dw/dt>``, splits into

    d/dt Psi + sum_j D_j,
    Psi = J0 <p, K p> / 2 + sum_j <eps_j, K eps_j> / (2 c_j)          (stored, N mm),
    D_j = <m_j, K m_j> / (c_j lambda_j)                                (dissipated, N mm / s).

Over a step ``dt`` with ``p`` linear, ``m_j(t + s) = alpha(s) m_j + c_j gamma(s) dp`` with
``alpha = exp(-s / lambda_j)`` and ``gamma = (lambda_j / dt) (1 - alpha)``, so the step's
dissipation is a quadratic form in ``m_j``, ``dp = p(t + dt) - p(t)`` whose weights are the
integrals of ``alpha^2``, ``alpha gamma`` and ``gamma^2`` over the step, in closed form
(:func:`step_integrals`). It needs the scalars ``<m_j, K m_j>``, carried from step to step by
the same exact recurrence, and one product ``K dp`` per step; nothing per branch is held on
the grid. The dashpots of the Prony (Maxwell) branches dissipate at the same rate at every
instant (the two forms are realisations of one material, and their free energies agree):
a test checks it on a stress history through both sets of branches.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .memory import Memory, step_factors


def step_integrals(lam: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(int alpha^2, int alpha gamma, int gamma^2)`` over ``[0, dt]`` (s) for every
    retardation time ``lam`` (module docstring); series where ``dt / lam`` is small (the
    closed form cancels there)."""
    r = dt / lam
    aa = -0.5 * lam * np.expm1(-2.0 * r)
    small = r < 1e-3
    rs = np.where(small, 1.0, r)  # avoid 0 / 0 in the branch not taken
    ab = lam / rs * (-np.expm1(-rs) + 0.5 * np.expm1(-2.0 * rs))
    f = rs + 2.0 * np.expm1(-rs) - 0.5 * np.expm1(-2.0 * rs)
    bb = lam * f / rs**2
    ab_s = lam * (0.5 * r - 0.5 * r**2 + 7.0 / 24.0 * r**3)
    bb_s = lam * (r / 3.0 - r**2 / 4.0 + 7.0 * r**3 / 60.0 - r**4 / 24.0)
    return aa, np.where(small, ab_s, ab), np.where(small, bb_s, bb)


@dataclass
class BranchEnergy:
    """The scalars that give the memory's stored and dissipated energy (owned by one run).

    ``S[j] = <m_j, K m_j>`` (the memory is dimensionless, ``K`` maps it to mm: mm^3), ``Kp``
    the displacement ``K p`` of the last pressure on the whole memory grid (mm / (1/MPa)),
    ``pKp = <p, K p>``. The memory ``m_j`` itself stays in :class:`Memory` (sparse)."""

    memory: Memory
    h: float
    S: np.ndarray = field(init=False)
    Kp: np.ndarray = field(init=False)
    pKp: float = 0.0

    def __post_init__(self) -> None:
        self.S = np.zeros(self.memory.J.lambdas.size)
        self.Kp = np.zeros(self.memory.size)

    def _dot(self, f: np.ndarray, cells: np.ndarray, g_full: np.ndarray) -> np.ndarray:
        return self.h**2 * (f @ g_full[cells]) if cells.size else np.zeros(f.shape[0])

    def step(self, dt: float, p_new: np.ndarray, K_dp: np.ndarray) -> float:
        """The energy dissipated (N mm) over a step ``dt`` (s) to ``p_new`` (flat, MPa), with
        ``K_dp`` the displacement (mm) of the pressure change; call before
        ``memory.advance``. ``dt = inf``: the relaxed start (memory empty after it, nothing
        counted: the hold before the run is not part of it)."""
        mem, J = self.memory, self.memory.J
        p_old = np.zeros(mem.size)
        p_old[mem.cells] = mem.p
        dp = p_new - p_old
        P = self.h**2 * float(dp @ K_dp)
        self.Kp = self.Kp + K_dp
        self.pKp = self.h**2 * float(p_new @ self.Kp)
        if not math.isfinite(dt):
            self.S[:] = 0.0
            return 0.0
        X = np.zeros(J.lambdas.size)
        X[mem.kept] = self._dot(mem.m, mem.cells, K_dp)
        lam, c = J.lambdas, J.c
        dissipated = 0.0
        if dt > 0 and lam.size:
            aa, ab, bb = step_integrals(lam, dt)
            dissipated = float(np.sum(aa * self.S / (c * lam) + 2.0 * ab * X / lam + c * bb * P / lam))
        a, g = step_factors(J, dt)
        self.S = a * a * self.S + 2.0 * a * c * g * X + (c * g) ** 2 * P
        return max(dissipated, 0.0)

    def stored(self) -> float:
        """``Psi`` (N mm) after ``memory.advance`` of the step just counted."""
        mem, J = self.memory, self.memory.J
        if not J.lambdas.size:
            return 0.5 * J.J_inf * self.pKp
        pKm = np.zeros(J.lambdas.size)
        pKm[mem.kept] = self._dot(mem.m, mem.cells, self.Kp)
        # <eps, K eps> / c = c <p, K p> - 2 <p, K m> + <m, K m> / c
        return float(0.5 * J.J0 * self.pKp + 0.5 * np.sum(J.c * self.pKp - 2.0 * pKm + self.S / J.c))


__all__ = ["BranchEnergy", "step_integrals"]
