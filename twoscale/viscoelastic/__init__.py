"""Viscoelastic bodies (Prony series at constant Poisson's ratio) under load histories.

* :mod:`.prony`: relaxation modulus ``E(t)`` and the exact creep compliance ``J(t)``;
* :mod:`.history`: :class:`LoadHistory` (piecewise-linear total load or approach, output times);
* :mod:`.stepping`: :class:`TimeSteps` (automatic steps with an error estimate, or fixed);
* :mod:`.memory`: the creep-form memory and its exact step;
* :mod:`.steps`: a step as an elastic problem, for the reference and the two-scale solver;
* :mod:`.solve`: :func:`solve_history`, the driver (``twoscale.solve`` calls it for a scene with a history);
* :mod:`.closed_forms`: Lee-Radok creep and relaxation, Ting's unloading, for a paraboloid;
* :mod:`.moving`: :func:`solve_moving`, indenters moving under the body (rolling), with
  :mod:`.moving_indenter` (what moves), :mod:`.moving_result` and :mod:`.dissipation`
  (the energy the branches dissipate).

Users guide: docs/viscoelastic.md.
"""

from .history import LoadHistory
from .prony import CreepCompliance, creep_compliance, relaxation_modulus
from .stepping import TimeSteps


def solve_history(scene, **options):
    """See :func:`twoscale.viscoelastic.solve.solve_history`."""
    from .solve import solve_history as run

    return run(scene, **options)


def solve_moving(material, provider, indenter, motion, **options):
    """See :func:`twoscale.viscoelastic.moving.solve_moving`."""
    from .moving import solve_moving as run

    return run(material, provider, indenter, motion, **options)


__all__ = [
    "CreepCompliance",
    "LoadHistory",
    "TimeSteps",
    "creep_compliance",
    "relaxation_modulus",
    "solve_history",
    "solve_moving",
]
