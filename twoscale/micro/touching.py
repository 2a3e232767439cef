"""Contacts that touch: the asperities one block of the two-level iteration solves together.

Each cell belongs to the asperity nearest the body (:mod:`.patches`), so two tips that
share one contact (tips closer than their contact radii) split it along the line where
their surfaces cross, and their blocks meet there. Solved as two blocks, force moves
across that line by a fraction a sweep and the coarse step, which sees the two as tips
coupled through their smeared compliance, overshoots it: on 1,013 scattered spheres and on
281 paraboloids the far-field two-level iteration's change fell by only 0.83-0.86 a sweep,
and the sweep's largest resultant changes were, every sweep, one such pair's (tips 0.041
and 0.057 mm apart with contact radii of 0.07-0.16 mm), alternating in sign. One block over
such a pair solves it exactly in every sweep.

:func:`touching_groups` finds them from the start pressures (paper eq. 7: each tip's own
contact on its own cells): the patches whose loaded cells are within ``reach`` cells of
cells another patch's asperity owns, joined transitively. Patches whose contacts are apart stay
one block each (the coarse space keeps one unknown per block).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from .patches import Patch

#: Loaded cells of two patches at most this many cells apart (along each axis) make their
#: contacts touch: 1 is adjacent cells, including diagonally.
TOUCH_REACH = 1


def touching_groups(
    patches: Sequence[Patch], pressures: Sequence[np.ndarray], reach: int = TOUCH_REACH, only=None
) -> list[list[int]]:
    """Groups of patch indices whose contacts touch, directly or through others: a patch
    whose loaded cells (``pressures`` > 0 on its owned cells) lie within ``reach`` cells of
    a cell another patch's asperity owns (that asperity is nearer the body there, so the
    contact goes on into its cells; its own start may even be empty, where the macro step
    gave the pair's force to one tip). Every patch in exactly one group, groups in the
    order of their first patch. ``only``: the patches that can link to another (the others
    are not examined; :meth:`~.stop_cells.StopCells.loaded_touch`)."""
    n = len(patches)
    index = {m: k for k, pt in enumerate(patches) for m in pt.members}
    pairs: list[tuple[int, int]] = []
    for k in range(n) if only is None else only:
        pt, p = patches[k], pressures[k]
        others = ~pt.owned & (pt.owner >= 0)  # cells another asperity owns
        if not others.any():  # a patch apart from the others (most of scattered tips')
            continue
        loaded = np.zeros(pt.grid.shape, dtype=bool)
        loaded[pt.owned] = np.asarray(p) > 0.0
        if not loaded.any():
            continue
        near = _dilated(loaded, reach) & others
        pairs += [(k, index[m]) for m in np.unique(pt.owner[near]).tolist() if index.get(m, k) != k]
    rows, cols = np.array(pairs, dtype=int).reshape(-1, 2).T
    links = sparse.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    _, label = csgraph.connected_components(links, directed=False)
    groups: dict = {}
    for k in range(n):
        groups.setdefault(int(label[k]), []).append(k)
    return sorted(groups.values(), key=lambda g: g[0])


def _dilated(mask: np.ndarray, reach: int) -> np.ndarray:
    """``mask`` dilated by the square of ``2 reach + 1`` cells (cells outside count as
    unset), as ``scipy.ndimage.binary_dilation`` with that structure gives it, by shifted
    slices along each axis (its call cost 0.1-0.2 ms on patches of a few hundred cells,
    4,000 of them on 1,013 spheres)."""
    out = mask.copy()
    for axis in (0, 1):
        step = out.copy()
        for d in range(1, reach + 1):
            lo, hi = [slice(None)] * 2, [slice(None)] * 2
            lo[axis], hi[axis] = slice(d, None), slice(None, -d)
            step[tuple(lo)] |= out[tuple(hi)]
            step[tuple(hi)] |= out[tuple(lo)]
        out = step
    return out
