"""Micro step of the two-scale method (METHOD.md section 3).

* :mod:`.patches` — one aligned patch of cells per asperity, sized from the macro step;
* :mod:`.blocks` — the influence of a patch on itself (dense or FFT) and on the others;
* :mod:`.pk` — constrained conjugate gradients (Polonsky-Keer) with FFT products for large blocks;
* :mod:`.local` — local contact problems on one block: eq. 7 (initial pressure carrying the
  macro force) and the active-set solve used inside a sweep;
* :mod:`.gauss_seidel` — block Gauss-Seidel sweeps (eq. 8) and the stopping test (eq. 9);
* :mod:`.constraints` — outer corrections of the approach and tilt so the pressure carries
  the total load and the two moments;
* :mod:`.solve` — the micro step as a whole, :func:`solve_micro`.
"""
from .patches import Patch, build_patches, grow_patch
from .solve import MicroResult, solve_micro

__all__ = ["Patch", "build_patches", "grow_patch", "MicroResult", "solve_micro"]
