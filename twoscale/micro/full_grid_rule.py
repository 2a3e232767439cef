"""When a default solve is its full grid's one constrained CG instead of the two-scale
iteration: the smallest scenes, and untilted tips crowding their grid. The full grid is the
reference solver's (:func:`twoscale.reference.on_scene.reference_grid`); the caller that
sizes it is :func:`twoscale.resources.full_grid_route`."""

from __future__ import annotations

#: A default solve whose full grid (the reference solver's, :func:`twoscale.reference.on_scene.
#: reference_grid`) has at most this many cells is that grid's one constrained CG: the
#: macro step, the patches and the policy then cost as much as the whole solve. Measured
#: on the scene-space sweep (CPU s, fresh processes, two-scale against the full grid):
#: grids of 2,500-3,100 cells 0.032-0.040 against 0.032-0.036 (1-2 tips, 0.9-1.2x) and 12
#: merged spheres 0.17 against 0.03 (the macro step's safe path alone 0.11 s); from 8,700
#: cells the two-scale solve ran at 0.5-1.1x (median 0.7).
FULL_GRID_MAX_CELLS = 5_000
#: The same on the half-space under penetration control. On the 47 sweep scenes of seeds 0-6 with at most 64
#: untilted tips on 5,000-14,000 cells (one interleaved run, load 5-7, each against its
#: reference's CPU): under penetration (29 scenes) the two-scale solve ran at 0.47-1.37x
#: the reference (8 above 1.0x: the macro step and the patches of tips whose union box is
#: most of the grid), the full grid's CG at 0.46-1.07x (median 0.71); under load (18)
#: the two-scale solve at 0.43-0.92x, the full grid at 0.51-1.04x, so that rule stays.
#: On 12,100-13,328 cells it ran at 0.47-0.77x, and on the paper's seven spheres (13,899
#: cells) at 0.72x against the full grid's 0.65x: the bound stays below them, where the
#: macro forces and the patches a user reads come with the answer. From 16,500 cells the
#: two-scale solve ran at 0.34-0.37x (seed 6's #75, #136).
FULL_GRID_MAX_CELLS_PENETRATION = 12_000
#: More tips than this: not tried for that route by cell count alone (sizing costs a loop).
FULL_GRID_MAX_TIPS = 64
#: An untilted tip scene whose full grid has at most this many cells a tip is that grid's
#: one CG too: the macro step and the patches cost 50-150 us a tip, the full grid's CG about
#: 5-9 us a cell. CPU s, two-scale against the full grid (fresh processes, penetration
#: control): 5,220 touching spheres on 55,696 cells (10.7 a tip) 0.68-0.83 against 0.51;
#: 7,610 paraboloids on 154,449 (20.3) 1.24 against 0.78; 9,129 on 346,921 (38) 1.19
#: against 1.82; 9,872 spheres under load and a free tilt on 291,060 (29.5) 5.0 against 24.
FULL_GRID_CELLS_PER_TIP = 25
#: Small grids: the union CG's box is about the grid, plus 0.2-0.3 ms a tip of macro step and patches.
#: CPU against the full grid: 79 spheres on 12,769 cells (162 a tip) 1.12x; 242 a tip 0.89x, 322 0.92x.
FULL_GRID_SMALL_CELLS = 20_000
FULL_GRID_SMALL_CELLS_PER_TIP = 200


def full_grid_max_cells(tips: int) -> int:
    """The largest full grid solved as its one CG by the cells-a-tip rules for ``tips`` tips."""
    return max(FULL_GRID_CELLS_PER_TIP * tips, min(FULL_GRID_SMALL_CELLS_PER_TIP * tips, FULL_GRID_SMALL_CELLS))


def full_grid_route(cells: int, tips: int = 0, penetration: bool = False) -> str | None:
    """The reason to solve a scene of ``tips`` untilted tips (0: not counted) whose full grid
    has ``cells`` cells whole (the default two-scale route's honest choice on the smallest
    scenes and on grids crowded with tips), or None. The sentence names no solver:
    :func:`twoscale.full_grid.full_grid_settings` picks the dense solve or the CG, and the
    result's message names the one that ran. ``penetration``: the
    scene is a half-space under penetration control (a larger grid of at most ``FULL_GRID_MAX_TIPS`` tips
    still pays, above)."""
    largest = FULL_GRID_MAX_CELLS_PENETRATION if penetration and tips <= FULL_GRID_MAX_TIPS else FULL_GRID_MAX_CELLS
    if cells <= largest:
        return (
            f"the full grid has {cells:,} cells (at most {largest:,}): solving it whole "
            "is the cheapest, the two-scale macro step alone costs as much"
        )
    if cells > full_grid_max_cells(tips):
        return None
    return (
        f"the full grid has {cells / tips:.3g} cells a tip (at most {full_grid_max_cells(tips) / tips:.3g}): "
        "solving it whole costs less than the macro step and the patches of its tips"
    )
