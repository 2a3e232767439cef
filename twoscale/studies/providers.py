"""Elastic bodies shared by the cases: built once per process, and the finite block's
correction computed once for the whole study.

A :class:`ProviderCache` belongs to one process (the serial run, or one Dask worker
through a worker plugin) and keeps the influence provider of each body it has met, keyed
by the body's influence settings and material, bounded in number of providers. Cases of
the same body on the same worker then share a provider and everything it keeps (a
block's factorisation and grid tables, the half-space's offset tables).

The finite block's correction fields live in an on-disk cache (``fem_influence``): a
file per mesh, material ratio and base, rewritten atomically (temporary file then
``os.replace``), so readers never see half a file. :func:`warm_blocks` computes, before
any case runs, every correction field the cases can ask for (the lattice around each
case's contact region) and writes it once; the workers then only read the file. Two
processes that do add fields at once each write their own temporary file (named by
process id): the last rename wins and the other's new fields are recomputed on demand,
never read half-written. Threads of one process must not share a block provider while
it adds fields (the temporary file name is per process), which is why the studies' Dask
workers run one thread each.
"""

from __future__ import annotations

from typing import Any, Iterable

import numpy as np

from ..influence.cache import BoundedCache

#: Providers a process keeps (least recently used dropped first).
MAX_PROVIDERS = 8


def provider_key(scene: Any) -> tuple:
    """What a provider depends on: the influence settings and the material."""
    inf = scene.influence
    return (
        inf["kind"],
        tuple(inf.get("size", ())),
        inf.get("base"),
        tuple(inf.get("origin", ())),
        float(scene.material.E),
        float(scene.material.nu),
    )


class ProviderCache:
    """Influence providers of one process, by :func:`provider_key`.

    Parameters
    ----------
    max_providers : int, default 8
        Bound on the number kept.
    """

    def __init__(self, max_providers: int = MAX_PROVIDERS):
        # each entry counts 1 "byte": the bound is a number of providers
        self._cache = BoundedCache(max_providers, name="study providers")

    def get(self, scene: Any):
        """The provider of ``scene``'s body, built on first use."""
        key = provider_key(scene)
        provider = self._cache.get(key)
        if provider is None:
            options = {"progress": False} if scene.influence["kind"] == "block" else {}
            provider = self._cache.put(key, scene.provider(**options), 1)
        return provider


def contact_box(scene: Any) -> tuple:
    """(xmin, xmax, ymin, ymax) mm covering every place contact can reach in ``scene``
    (the reference solver's grid for it, see :func:`twoscale.reference.on_scene.reference_grid`)."""
    from ..reference.on_scene import reference_grid
    from ..scene import default_h

    g = reference_grid(scene, default_h(scene))
    return (g.x0 - g.h, g.x0 + g.nx * g.h, g.y0 - g.h, g.y0 + g.ny * g.h)


def warm_blocks(scenes: Iterable[Any], *, progress: bool = False) -> dict:
    """Compute, once, the block correction every scene of ``scenes`` can need.

    For each block body, the source lattice around each scene's contact box is asked
    for (points every half source spacing over the box), which solves and stores on
    disk the nodes not yet known. Points outside the block's lattice are skipped (the
    case then fails with the block's own message). The providers built here are
    dropped: the processes that solve read the fields from disk.

    Returns
    -------
    dict
        Seconds spent per block body (``str`` of :func:`provider_key`).
    """
    import time

    boxes: dict = {}
    for sc in scenes:
        if sc.influence["kind"] == "block":
            boxes.setdefault(provider_key(sc), (sc, []))[1].append(contact_box(sc))
    spent = {}
    for key, (sc, bxs) in boxes.items():
        t0 = time.perf_counter()
        provider = sc.provider(progress=progress)
        d = 0.5 * provider.source_spacing
        pts = np.unique(np.concatenate([_sample(b, d) for b in bxs]), axis=0)
        inside = pts[_in_lattice(provider, pts)]
        if len(inside):
            provider.correction(np.zeros((1, 2)), inside)
        spent[str(key)] = time.perf_counter() - t0
    return spent


def _in_lattice(provider, points: np.ndarray) -> np.ndarray:
    """Which source points (scene frame) lie in the region the block answers for (its
    ``domain()``: the correction lattice; points beyond it are refused)."""
    x0, x1, y0, y1 = provider.domain()
    tol = 1e-9 * provider.source_spacing
    x, y = points[:, 0], points[:, 1]
    return (x >= x0 - tol) & (x <= x1 + tol) & (y >= y0 - tol) & (y <= y1 + tol)


def _sample(box: tuple, d: float) -> np.ndarray:
    """Points of a box on a lattice of spacing ``d`` (edges included), rounded to it."""
    x = np.arange(np.floor(box[0] / d), np.ceil(box[1] / d) + 1) * d
    y = np.arange(np.floor(box[2] / d), np.ceil(box[3] / d) + 1) * d
    X, Y = np.meshgrid(x, y)
    return np.column_stack([X.ravel(), Y.ravel()])
