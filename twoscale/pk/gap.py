"""One check's projected gap in the Polonsky-Keer iteration (:class:`GapBuffers`).

The gap ``g = A p + z`` projected on the constraints over the loaded cells ``S = {p > 0}``,
and its part on them, are written into arrays kept from check to check (a fresh (B, n)
array each iteration page-faults). On long rows the loaded cells are kept as 0/1 floats
too, the factor of every masking product of the iteration: a product by them takes half
the time of one by the bools and gives the same values (7 against 13 us on 28,000 cells,
one copy of the bools 6 us), and under load control the masked gap kept for the mean
over ``S`` is the product the gap on them would take anyway (one temporary less).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .projection import SHORT_ROW, column, free_cells, project, row_count


class GapBuffers:
    """The kept arrays of :meth:`~.iteration.Iteration.gap`, reallocated when the live rows
    change."""

    def __init__(self):
        self.on: Any = None  # the loaded cells
        self.weights: Any = None  # the loaded cells as 0/1 floats (long rows)
        self.g: Any = None
        self.g_on: Any = None
        self.spare: Any = None  # a scratch array shaped like the gap
        self.free_at: Any = None  # the cells off the mask (:meth:`free`)

    def gap(self, p, u, z, k, basis, basis_t, plane):
        """The projected gap ``g``, the multipliers ``m`` (None without constraint), the
        loaded cells ``on``, ``g`` on them, the loaded cells' count per row (under load
        control, at least 1; else None) and their weights (:meth:`weigh`)."""
        if self.on is None or self.on.shape != p.shape:
            self.on, self.g, self.g_on = np.empty(p.shape, bool), np.empty_like(u), np.empty_like(u)
        on = np.greater(p, 0.0, out=self.on)
        w = self.weigh(on)
        g, m, count = np.add(u, z, out=self.g), None, None
        if k == 1:
            count = np.maximum(row_count(on), 1)
        if k == 1 and w is not on:  # the mean over ``on`` from g's product by the weights
            c = np.einsum("bi->b", np.multiply(g, w, out=self.g_on)) / count
            g -= column(c)
            m = c[:, None]
        elif k:
            m = project(g, basis, on, count, basis_t, plane)
        return g, m, on, np.multiply(g, w, out=self.g_on), count, w

    def weigh(self, on: np.ndarray) -> np.ndarray:
        """The loaded cells ``on`` as the masks' factor: on long rows 0/1 floats in a kept
        array, else ``on`` itself."""
        if on.shape[1] <= SHORT_ROW:
            return on
        if self.weights is None or self.weights.shape != on.shape:
            self.weights = np.empty(on.shape)
        np.copyto(self.weights, on)
        return self.weights

    def scratch(self, like: np.ndarray) -> np.ndarray:
        """A kept array shaped like ``like`` (overwritten by each caller)."""
        if self.spare is None or self.spare.shape != like.shape:
            self.spare = np.empty_like(like)
        return self.spare

    def free(self, mask: np.ndarray) -> np.ndarray:
        """The cells off ``mask`` as :func:`~.projection.kkt_residual` takes them fastest
        (:func:`~.projection.free_cells`: by index where few), kept while the live rows stay."""
        if self.free_at is None or self.free_at[1] != mask.shape:
            self.free_at = (free_cells(~mask), mask.shape)
        return self.free_at[0]
