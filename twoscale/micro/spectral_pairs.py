"""The routed near pairs of many target blocks at once, their FFT products stacked.

:meth:`~.blocks.Coupling._sum` takes a target's pairs one by one: a pair on the spectral
route costs its source's padded transform (kept per block vector), a product with the
pair's kernel spectrum and, per target, one transform back: three calls and their Python
each, on transforms of a few thousand points (7,339 clustered spheres: ~4,100 such pairs a
sweep, ~70,000 in a solve). Here the targets of a sweep's level are taken together: the
sources' missing transforms of one padded shape in one call, the products pair by pair,
and the targets' sums of one shape transformed back in one call. Every pair's numbers are
those of its route (the stacked transforms are the same one-dimensional transforms), the
order of the sums aside.
"""

from __future__ import annotations

import numpy as np

from ..influence.convolution import ConvolutionOperator


def level_near(coupling, values: list, out: dict) -> dict:
    """``out[k] -= sum_{l near k} A_kl v_l`` (1-D, in place; returns ``out``) for the blocks
    of a sweep's level: each block's kept dense pairs and window gathers
    (:meth:`~.farfield.FarFieldCoupling._near_kept`), then the pairs left to their routes
    of all the blocks together (:func:`route_sums`)."""
    work = [(k, rest) for k, u in out.items() if (rest := coupling._near_kept(k, values, u))]
    for k, u in route_sums(coupling, work, values).items():
        out[k] -= u
    return out


def route_sums(coupling, work: list, values: list) -> dict:
    """``{k: sum_{l in sources} A_kl v_l}`` (mm) on block ``k``'s owned cells for ``work`` =
    ``[(k, sources)]`` (1-D block vectors ``values``), by the pairs' routes; a target
    whose sources carry no pressure is left out. Pairs off the spectral route, and every
    pair where the kernel has a split-off correction, as :meth:`~.blocks.Coupling._sum`."""
    if coupling._correction is not None:
        sums = {k: coupling._sum(k, sources, values, whole=False) for k, sources in work}
        return {k: u for k, u in sums.items() if u is not None}
    totals: dict = {}
    spectral, others = [], {}
    for k, sources in work:
        for l in sources:
            v = values[l]
            if v is None or not np.count_nonzero(v):
                continue
            kind, op, _ = coupling._route(k, l)
            if kind == "spectral" and isinstance(op, ConvolutionOperator):
                spectral.append((k, l, op))
            else:
                others.setdefault(k, []).append(l)
    for k, ls in others.items():
        _add(totals, k, coupling._sum(k, ls, values, whole=False))
    _spectra(coupling, spectral, values)
    sums: dict = {}  # per target and target key: the sum of its pairs' products
    for k, l, op in spectral:
        term = op.multiply(coupling._spectra[(l, op.source_key)][1])
        hit = sums.get((k, op.target_key))
        if hit is None:
            sums[(k, op.target_key)] = [op, term]
        else:
            hit[1] += term
    for k, u in _finished(coupling.patches, sums):
        _add(totals, k, u)
    return totals


def _add(totals: dict, k: int, u) -> None:
    if u is not None:
        totals[k] = u if k not in totals else totals[k] + u


def _spectra(coupling, pairs: list, values: list) -> None:
    """The sources' transforms the ``pairs`` ``(k, l, op)`` need and the coupling does not
    hold for their vectors, one call per transform and source shape, kept in the coupling's
    per-vector store (as :meth:`~.blocks.Coupling._spectrum` keeps them)."""
    missing: dict = {}
    for _, l, op in pairs:
        hit = coupling._spectra.get((l, op.source_key))
        if hit is None or hit[0] is not values[l]:
            missing.setdefault(op.source_key, (op, {}))[1][l] = values[l]
    for key, (op, vectors) in missing.items():
        stack = np.zeros((len(vectors), *op.source.shape))
        for i, (l, v) in enumerate(vectors.items()):
            pl = coupling.patches[l]
            stack[i, : pl.grid.ny, : pl.grid.nx][pl.owned] = v
        spectra = op.spectrum(stack)
        for i, (l, v) in enumerate(vectors.items()):
            coupling._spectra[(l, key)] = (v, spectra[i].copy())  # (not a view holding the stack)


def _finished(patches, sums: dict):
    """``(k, u)``: each target's summed products transformed back, those of one padded shape,
    source shape and target shape in one call (the transform back reads only the shapes),
    cut to the patch's owned cells."""
    groups: dict = {}
    for (k, _), (op, a) in sums.items():
        groups.setdefault((op.fft_shape, op.source.shape, op.target.shape), []).append((k, op, a))
    for members in groups.values():
        back = members[0][1].finish(np.stack([a for _, _, a in members]))
        for i, (k, _, _) in enumerate(members):
            pk = patches[k]
            yield k, back[i, : pk.grid.ny, : pk.grid.nx][pk.owned]
