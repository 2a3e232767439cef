"""The memory of a two-scale solve whose macro step stalls far from a solution: its patches
are then sized by each indenter's reach, not by the macro forces.

With more than :data:`~twoscale.macro.solve.SAFE_PATH_MAX_TIPS` tips the macro step skips
its safe path and hands the micro step Newton's last iterate; where that iterate's residual
is above :data:`~twoscale.micro.problem.SIZING_RESIDUAL` its forces size nothing
(:meth:`~twoscale.micro.problem.MicroProblem.from_macro`). The micro step then samples one
patch per tip at the reach of the geometric approach ``d - z_k`` (the policy's patches,
kept to the end), and the block iterations with far-field coupling work on patches at the
reach of the local approach plus a fifth of the largest
(:func:`twoscale.micro.strategies._sizing`). Which scene stalls is not known before the
macro step runs, so the estimate counts this route beside the others and takes the larger
(:func:`twoscale.memory_parts.twoscale_parts`). Both approaches come from the neighbours'
mean push (:func:`twoscale.mean_field.mean_field`): on the sweep's seed 8 #112 (1,916
clustered spheres under load, stalled at a residual of 1.5e-2) it gave the level 0.285 mm
against the macro step's 0.282 and 8.10 M / 2.42 M cells against the 8.13 M / 2.44 M the
solve sampled and carried (the count without it: 1.45 M). Bytes, mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .macro.solve import SAFE_PATH_MAX_TIPS
from .mean_field import mean_field, reaches
from .grid import Grid
from .memory_costs import REACH_BOX_SAMPLED, REACH_PATCH_HELD
from .micro.sampling import BOX_CELLS_PER_PATCH, BOX_MIN_PATCH_SHARE
from .scene import Scene

#: Share of the largest local approach added to every tip's where the far field sizes the
#: patches (:func:`twoscale.micro.strategies._sizing`).
SIZING_SHARE = 0.2


def stall_possible(scene: Scene) -> bool:
    """Whether the macro step may hand the micro step a stalled iterate (it skips its safe
    path on more than :data:`~twoscale.macro.solve.SAFE_PATH_MAX_TIPS` tips)."""
    return len(scene.asperities) > SAFE_PATH_MAX_TIPS and scene.surface is None


def reach_half_widths(scene: Scene, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Half-widths (mm, 0: no patch) of the patches a stalled macro step leaves: the
    policy's, at the reach of the geometric approach, and the far field's block iterations',
    at the reach of ``min(d - z_k, local_k + SIZING_SHARE max local)`` (both plus a cell)."""
    field = mean_field(scene)
    local = field.local
    sizing = np.minimum(field.geometric, local + SIZING_SHARE * max(float(local.max(initial=0.0)), 0.0))
    return _reach(scene, field.geometric, h), _reach(scene, sizing, h)


def _reach(scene: Scene, delta: np.ndarray, h: float) -> np.ndarray:
    return np.where(delta > 0, reaches(scene, delta) + h, 0.0)


@dataclass(frozen=True)
class StalledPatches:
    """What a stalled macro step leaves the micro step (:func:`stalled_patches`).

    Attributes
    ----------
    work : (N,) array
        Half-widths of the far field's working patches, mm (0: none).
    policy_cells : float
        Cells of the policy's patches at the geometric reach (their sum, overlaps counted).
    policy_box : Grid
        The box covering them.
    sampled : bool
        Whether they are cut from their box sampled once (:func:`twoscale.micro.sampling.sampled_patches`).
    """

    work: np.ndarray
    policy_cells: float
    policy_box: Grid
    sampled: bool

    @property
    def sampling_bytes(self) -> float:
        """Peak while the policy's patches are sampled, bytes (their box's heights and
        owners and the sampling's work, ``REACH_BOX_SAMPLED`` a box cell; one by one, each
        patch's arrays, ``REACH_PATCH_HELD`` a cell)."""
        return REACH_BOX_SAMPLED * self.policy_box.size if self.sampled else REACH_PATCH_HELD * self.policy_cells

    @property
    def held_bytes(self) -> float:
        """The policy's patches kept beside the block iterations' (copied out of their box:
        :func:`twoscale.micro.sampling.detached`), bytes."""
        return REACH_PATCH_HELD * self.policy_cells


def stalled_patches(scene: Scene, h: float, tips: np.ndarray) -> StalledPatches:
    """The patches a stalled macro step leaves on ``scene`` at cell size ``h`` (mm; ``tips``
    (N, 2) mm, the scene's)."""
    policy, work = reach_half_widths(scene, h)
    cells = _cells(policy, h)
    box = patch_box(tips, policy, h)
    count = int((policy > 0).sum())
    sampled = cells >= BOX_MIN_PATCH_SHARE * box.size or box.size <= BOX_CELLS_PER_PATCH * count
    return StalledPatches(work, cells, box, bool(sampled))


def patch_box(tips: np.ndarray, r: np.ndarray, h: float) -> Grid | None:
    """The grid covering the patches of half-widths ``r`` (mm, 0: none) about ``tips``
    ((N, 2) mm); None without a patch."""
    on = r > 0
    if not np.any(on):
        return None
    x, y, rr = tips[on, 0], tips[on, 1], r[on]
    return Grid.covering(float((x - rr).min()), float((x + rr).max()), float((y - rr).min()), float((y + rr).max()), h)


def _cells(r: np.ndarray, h: float) -> float:
    on = r > 0
    return float(((np.floor(2.0 * r[on] / h) + 1.0) ** 2).sum())
