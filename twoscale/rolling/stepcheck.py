"""The step of a viscoelastic rolling run against the texture and the Prony branches: when is
it too coarse for the hysteresis friction, and by how much the friction moves with the step.

**What was measured** (docs/records/rolling.md, the energy balance on sampled textures): a
chip seal sampled at ``h = 0.25`` mm, ten branches (relaxation times 1e-3 ... 1e3 s), 0.5
km/h (``v tau_min = 0.139`` mm). The work of the drag against the energy the branches store
and dissipate was off by -11.4 %, -4.3 % and +0.8 % at steps of 0.5, 0.25 and 0.125 mm (3.6,
1.8 and 0.9 times ``v tau_min``): about ``1 % x (step / (v tau_min))^2``, second order in the
step; on a 20 x 10 mm window of the same road -71, -16, -4.3 and -0.87 % at 0.5 ... 0.0625 mm,
about ``5 % x (step / (v tau_min))^2``. The friction (the mean drag) itself grew with every
halving, 1.65, 2.17, 2.45 N: first order in the step, the coarsest step two thirds of the
finest. Both follow from the stepping: the pressure is taken linear in time over a step, so a
branch whose relaxation time is shorter than a step's duration, or a stone's edge that
crosses a texture sample within a step, is integrated with too little detail, and what is
missed is dissipation (the friction comes out low).

**The criterion.** A step resolves the hysteresis friction when it is at most

    limit = min(h, v tau_a),

``h`` the road's sample spacing (a texture finer than the map is not there; the road moves
by whole samples at most) and ``tau_a`` the shortest relaxation time of an *active* branch:
one that carries at least :data:`MIN_SHARE` of the branches' modulus and whose loss peak
(``omega tau = 1``) falls at a road wavelength ``2 pi v tau`` the map resolves: from ``2 h``
to the map's length ``L`` along x (``h / pi <= v tau <= L / (2 pi)``). A branch faster
than that relaxes within the time the finest resolved wavelength takes to pass, one slower
stays glassy over the longest: either dissipates little on this texture, whatever the step.
How low the friction comes out, measured: with one branch (1 ms at 0.9 km/h on a 0.25 mm chip
seal, ``limit = h = v tau``; ``tests/test_rolling_stepcheck.py``) 42 %, 12 % and 0.04 % low at
4, 2 and 1 times the limit against the run at half the limit (the balance -23 %, -4.7 %,
-0.4 %); with the ten branches above (``limit = v tau_min = 0.139`` mm), against the friction
extrapolated to a vanishing step at first order, 40, 21 and 10 % low at 3.6, 1.8 and 0.9
times the limit (the window: 43, 22 and 11 % at 1.8, 0.9 and 0.45). So at about twice the
limit 12-43 % low; at the limit a single branch is resolved, a spread of branches still
loses up to about 20 % (compare a run at twice the step). A coarser step is
refused by nothing: the run says so
(:class:`~twoscale.errors.StepWarning`, ``rolling.json`` ``step_check``).

**The step's error, measured** (:func:`step_error`): the run at the step and at twice the
step over the same distance, on the same samples
(:func:`twoscale.rolling.run.roll_at_twice_the_step`); with the friction first order in the
step, ``F(step) - F(2 step)`` estimates the error of ``F(step)`` (Richardson with order 1)
and ``2 F(step) - F(2 step)`` the friction at a vanishing step; where the friction converges
faster (the single branch above) the estimate errs on the large side. It costs half the run
again.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import StepWarning, user_stacklevel

#: A branch is active when its modulus is at least this share of all the branches' moduli.
MIN_SHARE = 0.01
#: Order of the friction's error in the step, measured (module docstring): the Richardson
#: estimate of :func:`step_error` divides the difference of the two runs by 2^p - 1.
FRICTION_ORDER = 1.0


@dataclass(frozen=True)
class StepCheck:
    """The step of a run against what it must resolve (module docstring), mm.

    Attributes
    ----------
    step : float
        The run's step, mm.
    spacing : float or None
        The road's sample spacing, mm (None: tips, no sampled texture).
    branch_length : float or None
        ``v tau_a``, mm: the speed times the shortest relaxation time of an active branch
        (None: an elastic material, or no branch active on this texture).
    branch_tau : float or None
        That relaxation time, s.
    """

    step: float
    spacing: float | None
    branch_length: float | None
    branch_tau: float | None

    @property
    def limit(self) -> float:
        """The largest step that resolves the friction, mm (``inf`` when there is no active
        branch: an elastic material has no hysteresis for a step to miss)."""
        if self.branch_length is None:
            return math.inf
        return min(self.branch_length, math.inf if self.spacing is None else self.spacing)

    @property
    def coarse(self) -> bool:
        """Whether the step is coarser than :attr:`limit` (the friction comes out low)."""
        return self.step > self.limit * (1 + 1e-9)

    @property
    def message(self) -> str:
        """One line for the user when the step is coarse, else ""."""
        if not self.coarse:
            return ""
        parts = []
        if self.spacing is not None:
            parts.append(f"the road's sample spacing {self.spacing:g} mm")
        parts.append(f"speed x the fastest active branch's relaxation time {self.branch_length:.3g} mm")
        return (
            f"rolling.step = {self.step:g} mm is coarser than {self.limit:.3g} mm ({'; '.join(parts)}): the "
            f"hysteresis friction (mean drag) comes out low (measured: 12-43 % low at about twice the limit); "
            f"take step <= {self.limit:.3g} mm, or compare a run at twice the step (twoscale solve --step-error)"
        )

    def to_dict(self) -> dict:
        """The check as ``rolling.json`` records it."""
        return {
            "step_mm": self.step,
            "texture_spacing_mm": self.spacing,
            "branch_length_mm": self.branch_length,
            "branch_tau_s": self.branch_tau,
            "limit_mm": None if math.isinf(self.limit) else self.limit,
            "coarse": self.coarse,
            "criterion": "step <= min(texture spacing h, speed x tau_a); tau_a the shortest relaxation time "
            f"of a branch with at least {MIN_SHARE:g} of the branches' modulus and speed x tau_a >= h / pi",
            "message": self.message,
        }


def active_tau(material, speed_mm_s: float, spacing: float | None, length: float = math.inf) -> float | None:
    """The shortest relaxation time of an active branch, s (module docstring), or None; the
    road sampled at ``spacing`` mm (None: tips, no bound) over ``length`` mm along x."""
    if not material.viscoelastic:
        return None
    E = np.array([e for e, _ in material.prony], dtype=float)
    tau = np.array([t for _, t in material.prony], dtype=float)
    active = E >= MIN_SHARE * E.sum()
    if spacing is not None:
        active &= (speed_mm_s * tau >= spacing / math.pi) & (2.0 * math.pi * speed_mm_s * tau <= length)
    return float(tau[active].min()) if np.any(active) else None


def check_step(spec, material, spacing: float | None, length: float = math.inf) -> StepCheck:
    """The :class:`StepCheck` of a run (``spec``: a :class:`~twoscale.rolling.spec.RollingSpec`)
    of ``material`` over a road sampled at ``spacing`` mm (None for tips), ``length`` mm
    long along x."""
    tau = active_tau(material, spec.speed_mm_s, spacing, length)
    return StepCheck(
        float(spec.step),
        None if spacing is None else float(spacing),
        None if tau is None else spec.speed_mm_s * tau,
        tau,
    )


def warn_if_coarse(check: StepCheck) -> None:
    """A :class:`~twoscale.errors.StepWarning` with :attr:`StepCheck.message` when the step is coarse."""
    if check.coarse:
        warnings.warn(check.message, StepWarning, stacklevel=user_stacklevel())


def friction(result, distance: float | None = None) -> float:
    """The mean drag over the first ``distance`` mm of ``result`` (default all of it), N: the
    drag's work (trapezoid rule over the shifts) over the distance."""
    s, d = np.asarray(result.shifts), np.asarray(result.drag)
    n = len(s) if distance is None else int(np.searchsorted(s, s[0] + distance + 1e-9 * max(distance, 1.0)))
    if n < 2:
        return float(d[0])
    s, d = s[:n], d[:n]
    return float(np.sum(0.5 * (d[1:] + d[:-1]) * np.diff(s)) / (s[-1] - s[0]))


def step_error(fine, coarse) -> dict:
    """The friction's step error from a run at the step (``fine``) and at twice the step
    (``coarse``), both :class:`~twoscale.rolling.result.RollingResult` from the same first
    shift (module docstring): the frictions over the distance both cover, the estimated
    error of the fine run's and the extrapolated friction, N, and ``first_order``: whether
    the two runs are close enough for the correction to hold (:func:`first_order_holds`;
    where not, the extrapolation is not an answer: roll at a finer step)."""
    distance = float(coarse.shifts[-1] - coarse.shifts[0])
    f_fine, f_coarse = friction(fine, distance), friction(coarse)
    error = (f_fine - f_coarse) / (2.0**FRICTION_ORDER - 1.0)
    return {
        "distance_mm": distance,
        "friction_N": f_fine,
        "friction_at_twice_the_step_N": f_coarse,
        "estimated_error_N": error,
        "extrapolated_friction_N": f_fine + error,
        "order": FRICTION_ORDER,
        "first_order": first_order_holds(f_fine, f_coarse),
    }


def first_order_holds(fine: float, coarse: float) -> bool:
    """Whether frictions at the step (``fine``) and at twice the step (``coarse``) are close
    enough for a correction first order in the step: of one sign, and apart by at most half
    the fine one (a viscoelastic strip at 2 mm steps, 8 times the 0.25 mm limit: 3.412 N and
    -1.286 N, a "correction" larger than the friction; at 0.5 and 0.25 mm, 1.65 and 2.17 N)."""
    return bool(fine * coarse > 0.0 and abs(fine - coarse) <= 0.5 * abs(fine))


__all__ = [
    "FRICTION_ORDER",
    "MIN_SHARE",
    "StepCheck",
    "active_tau",
    "check_step",
    "first_order_holds",
    "friction",
    "step_error",
    "warn_if_coarse",
]
