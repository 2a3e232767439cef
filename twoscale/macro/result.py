"""The frozen result of the macro step."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np


@dataclass(frozen=True)
class MacroResult:
    """Tip forces of the macro step (docs/method.md section 2) and how they were found.

    Attributes
    ----------
    forces : (N,) array, N
        Tip force ``P_k`` of each asperity, in scene order (>= 0 when converged).
    penetration : float, mm
        Rigid approach ``d`` (given, or solved under load control).
    tilt : (alpha, beta) or None
        Tilt angles, radians (about x, about y), when solved with ``tilt=True``.
    pivot : (px, py), mm
        Pivot of the tilt (as given; meaningful only with a tilt).
    local_penetrations : (N,) array, mm
        Argument of each asperity's law at the solution: ``delta_k = d - z_k -
        [beta (x_k - px) + alpha (y_k - py)] - sum_{l != k} T_kl P_l - c_k P_k``
        (``c_k`` the smooth self-compliance, 0 on the half-space), so that
        ``P_k = f_k(delta_k)`` for ``delta_k > 0`` and ``P_k = 0`` otherwise.
    in_contact : (N,) bool array
        ``delta_k > 0``.
    converged : bool
        Whether the relative residual reached ``tol``.
    message : str
    iterations : int
        Newton steps taken (on the safe path: all of them, inner solves included).
    residuals : tuple of float
        Relative residual ``||r|| / ||P||`` of the Newton iteration on the coupled
        system, before each step and after the last (length iterations + 1); when the
        safe path ran, only its final residual is appended.
    timings_s : dict
        Wall-clock seconds: "compliance" (interaction matrix or operator), "newton",
        "error_check" (matrix-free only), "total".
    interaction : str
        "dense" (``N x N`` matrix, LU per Newton step) or "matrix-free" (the provider's
        point operator, Newton steps by conjugate gradients).
    operator_rtol : float or None
        Matrix-free: the accuracy asked of the point operator (relative to ``max |u|``).
    operator_error : float or None
        Matrix-free: measured error of the operator's product at the solution on a sample
        of tips against exact rows of the point compliance, relative to ``max |T P|``.
        A force error follows as about ``f_k' * operator_error * max |T P|``.
    krylov_iterations : int
        Matrix-free: conjugate-gradient iterations over all Newton steps.
    safe_path : bool
        Plain Newton stalled or reached an unstable equilibrium and the safe path
        (:mod:`twoscale.macro.robust`) gave the answer: a sign of merged contacts; or
        it was skipped (thousands of tips) or deferred (``safe_path_deferred``).
    safe_path_deferred : bool
        Newton stalled and its last iterate was handed on: the caller asked not to take
        the safe path yet (``solve_macro``'s ``defer_safe_path``).
    """

    forces: np.ndarray
    penetration: float
    tilt: tuple | None
    pivot: tuple
    local_penetrations: np.ndarray
    in_contact: np.ndarray
    converged: bool
    message: str
    iterations: int
    residuals: tuple
    timings_s: dict = field(default_factory=dict)
    interaction: str = "dense"
    operator_rtol: float | None = None
    operator_error: float | None = None
    krylov_iterations: int = 0
    safe_path: bool = False
    safe_path_deferred: bool = False

    def __post_init__(self) -> None:
        for name, dtype in (("forces", float), ("local_penetrations", float), ("in_contact", bool)):
            a = np.array(getattr(self, name), dtype=dtype, copy=True)
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @property
    def total_load(self) -> float:
        """Sum of the tip forces, N."""
        return float(np.sum(self.forces))


def continued(first: MacroResult, full: MacroResult) -> MacroResult:
    """The macro step ``full`` (started from the first stage's answer ``first``) with the
    first stage's steps, residuals, Krylov iterations and time counted in."""
    timings = {k: float(first.timings_s.get(k, 0.0)) + float(v) for k, v in full.timings_s.items()}
    return replace(
        full,
        iterations=first.iterations + full.iterations,
        residuals=tuple(first.residuals) + tuple(full.residuals[1:]),
        krylov_iterations=first.krylov_iterations + full.krylov_iterations,
        timings_s=timings,
    )
