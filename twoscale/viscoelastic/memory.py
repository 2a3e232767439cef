"""The body's memory in the creep form, and one time step of it (exact for a pressure
linear in time over the step).

With the creep compliance ``J(t) = J_inf - sum_j c_j exp(-t / lambda_j)``
(:mod:`twoscale.viscoelastic.prony`) the surface displacement is ``u = K w`` with ``K``
the body's unit-modulus influence operator and

    w(t) = int_0^t J(t - s) dp/ds ds = J_inf p(t) - sum_j m_j(t),
    m_j(t) = c_j int_0^t exp(-(t - s) / lambda_j) dp/ds ds.

Over a step ``dt`` in which ``p`` is linear in time,

    m_j(t + dt) = a_j m_j(t) + c_j g_j (p(t + dt) - p(t)),
    a_j = exp(-dt / lambda_j),  g_j = (lambda_j / dt) (1 - a_j)   (g_j = 1 at dt = 0),

so ``w(t + dt) = J_eff p(t + dt) + H`` with ``J_eff = J_inf - sum_j c_j g_j`` and
``H = sum_j (c_j g_j p(t) - a_j m_j(t))``, known before the step. The step is then an
elastic contact problem at compliance ``J_eff`` with the extra displacement ``K H``.

Memory held: for the cells where pressure has been (``w`` is zero elsewhere), one value per
kept branch plus the last pressure and the cell's index: ``8 (2 + n_kept)`` bytes a cell.
A cell is dropped once it carries no pressure and its memory has decayed below
``DROP`` times the largest ``J_inf p`` seen; a branch is dropped everywhere once its memory
has (its instantaneous part stays in ``J_eff``: nothing is lost but a decayed tail).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .prony import CreepCompliance

#: Memory below this fraction of the largest ``J_inf p`` seen is dropped (cells, branches).
DROP = 1e-10


def step_factors(J: CreepCompliance, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(a_j, g_j)`` of a step ``dt`` (s, >= 0)."""
    if dt <= 0:
        return np.ones_like(J.lambdas), np.ones_like(J.lambdas)
    r = dt / J.lambdas
    a = np.exp(-r)
    g = -np.expm1(-r) / r
    return a, g


def effective_compliance(J: CreepCompliance, dt: float) -> float:
    """``J_eff`` of a step ``dt``, 1/MPa (``J(0)`` at dt = 0, ``J_inf`` as dt -> inf)."""
    _, g = step_factors(J, dt)
    return float(J.J_inf - np.sum(J.c * g))


@dataclass
class Memory:
    """The memory ``m_j`` and last pressure on the cells of a flat field of ``size`` cells
    that pressure has reached. Owned by one history solve; advanced step by step."""

    J: CreepCompliance
    size: int
    cells: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    p: np.ndarray = field(default_factory=lambda: np.zeros(0))
    m: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    kept: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    scale: float = 0.0
    peak_cells: int = 0

    def __post_init__(self) -> None:
        self.kept = np.arange(self.J.lambdas.size)
        self.m = np.zeros((self.kept.size, 0))

    @property
    def nbytes(self) -> int:
        return int(self.cells.nbytes + self.p.nbytes + self.m.nbytes)

    def history_field(self, dt: float) -> np.ndarray:
        """``H`` of the next step of length ``dt`` as a flat field (dimensionless, as ``w``)."""
        H = np.zeros(self.size)
        if self.cells.size:
            a, g = step_factors(self.J, dt)
            # every branch's instantaneous part acts on the last pressure (it is in J_eff),
            # dropped branches only lose their decayed memory
            H[self.cells] = float(np.sum(self.J.c * g)) * self.p - a[self.kept] @ self.m
        return H

    def advance(self, dt: float, p_new: np.ndarray) -> None:
        """Advance over a step ``dt`` to the new pressure ``p_new`` (flat field, MPa)."""
        p_new = np.asarray(p_new, dtype=float).ravel()
        loaded = np.flatnonzero(p_new > 0)
        cells = np.union1d(self.cells, loaded)
        p_old = np.zeros(cells.size)
        m_old = np.zeros((self.kept.size, cells.size))
        if self.cells.size:
            pos = np.searchsorted(cells, self.cells)
            p_old[pos] = self.p
            m_old[:, pos] = self.m
        p = p_new[cells]
        a, g = step_factors(self.J, dt)
        m = a[self.kept, None] * m_old + (self.J.c * g)[self.kept, None] * (p - p_old)[None, :]
        self.scale = max(self.scale, self.J.J_inf * float(p.max(initial=0.0)))
        self.cells, self.p, self.m = cells, p, m
        self._drop()
        self.peak_cells = max(self.peak_cells, int(self.cells.size))

    def _drop(self) -> None:
        if self.scale <= 0:
            return
        tiny = DROP * self.scale
        if self.m.size:
            live = np.max(np.abs(self.m), axis=1) > tiny
            self.kept, self.m = self.kept[live], self.m[live]
        keep = (self.p > 0) | (np.max(np.abs(self.m), axis=0, initial=0.0) > tiny)
        self.cells, self.p, self.m = self.cells[keep], self.p[keep], self.m[:, keep]

    def w(self) -> np.ndarray:
        """``w = J_inf p - sum_j m_j`` on the carried cells (flat field)."""
        out = np.zeros(self.size)
        out[self.cells] = self.J.J_inf * self.p - self.m.sum(axis=0)
        return out


__all__ = ["DROP", "Memory", "effective_compliance", "step_factors"]
