"""Why an iteration stopped: one enumeration for every iterative solver of the package.

Control flow compares these members (like PETSc's ``KSPConvergedReason``); the sentence a
user reads (``result.message``) is derived from them and the numbers of the run.
"""

from __future__ import annotations

import enum


class StopReason(enum.Enum):
    """Outcome of an iteration."""

    #: The stopping test was met.
    CONVERGED = "converged"
    #: The iteration cap was reached first.
    MAX_ITER = "max_iter"
    #: The residual stopped decreasing (not halved over the allowed number of iterations),
    #: or would not reach the tolerance in the iterations left.
    STAGNATED = "stagnated"
    #: A search direction with ``t . A t <= 0`` (the operator is not positive definite on
    #: the contact, or rounding dominates).
    BREAKDOWN = "breakdown"
    #: The caller's own test ended the iteration early (e.g. to enlarge a patch).
    STOPPED = "stopped"
    #: A part of the iteration failed (e.g. a local solve), see the message.
    FAILED = "failed"

    @property
    def converged(self) -> bool:
        return self is StopReason.CONVERGED
