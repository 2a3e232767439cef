"""What memory costs, per cell and per part of a solve, as measured on this code.

The constants :mod:`twoscale.resources` turns counted cells into bytes with, and the
measured peaks they were checked against (:data:`CALIBRATION`). Bytes, mm.
"""

from __future__ import annotations

#: Resident memory of a small solve: the interpreter with numpy, scipy and the solvers'
#: modules, bytes (measured in fresh processes: 87-92 MB after the imports, 90-112 MB at the
#: peak of the sweep's smallest solves; ``twoscale solve --out`` with its writers 110-150 MB).
BASE_BYTES = 1.2e8
#: Bytes per cell of a full grid solved by constrained CG (reference, or the micro
#: step's union box): heights, owners, pressure, gap and the CG's vectors. With the FFT work
#: below, 300 bytes a cell: measured 180-225 on the reference (683,929-3.03 M cells) and
#: 260-390 on the union CG's boxes of the sweep (2.2-6.2 M cells, the patches included).
GRID_BYTES_PER_CELL = 150.0
#: Bytes per cell carried on patches (heights, owners, pressures, the patch's own FFT
#: operator, the output files), and per patch (its grid objects, operators' set-up): fitted
#: with the far field's terms to the peaks of 46 two-level runs of the sweep (seed 7, peaks
#: of 330-2,300 MB): 456 bytes a cell (with the far field's 144) and 83 kB a patch (with its
#: operator's 40), the fit's peaks within 0.79-1.24 of 41 of them; counted 10 % above.
PATCH_BYTES_PER_CELL = 350.0
PATCH_BYTES_EACH = 50e3
#: Bytes a patch holds where the union CG alone runs, its cells windows of the box sampled
#: once (:func:`twoscale.micro.sampling.patches_cut_from_box`): all that was live when the
#: union CG started, per patch, 3.9 kB on seed 8's #1 (7,285 patches) and 8.7 kB on #2
#: (2,941; tracemalloc).
PATCH_WINDOW_BYTES_EACH = 10e3
#: Patches sized by the indenters' reach where the macro step stalled far from a solution
#: (:mod:`twoscale.memory_stall`): each cell's height, owner and block mask, bytes (17,
#: their arrays'), and the peak while they are cut from their box sampled once, bytes per
#: box cell: measured on the sweep's seed 8 #112, 943 MB above the start for a box of
#: 30.6 M cells (476 MB resident after it: the box's heights and owners, 16 a cell).
REACH_PATCH_HELD = 17.0
REACH_BOX_SAMPLED = 32.0
#: The union CG's coarse correction (:mod:`twoscale.pk.coarse`, on boxes of at least its
#: ``MIN_CELLS``, built only where the loaded squares of 25 x 25 cells hold at most
#: ``MAX_FILL`` (0.2) of their cells, weighted by their loaded cells: ``fill = sum n_i^2 /
#: (side^2 sum n_i)``) holds its precorrected product's near pairs among the loaded cells
#: (:class:`twoscale.influence.precorrected.Precorrected`, Chebyshev radius 10 cells: the
#: pairs of a loaded cell grow with the fill about it) and the squares' dense matrix ``E``
#: with its Cholesky factor. Its build's peak over the memory before it, measured on the 17
#: union CG runs of seeds 6-8 where it was built (19-64 K loaded cells at fills 0.036-0.186,
#: 591-1,773 squares; 35-199 MB): a least-squares fit of ``loaded x fill`` and ``K^2`` gives
#: 13,800 bytes and 32 bytes (the peaks within 0.75-1.56 of the fit's counts below).
COARSE_BYTES_PER_LOADED_CELL_AND_FILL = 14_000.0
COARSE_BYTES_PER_SQUARE_PAIR = 32.0
#: The fill counted from the contacts with the neighbours' push, each spread over the squares
#: its bounding box meets, against the fill measured at the build (those 17 runs and 5 where
#: it was not built): 0.8-1.8 times it (the loaded cells spread over more squares), so the
#: correction is counted up to this times ``MAX_FILL``: every built one counted (seed 7's #61
#: at 1.46x: 565 MB in a fresh process against 355 counted without it), two of the five
#: others too (fills 0.27 counted 0.22-0.24).
COARSE_FILL_MARGIN = 1.5
#: Transient FFT work of the largest patch or grid, bytes per cell.
FFT_WORK_BYTES_PER_CELL = 150.0
#: Largest dense pair block of the cross-patch coupling, entries
#: (``twoscale.micro.blocks.Coupling``'s ``dense_max_entries``).
DENSE_PAIR_ENTRIES = 40_000
#: What the coupling holds per pair over its operators' own arrays (per-vector spectra and
#: moments beside them): fitted with the patches' costs above (1.1 x twice the arrays).
PAIR_HELD = 2.2
#: Share of a failed block attempt's memory (its operators and far field) still resident when
#: the union CG that follows it allocates, the heap trimmed between them
#: (:mod:`twoscale.micro.release`): 1,000 paraboloids, 508 MB resident after a two-level
#: trial that had peaked at 1,303 MB (the interpreter's 140 MB and 407 MB of live arrays
#: with the patches), about a third of what the attempt held above the patches.
BLOCK_ATTEMPT_HELD = 0.35
#: Budget of the cached cross-patch operators (dense pairs, and FFT / separated pairs:
#: ``twoscale.micro.blocks.Coupling``'s two caches of 4e8 bytes).
COUPLING_CACHE_BYTES = 8e8
#: The far field's point operator among the patches' nine stencil points and nine source
#: nodes each (the half-space's Ewald operator: near pairs, interpolation to and from its
#: mesh, the mesh's kernel spectrum), bytes per patch, held once (an earlier one is let go
#: before one is built anew). Measured 31 kB on 8,232 and 8,376 patches of the sweep's
#: scenes (8,897 spheres, 9,792 clustered paraboloids) and 27-36 kB on lattices of 300-9,000
#: patches; its build's own work adds about half of it for a moment.
FAR_OPERATOR_BYTES_PER_PATCH = 40e3
#: Patch half-width over the contact radius (``solve_twoscale``'s ``margin``).
MARGIN = 1.3
#: Cells a merged block may have over its members (``twoscale.micro.problem.MERGE_GROWTH``):
#: the largest block's FFT work is counted this much larger.
MERGE_GROWTH = 2.0
#: Largest number of asperities whose macro step holds the dense N x N matrix
#: (``twoscale.macro.solve.DENSE_MAX``).
MACRO_DENSE_MAX = 2000
#: The reference solver's dense branch: at most this many cells with material
#: (``twoscale.reference.AUTO_DENSE_CELLS``), the whole grid's matrix up to
#: ``MAX_DENSE_CELLS`` cells (``twoscale.reference.dense``).
DENSE_CELLS = 2000
DENSE_GRID_CELLS = 12_000
#: Default share of the available memory a solve may use.
DEFAULT_FRACTION = 0.8
#: A refused solve suggests an h whose estimate is within this share of the limit, so that
#: following the advice does not start a solve at the machine's edge.
ADVICE_SHARE = 0.5

#: (Recorded with the constants of then; the estimates here are not those of today.)
#: Measured peak resident memory of ``twoscale solve --quiet --out DIR`` (``/usr/bin/time``
#: ``%M``; 2 CPUs, numpy 2 / scipy FFT) against the estimate: (scene, method, h mm, cells
#: the solver carried, peak MB, estimate MB). "random50" / "random300": 50 / 300 spheres,
#: R 3-6 mm, z 0-0.1 mm, seed 0, on 25 / 60 mm squares under 75 / 450 N (E = 10 MPa).
CALIBRATION = (
    ("hertz_sphere", "reference", 0.13, 3_249, 112, 162),
    ("hertz_sphere", "twoscale", 0.13, 2_401, 131, 161),
    ("hertz_sphere", "reference", 0.02, 112_225, 136, 217),
    ("hertz_sphere", "twoscale", 0.02, 87_025, 151, 203),
    ("hertz_sphere", "reference", 0.008, 683_929, 339, 506),
    ("hertz_sphere", "twoscale", 0.008, 534_361, 297, 426),
    ("S1", "twoscale", 0.1, 15_279, 131, 221),
    ("S1", "reference", 0.1, 140_225, 147, 231),
    ("S1 on the block, cold FEM cache", "twoscale", 0.1, 15_279, 1032, 1221),
    ("paper_seven_spheres", "twoscale", 0.25, 11_211, 132, 171),
    ("paper_seven_spheres", "reference", 0.25, 13_899, 113, 167),
    ("random50", "twoscale", 0.028, 907_124, 629, 1075),
    ("random50", "reference", 0.028, 1_601_028, 694, 970),
    ("random50", "twoscale", 0.014, 3_615_196, 1925, 3025),
    ("random300", "twoscale", 0.028, 5_064_198, 2037, 3811),
)
