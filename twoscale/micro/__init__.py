"""Micro step of the two-scale method: the pressure on patches around the tips.

Read it in this order:

* driver and policy — :mod:`.driver` (:func:`~.driver.run_micro`: builds the patches from
  the macro forces, runs the chosen iteration and, if it fails, the next, recording every
  attempt) and :mod:`.policy` (:func:`~.policy.choose`: which iteration and coupling, by a
  cost estimate from the patches, with its reason);
* strategies — :mod:`.union` (one constrained CG over the box of the patches),
  :mod:`.solve` (the block iterations: eq. 7, block Gauss-Seidel (eq. 8-9) with load and
  tilt corrections, or the two-level variant of :mod:`.twolevel`), :mod:`.gauss_seidel`
  (the sweeps), :mod:`.coarse` and :mod:`.constraints` (load, moments, coarse correction);
  couplings between patches: :class:`.blocks.Coupling` (exact) and :mod:`.farfield` (far
  patches through their resultants);
* local solvers — :mod:`.local` (eq. 7 and the active-set solve on one block), :mod:`.pk`
  (a block's contact problems, eq. 7 and 8, on the one Polonsky-Keer kernel
  :func:`twoscale.pk.pk_solve`), :mod:`.pk_stack` (the blocks of one size class solved as
  one stack), :mod:`.blocks` (a block's own influence);
* patches — :mod:`.patches` (one aligned patch per asperity, merging of close ones) and
  :mod:`.workset` (the patches as the iterations grow them).
"""
from .driver import Attempt, MicroPlan, run_micro
from .patches import Patch, build_patches, grow_patch
from .policy import Choice, choose
from .result import MicroResult
from .solve import solve_micro

__all__ = ["Attempt", "Choice", "MicroPlan", "MicroResult", "Patch", "build_patches", "choose", "grow_patch",
           "run_micro", "solve_micro"]
