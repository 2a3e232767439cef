"""What memory costs, per cell and per part of a solve, as measured on this code.

The constants :mod:`twoscale.resources` turns counted cells into bytes with, and the
measured peaks they were checked against (:data:`CALIBRATION`). Bytes, mm.
"""

from __future__ import annotations

#: Resident memory of ``twoscale solve --out`` on a small scene: the interpreter with
#: numpy, scipy, meshio and matplotlib, bytes (measured: 110-150 MB).
BASE_BYTES = 1.6e8
#: Bytes per cell of a full grid solved by constrained CG (reference, or the micro
#: step's union box): heights, owners, pressure, gap and the CG's vectors, the kernel
#: spectrum on the zero-padded grid, the output files (VTK quads). Measured with the
#: FFT work below: 310-370 bytes per cell in all (CALIBRATION).
GRID_BYTES_PER_CELL = 250.0
#: Bytes per cell carried on patches (heights, owners, pressures, the patch's own FFT
#: operator, the output files); with the FFT work, measured 310 bytes per cell.
PATCH_BYTES_PER_CELL = 250.0
#: Transient FFT work of the largest patch or grid, bytes per cell: four complex arrays
#: on a grid padded to four times the cells (4 x 4 x 16).
FFT_WORK_BYTES_PER_CELL = 256.0
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
#: The finite-block provider (``[influence] kind = "block"``): building its FEM correction
#: for the default 140 x 140 x 20 mm block peaked at 1.03 GB (S1, cold cache; 0.13 GB
#: with the cache warm). Counted whether or not the cache is warm.
BLOCK_PROVIDER_BYTES = 1.0e9
#: Default share of the available memory a solve may use.
DEFAULT_FRACTION = 0.8
#: A refused solve suggests an h whose estimate is within this share of the limit, so that
#: following the advice does not start a solve at the machine's edge.
ADVICE_SHARE = 0.5

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
