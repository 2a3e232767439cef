"""The near pairs' displacement on whole patches, many patches at once.

The growth check (:func:`.workset.grow`: an asperity penetrating on cells another owns) and
the result's gaps ask for the displacement on every cell of a patch, the cells its
neighbours own included. A near pair whose dense block is kept gives it by that block on the
patch's own cells and by :func:`~.localblock.whole_patch` on the others (not an FFT operator
made for this one product: 2,370 of them on 939 scattered patches, the growth check's 0.4 s);
the pairs left to their routes are taken for all the patches asked together
(:func:`.spectral_pairs.route_sums`, whole patches): the sources' transforms of one shape in
one call and the targets' sums of one shape transformed back in one call, not three calls a
pair and a transform back a target (7,339 clustered spheres: ~3,800 targets a check).
"""

from __future__ import annotations

import numpy as np

from .localblock import whole_patch, whole_patch_is_large
from .spectral_pairs import route_sums

#: Target cells whose routed pairs are summed in one pass: their padded sums (complex, about
#: four times the patch) and transforms back are held together, ~64 bytes a cell (64 MB).
PART_CELLS = 1_000_000


def near_on_patches(coupling, ks, values: list) -> dict:
    """``{k: sum_{l near k} A_kl v_l}`` (mm) on the whole patch ``k`` (ny, nx) for the
    patches ``ks`` (1-D block vectors ``values``; ``coupling.near(k)`` the pairs)."""
    out, work = {}, []
    for k in ks:
        pt = coupling.patches[k]
        u, rest = np.zeros(pt.grid.shape), []
        for l in coupling.near(k):
            v = values[int(l)]
            if v is None or not np.count_nonzero(v):
                continue
            M = coupling._ops.get((k, int(l)))
            if M is None or whole_patch_is_large(pt, v):
                rest.append(int(l))
            else:
                u += whole_patch(coupling.provider, pt, M @ v, coupling.patches[int(l)], v)
        out[k] = u
        if rest:
            work.append((k, rest))
    for part in _parts(coupling.patches, work):
        for k, u in route_sums(coupling, part, values, whole=True).items():
            out[k] += u
    return out


def _parts(patches, work: list) -> list:
    """``work`` cut in runs whose targets' cells add up to at most :data:`PART_CELLS` (one
    target at least a run): the stacked sums and transforms back of a run are held at once."""
    runs: list = [[]]
    total = 0
    for item in work:
        cells = patches[item[0]].grid.size
        if runs[-1] and total + cells > PART_CELLS:
            runs.append([])
            total = 0
        runs[-1].append(item)
        total += cells
    return runs
