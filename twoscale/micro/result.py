"""What the micro step returns: :class:`MicroResult`."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..stopping import StopReason


@dataclass(frozen=True)
class MicroResult:
    """Pressure on the patches after the micro step.

    Attributes
    ----------
    patches : tuple of Patch
    pressures : tuple of (ny, nx) arrays, MPa: final pressure on each patch's block.
    initial : tuple of (ny, nx) arrays, MPa: eq. 7 pressures ``p0`` on the final patches
        (empty when they were not computed: the union CG without ``p0``).
    gaps : tuple of (ny, nx) arrays, mm: ``z + tilt + u - d`` (``inf`` where no indenter).
    penetration : float
        Approach d, mm (given, or corrected under load control).
    tilt : (alpha, beta) or None, radians.
    converged : bool
    message : str
    sweeps : int
        Block Gauss-Seidel sweeps, all rounds together.
    corrections : int
        Newton corrections of (d, alpha, beta) (load control only).
    growths : int
        Patch enlargements.
    linear_sweeps : int
        Sweeps of the sensitivity solves behind the corrections (each with 1 or 3
        right-hand sides).
    history : tuple of float
        Relative change after every sweep (eq. 9).
    coupling : dict
        How the cross-patch products were made: pairs per route (``dense``, ``fft``,
        ``separated``, ``spectral``; :class:`~.blocks.Coupling`) and ``separated_rtol``.
    merged : tuple of tuple of int
        Asperities solved together as one block (``merge``), one tuple per merged patch.
    reason : StopReason
        Why the iteration ended (``message`` says it in words); ``reason.converged`` is
        ``converged``.
    """

    patches: tuple
    pressures: tuple
    initial: tuple
    gaps: tuple
    penetration: float
    tilt: tuple | None
    converged: bool
    message: str
    sweeps: int
    corrections: int
    growths: int
    linear_sweeps: int
    history: tuple
    coupling: dict = field(default_factory=dict)
    merged: tuple = ()
    reason: StopReason = StopReason.CONVERGED

    def __post_init__(self) -> None:
        if self.reason.converged != bool(self.converged):
            raise ValueError(f"stop reason {self.reason} disagrees with converged={self.converged!r}")
