"""Classical full-grid reference solvers (the paper's p_r).

* :func:`solve_dense`: Johnson's matrix inversion with an active set (up to ~10^4 cells);
* :func:`solve_cg`: Polonsky & Keer's constrained conjugate gradient with FFT products;
* :func:`solve_reference`: picks one (``method="auto"``: dense up to
  :data:`AUTO_DENSE_CELLS` cells with material, CG beyond).

All take an influence provider and a :class:`~twoscale.indenters.Surface`, exactly one
of ``penetration`` (mm) or ``total_load`` (N), optionally ``tilt=True`` with a
``pivot`` (mm), and return a :class:`~twoscale.results.ContactResult`.
"""
from __future__ import annotations

import numpy as np

from ..indenters import Surface
from ..influence.base import InfluenceProvider
from ..results import ContactResult
from .cg import solve_cg
from .dense import solve_dense

#: ``method="auto"`` uses the dense solver up to this many cells with material: below it
#: a factorisation (n^3/3 flops, 8 n^2 bytes) costs about as much as CG and is exact.
AUTO_DENSE_CELLS = 2000

METHODS = {"dense": solve_dense, "cg": solve_cg}


def solve_reference(provider: InfluenceProvider, surface: Surface, *, method: str = "auto",
                    **kwargs) -> ContactResult:
    """Solve on the full grid with ``method`` in {"auto", "dense", "cg"}.

    ``kwargs`` are those of :func:`solve_dense` / :func:`solve_cg` (penetration,
    total_load, tilt, pivot, tol, max_iter). ``"auto"`` picks dense when at most
    :data:`AUTO_DENSE_CELLS` cells have indenter material, otherwise CG.
    """
    if method == "auto":
        n = int(np.count_nonzero(np.isfinite(surface.height)))
        method = "dense" if n <= AUTO_DENSE_CELLS else "cg"
    if method not in METHODS:
        raise ValueError(f"method must be 'auto', 'dense' or 'cg', got {method!r}")
    return METHODS[method](provider, surface, **kwargs)


__all__ = ["solve_dense", "solve_cg", "solve_reference", "AUTO_DENSE_CELLS"]
