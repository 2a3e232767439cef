"""What only one method reports: typed, frozen parts of :attr:`ContactResult.details`.

* :class:`TwoScaleDetails` (``method="twoscale"``): the macro step (:class:`MacroDetails`:
  tip forces, local approaches, how the interaction was held) and the micro step
  (:class:`MicroDetails`: the policy's choice, every attempt, the cross-patch coupling
  routes, merged patches, the paper's eq. 7 start ``p0``);
* :class:`BulgeDetails` (``method="twoscale"`` on a body whose surface may rise): the tips
  above the approach its rise lifted into contact, taken in or left;
* :class:`ReferenceDetails` (``method="reference"``): which full-grid solver ran and on
  what grid;
* :class:`SurfaceDetails` (either method, on a height map): what conditioning did to the
  map and which contacts reach its edge.

Indices are 0-based, as everywhere in Python (``merged_patches`` lists positions in
``scene.asperities``); files written for people number from 1.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np

from .results import FrozenMapping, frozen_array


@dataclass(frozen=True)
class MacroDetails:
    """The macro step: tip forces with elastic interaction (paper eqs. 3-5).

    Attributes
    ----------
    forces : (n,) array, N
        Tip force ``P_k`` of each asperity (scene order).
    local_penetrations : (n,) array, mm
        Argument of each asperity's law at the solution.
    converged : bool
    interaction : {"dense", "matrix-free"}
        How the interaction was held (an ``n x n`` matrix, or the provider's point operator).
    operator_error : float or None
        Matrix-free: measured relative error of the point operator at the solution.
    seconds : float
        Wall-clock time of the macro step.
    penetration : float or None
        The macro step's approach d, mm (the micro step corrects it under load control).
    tilt : (alpha, beta) or None
        The macro step's tilt angles, radians (with a ball-and-socket joint).
    """

    forces: np.ndarray
    local_penetrations: np.ndarray
    converged: bool
    interaction: str
    operator_error: float | None
    seconds: float
    penetration: float | None = None
    tilt: tuple | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "forces", frozen_array(self.forces))
        object.__setattr__(self, "local_penetrations", frozen_array(self.local_penetrations))


@dataclass(frozen=True)
class Coupling:
    """How the micro step made its cross-patch products: ordered patch pairs per route.

    ``dense`` (dense block), ``fft`` (plain FFT product), ``separated`` (low-rank separated
    operator, accurate to ``separated_rtol``), ``spectral`` (the kernel's
    translation-invariant part); all zero when no two patches were coupled. ``precorrected``:
    the union CG's products by a precorrected FFT on a sparse part of its box
    (:mod:`twoscale.influence.precorrected`), 0 where it took none.
    """

    dense: int = 0
    fft: int = 0
    separated: int = 0
    spectral: int = 0
    separated_rtol: float | None = None
    precorrected: int = 0

    @classmethod
    def of(cls, routes: Mapping) -> "Coupling":
        """From the micro step's route counts (:meth:`twoscale.micro.blocks.Coupling.route_counts`)."""
        return cls(
            **{
                k: routes[k]
                for k in ("dense", "fft", "separated", "spectral", "separated_rtol", "precorrected")
                if k in routes
            }
        )


@dataclass(frozen=True)
class MicroDetails:
    """The micro step: pressure on the patches (paper eqs. 6-9).

    Attributes
    ----------
    iteration : str
        What produced the answer, in words, with the attempts before it
        (e.g. ``"block Gauss-Seidel (union CG did not converge in 40 sweeps)"``).
    strategy : {"union-cg", "block-gs", "two-level"}
        The strategy of the last attempt (the one that gave the answer).
    choice : twoscale.micro.policy.Choice
        What the policy chose (or the caller fixed) and why: ``iteration``, ``far_tol``,
        ``reason`` (one sentence), ``by_caller``, ``estimates`` (read-only mapping of the
        scene figures and cost estimates behind the choice).
    attempts : tuple of twoscale.micro.driver.Attempt
        Every strategy run, in order (iteration, far_tol, converged, sweeps, seconds, message).
    coupling : Coupling
    merged_patches : tuple of tuple of int
        Asperities solved together as one block, 0-based positions in the scene.
    growths : int
        Patch enlargements.
    p0 : tuple of arrays or None
        The paper's eq. 7 pressure on each field's grid, MPa (None when not computed).
    p0_change_percent : float or None
        ``100 ||p0 - p|| / ||p||``.
    seconds : float
        Wall-clock time of the micro step.
    """

    iteration: str
    strategy: str
    choice: object
    attempts: tuple
    coupling: Coupling
    merged_patches: tuple
    growths: int
    p0: tuple | None
    p0_change_percent: float | None
    seconds: float

    def __post_init__(self) -> None:
        estimates = self.choice.estimates
        if not isinstance(estimates, FrozenMapping):  # frozen all the way down
            object.__setattr__(self, "choice", replace(self.choice, estimates=FrozenMapping(estimates)))
        object.__setattr__(self, "attempts", tuple(self.attempts))
        object.__setattr__(self, "merged_patches", tuple(tuple(int(k) for k in m) for m in self.merged_patches))


@dataclass(frozen=True)
class SurfaceDetails:
    """A height map solved as the indenter (``scene.surface``): the map as conditioned,
    and where the answer needs care.

    Attributes
    ----------
    source : str
        The file, or ``"array"`` for heights given in Python.
    samples : (ny, nx)
        Samples of the conditioned map (the solver's lattice).
    spacing : float
        Their spacing, mm (the cell size).
    measured_spacing : float or None
        The map's own spacing, mm, when it was resampled to ``spacing``; None when not.
    units : str
        Units the heights were given in (converted to mm).
    units_from : str
        ``"map"`` (the file or the RawMap declares them), ``"option"`` (``units`` given)
        or ``"default"`` (nothing said: mm, the relief being plausible in mm).
    missing : int
        Samples the map had no height for, on the conditioned lattice.
    fill : {"nearest", "mask"}
        How they were treated: filled from the nearest measured height, or without
        material (never in contact).
    edge_contacts : tuple of int
        Asperities (0-based) whose contact reaches the map's outermost samples, where the
        scan ends in a wall and the pressure is a punch corner's.
    """

    source: str
    samples: tuple
    spacing: float
    measured_spacing: float | None
    units: str
    units_from: str
    missing: int
    fill: str
    edge_contacts: tuple = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "samples", tuple(int(n) for n in self.samples))
        object.__setattr__(self, "edge_contacts", tuple(int(k) for k in self.edge_contacts))


@dataclass(frozen=True)
class BulgeDetails:
    """Tips above the approach that a body's rising surface lifts into contact
    (:mod:`twoscale.bulge_rounds`), on a body whose surface may rise, without a free tilt.

    Attributes
    ----------
    rounds : int
        Micro steps run again to take in the tips the solved surface reached (0: none).
    taken : tuple of int
        Tips above the approach given a patch for the surface's rise (0-based).
    left : tuple of int
        Tips still lifted after the rounds, deepest first (0-based): the answer lacks their
        contact (a :class:`~twoscale.errors.BulgeWarning` names them).
    left_gaps : tuple of float
        Their apexes' gaps to the solved surface, mm (negative: into it).
    """

    rounds: int = 0
    taken: tuple = ()
    left: tuple = ()
    left_gaps: tuple = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "taken", tuple(int(k) for k in self.taken))
        object.__setattr__(self, "left", tuple(int(k) for k in self.left))
        object.__setattr__(self, "left_gaps", tuple(float(g) for g in self.left_gaps))


@dataclass(frozen=True)
class TwoScaleDetails:
    """The two-scale method's own report: its macro step and its micro step (and, on a
    height map, :class:`SurfaceDetails`; on a body whose surface may rise, without a free
    tilt, :class:`BulgeDetails`)."""

    macro: MacroDetails
    micro: MicroDetails
    surface: SurfaceDetails | None = None
    bulge: BulgeDetails | None = None


@dataclass(frozen=True)
class ReferenceDetails:
    """The full-grid reference method's own report.

    Attributes
    ----------
    solver : {"dense", "cg"}
        Johnson's matrix inversion with an active set, or Polonsky-Keer's constrained CG.
    working_grid : (nx, ny) or None
        CG: the grid it iterated on (cropped to the cells that can touch).
    single_precision_iterations : int or None
        CG: iterations made in single precision before the double-precision ones.
    grid_enlargements : int or None
        On a scene: how many times the grid was enlarged because pressure reached its edge.
    surface : SurfaceDetails or None
        On a height map: the map as conditioned, contacts at its edge.
    """

    solver: str
    working_grid: tuple | None = None
    single_precision_iterations: int | None = None
    grid_enlargements: int | None = None
    surface: SurfaceDetails | None = None
