"""Classical full-grid reference solvers (the paper's p_r).

* :func:`solve_dense`: Johnson's matrix inversion with an active set (up to ~10^4 cells);
* :func:`solve_cg`: Polonsky & Keer's constrained conjugate gradient with FFT products;
* :func:`solve_reference`: picks one (``method="auto"``: dense up to
  :data:`AUTO_DENSE_CELLS` cells with material, CG beyond).

All take an influence provider and a :class:`~twoscale.indenters.Surface`, exactly one
of ``penetration`` (mm) or ``total_load`` (N), optionally ``tilt=True`` with a
``pivot`` (mm), and return a :class:`~twoscale.results.ContactResult`. Both solve the
same discrete problem (uniform pressure on square cells, collocation at the centres) and
agree to 1e-6 relative (tests/test_reference_agree.py).

Accuracy against Hertz (tests/test_reference_hertz.py; paraboloid R = 10 mm, E = 10 MPa,
nu = 0.5, d = 0.5 mm, tip at the corner of four cells), n = 2a/h cells across the contact:

=====  ===========  ==========  ============
n      L2 pressure  total load  contact area
=====  ===========  ==========  ============
16     2.0 %        0.16 %      3.5 %
32     0.88 %       0.034 %     0.96 %
64     0.45 %       0.0073 %    1.1 %
128    0.22 %       0.0019 %    0.25 %
=====  ===========  ==========  ============

The L2 error is first order in h (square-root edge of the pressure), the load error about
order 2. With the tip at a cell centre instead, n = 64 gives 0.62 % in L2.

Exact spheres (``shape="sphere"``) are not Hertz's setting: the cap
``R - sqrt(R^2 - r^2)`` rises faster than ``r^2 / 2R`` (by about ``r^4 / 8 R^3``), so at
the same penetration the contact is smaller and the load lower, by the fraction
``d / (10 R)`` to first order (0.5 % at d = R/20); they match Segedin's exact law
(:func:`twoscale.analytic.hertz.sphere_load`), which the tests check instead of Hertz.
"""

from __future__ import annotations

import numpy as np

from ..indenters import Surface
from ..influence.base import InfluenceProvider
from ..results import ContactResult
from .cg import solve_cg
from .dense import solve_dense

#: ``method="auto"`` uses the dense solver up to this many cells with material: there it
#: takes well under a second (a few factorisations of n^3/3 flops, 8 n^2 bytes) and meets
#: the KKT conditions to rounding; CG is faster at every size (Hertz, 1296 cells: 0.2 s
#: dense, 0.02 s CG) and is the only option beyond about 10^4 cells.
AUTO_DENSE_CELLS = 2000

REFERENCE_SOLVERS = {"dense": solve_dense, "cg": solve_cg}


def solve_reference(provider: InfluenceProvider, surface: Surface, *, method: str = "auto", **kwargs) -> ContactResult:
    """Solve on the full grid with ``method`` in {"auto", "dense", "cg"}.

    ``kwargs`` are those of :func:`solve_dense` / :func:`solve_cg` (penetration,
    total_load, tilt, pivot, tol, max_iter). ``"auto"`` picks dense when at most
    :data:`AUTO_DENSE_CELLS` cells have indenter material, otherwise CG.
    """
    if method == "auto":
        n = int(np.count_nonzero(np.isfinite(surface.height)))
        method = "dense" if n <= AUTO_DENSE_CELLS else "cg"
    if method not in REFERENCE_SOLVERS:
        raise ValueError(f"method must be 'auto', 'dense' or 'cg', got {method!r}")
    return REFERENCE_SOLVERS[method](provider, surface, **kwargs)


__all__ = ["solve_dense", "solve_cg", "solve_reference", "AUTO_DENSE_CELLS"]
