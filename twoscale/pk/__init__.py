"""Polonsky & Keer's constrained conjugate gradient, one kernel for every caller: the
full-grid reference (:mod:`twoscale.reference.cg`), one block of the micro step and the
stacked blocks of one size class (:mod:`twoscale.micro.pk`).

* :mod:`.kernel` — :func:`~.kernel.pk_solve` (the iteration on a stack of rows, its
  stopping rule :class:`~.kernel.Tolerance` and result :class:`~.kernel.PKResult`);
* :mod:`.products` — the products it takes (:class:`~.products.Products`: exact, a
  cheaper one for the search directions, the kernel's columns for a few changed cells);
* :mod:`.projection` — the constraint pieces: projection of the gap, restoring the load
  and moments, the residuals the stopping rule reads.
"""

from ..stopping import StopReason
from .kernel import Constraint, PKResult, Tolerance, pk_solve
from .products import Products

__all__ = ["Constraint", "PKResult", "Products", "StopReason", "Tolerance", "pk_solve"]
