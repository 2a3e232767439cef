"""The stacked products through kept buffers (``GridOperator.kept_stack``,
:mod:`twoscale.influence.stacked`) against the stacked products through ``scipy.fft``'s
fresh arrays that they replace, bit for bit, and against the dense kernel: the float64 and
float32 zero-padded convolutions (a square canvas, a pair of unequal grids and the
transposed pair) and the circulant inverse (on the canvas's own torus and on a longer
one). The stacks shrink and grow between calls, as a stacked CG's rows leave it and a new
size class's first stack comes in; the products share one workspace, and a small one takes
a stack in parts."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.fft as sfft

from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace
from twoscale.influence.circulant import CirculantInverse, torus_shape
from twoscale.influence.stacked import Workspace

HS = HalfSpace(Material(E=10.0, nu=0.5))
H = 0.1

PAIRS = [
    (Grid(0.0, 0.0, H, 16, 16), None),
    (Grid(0.0, 0.0, H, 9, 8), None),
    (Grid(-0.3, 0.5, H, 7, 13), Grid(0.0, 0.0, H, 15, 8)),
]


def _scipy_stack(op, P: np.ndarray, dtype) -> np.ndarray:
    """The stacked product as it was made with ``scipy.fft`` (fresh padded arrays)."""
    (my, mx), (ny, nx) = op.fft_shape, op.source.shape
    padded = np.zeros((len(P), my, nx), dtype)
    padded[:, :ny] = P
    a = sfft.fft(sfft.rfft(padded, axis=-2, overwrite_x=True), n=mx, axis=-1, overwrite_x=True)
    if dtype == np.float32:
        a *= op._parent._khat.astype(np.complex64)
    else:
        a = op._times_kernel(a)
    sy, sx = ny - 1, nx - 1
    a = sfft.ifft(a, axis=-1, overwrite_x=True)[..., sx : sx + op.target.nx]
    return sfft.irfft(a, n=my, axis=-2)[..., sy : sy + op.target.ny, :].astype(np.float64)


def _operators(target, source):
    op = HS.grid_operator(target, source)
    yield op, np.float64
    yield op.transposed(), np.float64
    yield op.single_precision(), np.float32


@pytest.mark.parametrize("target,source", PAIRS)
@pytest.mark.parametrize("fields", [None, 2])
def test_kept_stack_products_equal_the_fresh_arrays_ones_bit_for_bit(target, source, fields):
    """One workspace for all the products (each call finds the others' values in it); with
    ``fields``, one so small that a stack goes through in parts of that many fields."""
    rng = np.random.default_rng(5)
    work = Workspace()
    for op, dtype in _operators(target, source if source is not None else target):
        kept = op.kept_stack(work)
        if fields is not None and work.nbytes == 0:
            work.limit = fields * kept._per_field  # (the float64 product's fields are the largest)
        for b in (4, 2, 3, 6, 1):  # shrinking, then growing
            P = rng.uniform(size=(b, *op.source.shape))
            P[P < 0.3] = 0.0
            got = kept(P)
            assert got.dtype == np.float64 and got.shape == (b, *op.target.shape)
            assert np.array_equal(got, _scipy_stack(op, P, dtype))
            assert np.array_equal(got, op.apply_stack(P))
        if fields is not None:
            assert work.nbytes <= work.limit + 64


def test_kept_stack_products_are_the_dense_kernel():
    target = Grid(0.0, 0.0, H, 9, 8)
    A = HS.cell_block(target.points(), target.points(), H)
    P = np.random.default_rng(2).uniform(size=(3, *target.shape))
    op = HS.grid_operator(target)
    want = np.stack([(A @ p.ravel()).reshape(target.shape) for p in P])
    assert np.allclose(op.kept_stack()(P), want, rtol=1e-12, atol=1e-14 * np.abs(want).max())
    assert np.allclose(op.single_precision().kept_stack()(P), want, rtol=0, atol=1e-6 * np.abs(want).max())


@pytest.mark.parametrize("side", [12, 130])
def test_kept_stack_inverse_equals_scipys_two_axis_transforms(side):
    g = Grid(0.0, 0.0, H, side, side - 3)
    inverse = CirculantInverse.of(HS.grid_operator(g), HS.grid_operator(g).offset_table, np.float32)
    assert (torus_shape(g) != g.shape) == (side >= 128)
    work = Workspace()
    kept = inverse.kept_stack(work)
    rng = np.random.default_rng(7)
    for b in (3, 1, 5, 4):
        if b == 4:  # in parts of one field, on the arrays the larger stack left
            work.limit = 1
        V = rng.normal(size=(b, *g.shape))
        a = sfft.rfft2(V.astype(np.float32), s=torus_shape(g))
        a *= inverse._m
        want = sfft.irfft2(a, s=torus_shape(g))[..., : g.ny, : g.nx].astype(np.float64)
        got = kept(V)
        assert np.array_equal(got, want)
        assert np.array_equal(got, inverse.apply_stack(V))
        if side < 128:  # the torus is the grid: the exact inverse of its circulant
            back = sfft.irfft2(sfft.rfft2(got) / inverse._m.astype(float), s=g.shape)
            assert np.allclose(back, V, atol=1e-5 * np.abs(V).max())


@pytest.mark.parametrize("target,source", PAIRS)
def test_staged_products_equal_the_scipy_transforms_bit_for_bit(target, source):
    """``spectrum`` and ``finish`` (the near pairs' staged products, and the stacked
    ``apply_stack``) give what ``apply``'s ``scipy.fft`` transforms give, one field or a stack."""
    from twoscale.influence.transforms import padded_transform as _transform

    source = target if source is None else source
    rng = np.random.default_rng(11)
    for op in (HS.grid_operator(target, source), HS.grid_operator(target, source).transposed()):
        for P in (rng.uniform(size=source.shape if op.source is source else target.shape), None):
            P = rng.uniform(size=(3, *op.source.shape)) if P is None else P
            s = op.spectrum(P)
            assert np.array_equal(s, _transform(P, op.fft_shape))
            got = op.finish(op.multiply(s))
            assert np.array_equal(got, op._finish(op.multiply(_transform(P, op.fft_shape))))
            if P.ndim == 2:
                assert np.array_equal(got, op.apply(P))
            else:
                assert np.array_equal(got, np.stack([op.apply(p) for p in P]))
