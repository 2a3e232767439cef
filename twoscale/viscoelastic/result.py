"""The result of a history solve: the histories as arrays and each output time's
:class:`~twoscale.results.ContactResult`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..material import Material
from .history import LoadHistory


@dataclass(frozen=True)
class StepRecord:
    """One accepted step: its end time (s), length (s), effective compliance (1/MPa),
    error estimate (relative; None where none could be made), solver iterations and seconds."""

    t: float
    dt: float
    J_eff: float
    error: float | None
    iterations: int
    seconds: float


@dataclass(frozen=True)
class HistoryResult:
    """A viscoelastic (or quasi-static elastic) history.

    Attributes
    ----------
    times : (n,) array
        Output times, s.
    penetration : (n,) array
        Rigid approach, mm.
    total_load : (n,) array
        Total load, N.
    contact_area : (n,) array
        Contact area, mm^2.
    tilt : (n, 2) array or None
        (alpha, beta), rad, under tilt.
    forces : (n, N) array
        Asperity forces, N (scene order, 0-based).
    results : tuple of ContactResult
        The full answer at each output time.
    steps : tuple of StepRecord
        Every accepted step, in order (a step of length 0 is the glassy instant of a step load).
    rejected : int
        Steps redone with a shorter step (automatic steps).
    error_estimate : float
        Largest local error estimate of the accepted steps (relative, see
        :mod:`twoscale.viscoelastic.stepping`).
    method : str
        The step solver ("twoscale" or "reference").
    material : Material
    history : LoadHistory
    memory : dict
        ``peak_cells`` (cells carrying memory at most), ``branches`` (n), ``bytes_per_cell``,
        ``peak_bytes``.
    converged : bool
        Every step's solve converged.
    message : str
    timings_s : dict
    caches : tuple of CacheUsage
        What the on-disk caches (the block's corrections) gave and took, the body's build
        included (:class:`twoscale.io.cache_entry.CacheUsage`); empty when none was used.
    """

    times: np.ndarray
    penetration: np.ndarray
    total_load: np.ndarray
    contact_area: np.ndarray
    tilt: np.ndarray | None
    forces: np.ndarray
    results: tuple
    steps: tuple
    rejected: int
    error_estimate: float
    method: str
    material: Material
    history: LoadHistory
    memory: dict
    converged: bool
    message: str
    timings_s: dict
    caches: tuple = ()

    def __post_init__(self) -> None:
        for name in ("times", "penetration", "total_load", "contact_area", "forces", "tilt"):
            a = getattr(self, name)
            if a is not None:
                a = np.array(a, dtype=float)
                a.setflags(write=False)
                object.__setattr__(self, name, a)

    @property
    def n_steps(self) -> int:
        return len(self.steps)

    def __repr__(self) -> str:
        state = "converged" if self.converged else "NOT converged"
        return (
            f"<HistoryResult {self.method}: {len(self.times)} output times over "
            f"{self.times[-1]:.3g} s, {self.n_steps} steps ({self.rejected} redone), error estimate "
            f"{self.error_estimate:.2g}, {state}, {self.timings_s.get('total', 0.0):.3g} s>"
        )

    __str__ = __repr__


__all__ = ["HistoryResult", "StepRecord"]
