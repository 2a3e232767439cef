"""Memory a block's first answers will take to build: its factorisation, where the on-disk
cache lacks a lattice node's correction field that loads in a region need.

A provider solves the FEM model for the lattice nodes around the loaded points it is asked
about (:meth:`~fem_influence.provider.BlockProvider._ensure`): where every such node's field
was read from the cache, nothing is factorised; where one is missing, the whole model is
assembled and factorised first, which dominates the solve's memory on small scenes.
Bytes, mm.
"""

from __future__ import annotations

import math

import numpy as np

#: Peak of the factorisation and the lattice solves of the default block (140 x 140 x 20 mm,
#: bonded, the default mesh) beyond the interpreter: a cold cache's first solve of one
#: paraboloid peaked at 1.03 GB (S1) against 0.13 GB with the fields read from the cache.
FACTORISATION_BYTES = 1.0e9


def build_bytes(provider, rect: tuple[float, float, float, float]) -> float:
    """:data:`FACTORISATION_BYTES` when loads in ``rect`` ``(x0, x1, y0, y1)`` (mm, scene
    frame) need a lattice node's field the provider does not hold (read from its cache),
    else 0. Every node whose cubic stencil can reach ``rect`` is counted (a superset of
    those the solve asks for); a mirror-symmetric mesh solves only ``i, j >= 0``."""
    d = provider.source_spacing
    ox, oy = provider.origin
    bx0, bx1, by0, by1 = provider._lattice_bounds()
    x0, x1, y0, y1 = rect
    i = np.arange(max(bx0, math.floor((x0 + ox) / d) - 2), min(bx1, math.ceil((x1 + ox) / d) + 2) + 1)
    j = np.arange(max(by0, math.floor((y0 + oy) / d) - 2), min(by1, math.ceil((y1 + oy) / d) + 2) + 1)
    if not (len(i) and len(j)):
        return 0.0
    nodes = np.array(np.meshgrid(i, j, indexing="ij")).reshape(2, -1).T
    state = provider._state
    if np.all(state.column_of(nodes) >= 0):  # a warm cache holds the mirrored fields too
        return 0.0
    if provider.use_symmetry and state.mirror_permutations(provider.mesh) is not None:
        nodes = np.unique(np.abs(nodes), axis=0)
    return 0.0 if bool(np.all(state.column_of(nodes) >= 0)) else FACTORISATION_BYTES
