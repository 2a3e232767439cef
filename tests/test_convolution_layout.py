"""The half-space's zero-padded FFT operator (``ConvolutionOperator``) keeps its kernel as a
spectrum in one layout (real transform along y, complex along x) that every user shares:
the product and the stacked product, the staged ``spectrum``/``multiply``/``finish``, the
float32 twin, the transposed pair, the kernel's columns and the circulant preconditioner.
Each is checked here against a construction that does not go through that spectrum: the
Love cell kernel summed densely, and the circulant of the wrapped kernel built entry by
entry. The grids include an odd padded length along y (the axis whose half is kept)."""

from __future__ import annotations

import numpy as np
import pytest

from twoscale import Material
from twoscale.grid import Grid
from twoscale.influence import HalfSpace

HS = HalfSpace(Material(E=10.0, nu=0.5))
H = 0.1


def _dense(target: Grid, source: Grid) -> np.ndarray:
    return HS.cell_block(target.points(), source.points(), H)


# (target, source): self pairs with an even and an odd padded y length (8 rows: 15), and
# a pair of unequal grids that overlap
PAIRS = [
    (Grid(0.0, 0.0, H, 9, 8), None),
    (Grid(0.0, 0.0, H, 12, 10), None),
    (Grid(-0.3, 0.5, H, 7, 13), Grid(0.0, 0.0, H, 15, 8)),
]


@pytest.mark.parametrize("target,source", PAIRS)
def test_products_equal_the_dense_kernel_in_every_form(target, source):
    source = target if source is None else source
    op = HS.grid_operator(target, None if source is target else source)
    rng = np.random.default_rng(3)
    P = rng.uniform(size=(3, *source.shape))
    M = _dense(target, source)
    want = np.stack([(M @ p.ravel()).reshape(target.shape) for p in P])
    scale = np.abs(want).max()
    assert np.abs(op.apply(P[0]) - want[0]).max() <= 1e-13 * scale
    assert np.abs(op.apply_stack(P) - want).max() <= 1e-13 * scale
    # the staged form: two sources' spectra multiplied and summed before one finish
    staged = op.finish(op.multiply(op.spectrum(P[0])) + op.multiply(op.spectrum(P[1])))
    assert np.abs(staged - (want[0] + want[1])).max() <= 1e-13 * scale
    # float32 transforms with the same spectrum: float32 rounding only
    assert np.abs(op.single_precision().apply(P[0]) - want[0]).max() <= 1e-6 * scale
    # its float64 product through buffers of its own: the operator's product to the bit
    assert np.array_equal(op.single_precision().exact(P[0]), op.apply(P[0]))
    # the transposed pair: the dense transpose
    back = op.transposed()
    q = rng.uniform(size=target.shape)
    assert np.abs(back.apply(q) - (M.T @ q.ravel()).reshape(source.shape)).max() <= 1e-13 * scale


@pytest.mark.parametrize("target,source", PAIRS)
def test_the_padded_table_and_the_columns_are_the_kernel_itself(target, source):
    source = target if source is None else source
    op = HS.grid_operator(target, None if source is target else source)
    my, mx = target.ny + source.ny - 1, target.nx + source.nx - 1
    table = op.padded_table()
    assert table.shape == op.fft_shape
    # entry (m, n): the kernel at lattice offset (target's first cell - source's last) + (m, n)
    ti, tj = target.offset_in(source)
    oy, ox = tj - (source.ny - 1), ti - (source.nx - 1)
    dy, dx = np.meshgrid((oy + np.arange(my)) * H, (ox + np.arange(mx)) * H, indexing="ij")
    love = HS.cell_block(np.c_[dx.ravel(), dy.ravel()], np.zeros((1, 2)), H).reshape(my, mx)
    assert np.abs(table[:my, :mx] - love).max() <= 1e-13 * love.max()
    rest = table.copy()
    rest[:my, :mx] = 0.0
    assert np.abs(rest).max() <= 1e-13 * love.max()  # the padding carries nothing
    add = op.columns()
    out = np.zeros(target.size)
    cells, values = np.array([0, source.size - 1, source.size // 2]), np.array([1.5, -0.5, 2.0])
    add(out, cells, values)
    assert np.abs(out - _dense(target, source)[:, cells] @ values).max() <= 1e-13 * love.max()


@pytest.mark.parametrize("shape", [(8, 9), (10, 12)])
def test_the_preconditioner_inverts_the_wrapped_kernels_circulant(shape):
    """The preconditioner is the inverse of the circulant whose first column is the kernel
    wrapped onto the grid's torus (offsets -(n // 2) .. (n - 1) // 2 per axis): built here
    entry by entry from Love's kernel, its product undone by the preconditioner."""
    ny, nx = shape
    g = Grid(0.0, 0.0, H, nx, ny)
    op = HS.grid_operator(g)
    oy = np.where(np.arange(ny) <= (ny - 1) // 2, np.arange(ny), np.arange(ny) - ny)
    ox = np.where(np.arange(nx) <= (nx - 1) // 2, np.arange(nx), np.arange(nx) - nx)
    dy, dx = np.meshgrid(oy * H, ox * H, indexing="ij")
    wrapped = HS.cell_block(np.c_[dx.ravel(), dy.ravel()], np.zeros((1, 2)), H).reshape(ny, nx)
    jy, jx = np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij")
    C = np.empty((g.size, g.size))
    for k, (a, b) in enumerate(zip(jy.ravel(), jx.ravel())):
        C[:, k] = wrapped[(jy - a) % ny, (jx - b) % nx].ravel()
    v = np.random.default_rng(5).standard_normal(g.size)
    for pc, rtol in ((op.preconditioner(), 1e-12), (op.single_precision().preconditioner(), 1e-5)):
        back = pc.apply((C @ v).reshape(g.shape)).ravel()
        assert np.abs(back - v).max() <= rtol * np.abs(v).max()


def test_a_smaller_grid_restricted_from_the_kept_table_is_the_kernel_on_it():
    """The operator of a window's cut made from the window's offset table (no kernel
    evaluated) multiplies like the dense Love kernel on the cut, and its own offset table
    is that window of the larger one; before the table is made, or for a larger grid or
    another spacing, there is none."""
    big, cut = Grid(0.0, 0.0, H, 12, 10), Grid(0.4, -0.2, H, 7, 9)
    op = HS.grid_operator(big)
    assert op.restricted(cut) is None  # (no offset table yet)
    op.offset_table()
    small = op.restricted(cut)
    p = np.random.default_rng(3).random(cut.shape)
    dense = _dense(cut, cut) @ p.ravel()
    assert np.abs(small.apply(p).ravel() - dense).max() <= 1e-13 * np.abs(dense).max()
    own = HS.grid_operator(cut).offset_table()
    assert np.abs(small.offset_table() - own).max() <= 1e-13 * own.max()
    assert op.restricted(Grid(0.0, 0.0, H, 13, 10)) is None
    assert op.restricted(Grid(0.0, 0.0, 2 * H, 6, 5)) is None


def test_the_kept_buffers_carry_nothing_from_one_product_to_the_next():
    """The float32 product and the circulant inverse of one field run through buffers kept
    with the operator (the inverse's transforms along x pruned to the field's rows on a
    torus longer than the grid): a second field's result is its own, the float32 product
    within float32 rounding of the float64 one and the inverse equal to the unpruned
    transform of a stack of one field."""
    g = Grid(0.0, 0.0, H, 131, 140)  # sides from 128 cells: a torus longer than the grid
    op = HS.grid_operator(g)
    single = op.single_precision()
    inverse = single.preconditioner()
    assert inverse is not None
    rng = np.random.default_rng(7)
    for _ in range(2):
        p = rng.uniform(size=g.shape) * (rng.uniform(size=g.shape) < 0.3)
        want = op.apply(p)
        assert np.abs(single.apply(p) - want).max() <= 1e-6 * np.abs(want).max()
        stacked = inverse.apply(p[None])[0]  # (the unpruned transforms)
        assert np.abs(inverse.apply(p) - stacked).max() <= 1e-6 * np.abs(stacked).max()


@pytest.mark.parametrize("dropped", [False, True])
def test_the_offset_table_is_gathered_again_from_the_kept_kernel_values(monkeypatch, dropped):
    """With the caller's cache of Love values the operator's offset table is gathered from
    it again (no inverse transform of the spectrum); when the values have left the cache,
    it comes back from the spectrum. Either way it is Love's kernel on the offsets."""
    from twoscale.influence import convolution
    from twoscale.influence.cache import BoundedCache

    grid = Grid(0.0, 0.0, H, 23, 17)
    my, mx = 2 * grid.ny - 1, 2 * grid.nx - 1
    dy, dx = np.meshgrid((np.arange(my) - grid.ny + 1) * H, (np.arange(mx) - grid.nx + 1) * H, indexing="ij")
    love = HS.cell_block(np.c_[dx.ravel(), dy.ravel()], np.zeros((1, 2)), H).reshape(my, mx)
    tables = BoundedCache(1e8)
    op = HS.grid_operator(grid, tables=tables)
    if dropped:
        tables.pop(("love-quadrant", H))
    inverses = []
    inverse = convolution._inverse
    monkeypatch.setattr(convolution, "_inverse", lambda *a: inverses.append(1) or inverse(*a))
    table = op.offset_table()
    assert len(inverses) == int(dropped)
    assert table.shape == (my, mx) and np.abs(table - love).max() <= 1e-13 * love.max()


def test_the_products_on_a_set_of_cells_are_the_grids_products_there():
    """The float32 product and the circulant inverse on the flat cells of a part of the grid
    (``on_cells``: the part's values straight into padded fields of their own) give the
    grid's products on those cells to the bit, product after product, beside products of
    whole fields through the same kept buffers."""
    g = Grid(0.0, 0.0, H, 131, 140)
    single = HS.grid_operator(g).single_precision()
    inverse = single.preconditioner()
    assert inverse is not None
    rng = np.random.default_rng(11)
    cells = np.flatnonzero(rng.uniform(size=g.size) < 0.2)
    product, inverted = single.on_cells(cells), inverse.on_cells(cells)
    assert product is not None and inverted is not None
    for _ in range(2):
        p = np.zeros(g.size)
        p[cells] = rng.uniform(size=cells.size)
        whole = rng.uniform(size=g.shape)  # a whole field between the part's products
        single.apply(whole), inverse.apply(whole)
        field = p.reshape(g.shape)
        assert np.array_equal(product(p[cells]), single.apply(field).ravel()[cells])
        assert np.array_equal(inverted(p[cells]), inverse.apply(field).ravel()[cells])


@pytest.mark.parametrize("shape", [(131, 140), (38, 37)])
def test_a_part_product_in_two_halves_is_the_product_and_its_energy_the_inner_product(shape):
    """The float32 product on a part's cells begun and finished is the whole call to the bit,
    and the Parseval sum of its forward transforms is ``v.A v`` (the float64 product's) to
    the float32 spectrum's rounding, on padded lengths even and odd."""
    g = Grid(0.0, 0.0, H, *shape[::-1])
    op = HS.grid_operator(g)
    single = op.single_precision()
    rng = np.random.default_rng(3)
    cells = np.flatnonzero(rng.uniform(size=g.size) < 0.3)
    product = single.on_cells(cells)
    assert product is not None
    for _ in range(2):
        v = rng.standard_normal(cells.size)
        whole = product(v)
        energy = product.forward(v).energy()
        assert np.array_equal(product.finish(), whole)
        p = np.zeros(g.size)
        p[cells] = v
        exact = float(p @ op.apply(p.reshape(g.shape)).ravel())
        assert energy == pytest.approx(exact, rel=1e-6)
    with pytest.raises(RuntimeError, match="forward"):
        product.finish()


@pytest.mark.parametrize("chunk", [1, 700, 1 << 18])
def test_the_energy_weights_made_in_blocks_give_the_inner_product(monkeypatch, chunk):
    """The Parseval weights made block by block of the half-spectrum's rows (one row, a few
    rows, all at once) are the whole spectrum's phase-shifted real part, and the step's
    ``v.A v`` from them is the float64 product's to the float32 spectrum's rounding."""
    from twoscale.influence import on_cells

    monkeypatch.setattr(on_cells, "ENERGY_CHUNK", chunk)
    g = Grid(0.0, 0.0, H, 71, 53)
    op = HS.grid_operator(g)
    single = op.single_precision()
    (ny, nx), (my, mx) = g.shape, single.fft_shape
    khat = single._khat
    w = on_cells.energy_weights(khat, g.shape, (my, mx))
    ky, kx = np.meshgrid(np.arange(my // 2 + 1), np.arange(mx), indexing="ij")
    phase = np.exp(2j * np.pi * (ky * (ny - 1) / my + kx * (nx - 1) / mx))
    whole = (khat.astype(complex) * phase).real * np.where((ky >= 1) & (ky < (my + 1) // 2), 2.0, 1.0) / (my * mx)
    assert np.allclose(w, whole, rtol=0.0, atol=1e-6 * np.abs(whole).max())
    rng = np.random.default_rng(8)
    cells = np.flatnonzero(rng.uniform(size=g.size) < 0.4)
    v = rng.standard_normal(cells.size)
    p = np.zeros(g.size)
    p[cells] = v
    exact = float(p @ op.apply(p.reshape(g.shape)).ravel())
    spectrum = single.on_cells(cells).forward(v).spectrum
    assert on_cells.parseval_sum(spectrum, w) == pytest.approx(exact, rel=1e-6)


def test_the_product_on_every_cell_in_halves_is_the_grids_product():
    """``on_cells(None)``: every cell through the operator's own padded field (no index
    arrays), the grid's float32 product to the bit, begun and finished or in one call, and
    the same Parseval sum as the product on the flat indices of every cell."""
    g = Grid(0.0, 0.0, H, 57, 44)
    single = HS.grid_operator(g).single_precision()
    every, indexed = single.on_cells(None), single.on_cells(np.arange(g.size))
    assert every is not None and indexed is not None
    p = np.random.default_rng(5).standard_normal(g.shape)
    energy = every.forward(p.ravel()).energy()
    assert np.array_equal(every.finish(), single.apply(p).ravel())
    assert np.array_equal(every(p.ravel()), indexed(p.ravel()))
    assert energy == indexed.forward(p.ravel()).energy()


@pytest.mark.parametrize("shape", [(131, 140), (38, 37)])
def test_the_preconditioners_energy_is_the_wrapped_kernels_inner_product(shape):
    """``energy_on_cells``: ``v.C v`` for ``C`` the kernel wrapped on the preconditioner's
    torus (a longer one from 128 cells a side, the grid's own below), built here from Love's
    kernel at the wrapped offsets and applied by numpy's float64 transforms; on a part's
    cells and on every cell, to the float32 transforms' rounding."""
    from twoscale.influence.circulant import torus_shape

    g = Grid(0.0, 0.0, H, *shape[::-1])
    inverse = HS.grid_operator(g).single_precision().preconditioner()
    ly, lx = torus_shape(g)
    assert (ly, lx) != g.shape if min(shape) >= 128 else (ly, lx) == g.shape
    oy = np.where(np.arange(ly) <= (ly - 1) // 2, np.arange(ly), np.arange(ly) - ly)
    ox = np.where(np.arange(lx) <= (lx - 1) // 2, np.arange(lx), np.arange(lx) - lx)
    dy, dx = np.meshgrid(oy * H, ox * H, indexing="ij")
    wrapped = HS.cell_block(np.c_[dx.ravel(), dy.ravel()], np.zeros((1, 2)), H).reshape(ly, lx)
    rng = np.random.default_rng(7)
    cells = np.flatnonzero(rng.uniform(size=g.size) < 0.2)
    for at in (cells, None):
        v = rng.standard_normal(g.size if at is None else at.size)
        field = np.zeros((ly, lx))
        flat = np.zeros(g.size)
        flat[slice(None) if at is None else at] = v
        field[: g.ny, : g.nx] = flat.reshape(g.shape)
        Cv = np.fft.irfft2(np.fft.rfft2(field) * np.fft.rfft2(wrapped), s=(ly, lx))
        exact = float(np.sum(field * Cv))
        assert inverse.energy_on_cells(at)(v) == pytest.approx(exact, rel=1e-5)


@pytest.mark.parametrize("shape", [(10, 12), (128, 130)])
def test_the_even_kernels_spectrum_from_its_quadrant_is_the_padded_tables_dft_and_back(shape):
    """A self pair's spectrum by the quadrant's cosine transforms against the padded table's
    discrete Fourier sum written out (real along y, complex along x): the same to rounding;
    an odd padded length has no such form (None: the transforms of the whole table). On a
    grid large enough for the operator to take that route, its offset table back from the
    spectrum is Love's kernel, its whole padded lattice the table with zeros beyond it."""
    from twoscale.influence.even_kernel import EVEN_MIN_CELLS, even_spectrum

    ny, nx = shape
    offsets = Grid(-(nx - 1) * H, -(ny - 1) * H, H, 2 * nx - 1, 2 * ny - 1)
    table = HS.cell_block(offsets.points(), np.zeros((1, 2)), H).reshape(offsets.shape)  # Love's kernel
    (ty, tx) = table.shape
    op = HS.grid_operator(Grid(0.0, 0.0, H, nx, ny))
    my, mx = op.fft_shape
    assert my % 2 == 0 and mx % 2 == 0
    wy = np.exp(-2j * np.pi * np.outer(np.arange(my // 2 + 1), np.arange(ty)) / my)
    wx = np.exp(-2j * np.pi * np.outer(np.arange(tx), np.arange(mx)) / mx)
    dft = wy @ table @ wx
    quadrant = table[ny - 1 :, nx - 1 :]
    scale = np.abs(dft).max()
    assert np.abs(even_spectrum(quadrant, (my, mx)) - dft).max() < 1e-13 * scale
    assert even_spectrum(quadrant, (my + 1, mx)) is None
    if ny * nx >= EVEN_MIN_CELLS:
        assert np.abs(op.offset_table() - table).max() <= 1e-13 * table.max()
        assert np.abs(op.transposed().offset_table() - table).max() <= 1e-13 * table.max()
        lattice = np.zeros((my, mx))
        lattice[:ty, :tx] = table
        assert np.abs(op.padded_table() - lattice).max() <= 1e-13 * table.max()
