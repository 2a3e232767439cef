"""Micro step of the two-scale method: the pressure on patches around the tips.

Read it in this order:

* driver and policy — :mod:`.driver` (:func:`~.driver.run_micro`: builds the patches from
  the macro forces, asks :mod:`.policy` (:func:`~.policy.choose`, priced by
  :mod:`.costmodel`) which iteration and coupling to run, runs it and, if it fails, the
  next, recording every attempt; :func:`~.driver.solve_micro`: one iteration with one
  coupling, without the policy); what every iteration receives is in :mod:`.problem`
  (:class:`~.problem.MicroProblem`, :class:`~.problem.BlockSettings`,
  :class:`~.problem.MicroContext`), what it returns in :mod:`.result`;
* iterations — :mod:`.strategies` (the objects :class:`~.strategies.BlockGaussSeidel`,
  :class:`~.strategies.TwoLevel`, :class:`~.strategies.UnionCG`, each saying which
  couplings it accepts); the block iterations are set up by :mod:`.setup` (patches,
  blocks, eq. 7 or :mod:`.start`'s warm start, merged blocks) and run by
  :mod:`.block_iterations` (growth, load and tilt corrections) over the sweeps of
  :mod:`.gauss_seidel` (eq. 8-9) or :mod:`.twolevel` (with the coarse correction of
  :mod:`.coarse`); load and moments in :mod:`.constraints`; the union CG is
  :mod:`.union`;
* couplings — :mod:`.couplings` (the objects :class:`~.couplings.Exact` and
  :class:`~.couplings.FarField`, each building its product engine):
  :class:`.blocks.Coupling` (every pair exactly: dense, separated or spectral route),
  :mod:`.farfield` (far pairs through their resultants, per block or held for a sweep,
  with the moment-matching sources of :mod:`.sources`);
* local solvers — :mod:`.localblock` (one block's operator and solves), :mod:`.local`
  (eq. 7 and the active-set contact solve on one block), :mod:`.pk` (a block's contact
  problems on the one Polonsky-Keer kernel :func:`twoscale.pk.pk_solve`),
  :mod:`.pk_stack` (the blocks of one size class solved as one stack);
* patches — :mod:`.patches` (one aligned patch per asperity, merging of close ones) and
  :mod:`.workset` (the patches, blocks and engine as the iterations grow them).
"""

from .driver import Attempt, MicroPlan, run_micro, solve_micro
from .patches import Patch, grow_patch
from .sampling import build_patches
from .policy import Choice, choose
from .problem import BlockSettings, MicroContext, MicroProblem
from .result import MicroResult

__all__ = [
    "Attempt",
    "BlockSettings",
    "Choice",
    "MicroContext",
    "MicroPlan",
    "MicroProblem",
    "MicroResult",
    "Patch",
    "build_patches",
    "choose",
    "grow_patch",
    "run_micro",
    "solve_micro",
]
