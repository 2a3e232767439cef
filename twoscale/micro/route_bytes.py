"""Which of a near pair's two kept operators holds fewer bytes.

A pair too large for a dense block takes the separated route (a Chebyshev low-rank block,
:mod:`twoscale.influence.separated`) or the spectral one (the kernel's half-spectrum on the
zero-padded transform of the two patches enlarged to their size classes). Both are kept for
the whole solve within the coupling's budget; past it a pair's operator is made again at
every product. Near pairs (those the far field leaves exact) are close for their size, and
their Chebyshev blocks are large: on 2,966 lattice patches of ~1,700 cells (seed 9's #98)
the separated operators took a median 282 KB against the spectra's 133 KB, so 3,864
separated routes filled the budget (800 MB) and 1,957 pairs made a separated operator again
at each of the six sweeps (1.3 ms of Love's far field each). The route holding fewer bytes
keeps them all (6,531 routes, 403 MB). Where the preferred Chebyshev blocks fit the budget
they stay (:func:`preferred_bytes`): their products need no transforms.
"""

from __future__ import annotations

from scipy.fft import next_fast_len

from ..influence.separated import plan, relative_frames


def spectrum_bytes(target, source) -> int:
    """Bytes of the kernel's half-spectrum on the zero-padded transform of the pair's grids
    ``target``, ``source`` (:class:`~twoscale.influence.convolution.ConvolutionOperator`:
    the linear convolution's ``ny_t + ny_s - 1`` by ``nx_t + nx_s - 1``, each to a fast
    length, halved along y)."""
    my = next_fast_len(target.ny + source.ny - 1, real=True)
    mx = next_fast_len(target.nx + source.nx - 1, real=True)
    return 16 * (my // 2 + 1) * mx


def chebyshev_bytes(target, source, rtol: float) -> float:
    """Bytes of the node-to-node kernel of the pair's Chebyshev block within ``rtol``
    (:func:`~twoscale.influence.separated.plan`: a lower bound of the operator's, which adds
    the interpolation matrices); 0 where the plan has none (the pair is too close)."""
    sep = plan(*relative_frames(target, source), rtol)
    if sep is None:
        return 0.0
    qtx, qty, qsx, qsy = sep.q
    return 8.0 * qtx * qty * qsx * qsy


def spectrum_is_smaller(target, source, big_target, big_source, rtol: float) -> bool:
    """Whether the pair ``target``, ``source`` (its grids; ``big_*`` enlarged to their size
    classes, as the spectral route takes them) holds fewer bytes as a spectrum than as the
    Chebyshev block the plan would make."""
    return chebyshev_bytes(target, source, rtol) > spectrum_bytes(big_target, big_source)


def preferred_bytes(patches, pairs, dense_max_entries: int, rtol: float | None, enlarged) -> float:
    """Bytes the routes of ``pairs`` ``(k, l)`` (one direction each: the reverse pair is its
    transpose) hold with the Chebyshev block preferred wherever the plan has one, the
    kernel's part only (a lower bound); pairs within ``dense_max_entries`` take dense blocks
    and are not counted. ``enlarged(grid)``: the grid the spectral route takes."""
    total = 0.0
    for k, l in pairs:
        pk, pl = patches[k], patches[l]
        if int(pk.owned.sum()) * int(pl.owned.sum()) <= dense_max_entries:
            continue
        cheb = 0.0 if rtol is None else chebyshev_bytes(pk.grid, pl.grid, rtol)
        total += cheb if cheb else spectrum_bytes(enlarged(pk.grid), enlarged(pl.grid))
    return total
