"""Boussinesq and Love: surface displacement of an elastic half-space.

Both give the vertical surface displacement (positive into the body) in mm.
"""

from __future__ import annotations

import numpy as np

#: Beyond this distance (in units of the larger rectangle side) Love's closed form
#: loses digits to cancellation; a two-term multipole expansion is used instead,
#: whose truncation error there is below 1e-11 relative.
_FAR = 600.0


def boussinesq_point(r, E_star: float, out: np.ndarray | None = None):
    """Surface displacement at distance ``r`` (mm) from a unit normal point force (N).

    ``u = 1 / (pi E* r)`` (Boussinesq 1885). Returns ``inf`` at ``r = 0``. ``out``: a float
    array of ``r``'s shape to write into (it may be ``r`` itself): no temporary of that size
    (a tips' interaction of millions of pairs, in a fresh process, pays each one's pages).
    """
    r = np.asarray(r, dtype=float)
    with np.errstate(divide="ignore"):
        if out is None:
            return 1.0 / (np.pi * E_star * r)
        np.multiply(r, np.pi * E_star, out=out)
        return np.divide(1.0, out, out=out)


def _F(X, Y):
    # Antiderivative of 1/sqrt(X^2+Y^2) over X and Y, written with asinh so that it
    # stays accurate for either sign and at X = 0 or Y = 0 (where its terms vanish).
    ax, ay = np.abs(X), np.abs(Y)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = np.where(ax > 0, X * np.arcsinh(Y / np.where(ax > 0, ax, 1.0)), 0.0)
        t2 = np.where(ay > 0, Y * np.arcsinh(X / np.where(ay > 0, ay, 1.0)), 0.0)
    return t1 + t2


def love_rectangle(x, y, a: float, b: float, E_star: float):
    """Surface displacement at ``(x, y)`` (mm) from unit uniform pressure (1 MPa)
    on the rectangle ``|x'| <= a, |y'| <= b`` (half-sides in mm).

    Love (1929): ``u = 1/(pi E*) * sum over corners of +-F(x -+ a, y -+ b)`` with
    ``F(X, Y) = X asinh(Y/|X|) + Y asinh(X/|Y|)``; exact everywhere, including on
    the rectangle and its edges. Far away (``r > 600 max(a, b)``) the multipole
    expansion ``4ab/r * (1 + ((a^2+b^2)/6 r^2 ... ))`` to fourth order is used.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    x, y = np.broadcast_arrays(x, y)
    r2 = x * x + y * y
    L = max(a, b)
    far = r2 > (_FAR * L) ** 2
    out = np.empty(x.shape)
    near = ~far
    if np.any(near):
        xn, yn = x[near], y[near]
        s = _F(xn + a, yn + b) - _F(xn + a, yn - b) - _F(xn - a, yn + b) + _F(xn - a, yn - b)
        out[near] = s
    if np.any(far):
        xf, yf, rf2 = x[far], y[far], r2[far]
        rf = np.sqrt(rf2)
        # mean of 1/r over the rectangle: Taylor expansion of 1/|r - s| to 2nd order in s
        # <s_x^2> = a^2/3, <s_y^2> = b^2/3:  1/r + (a^2 (2x^2 - y^2) + b^2 (2y^2 - x^2)) / (6 r^5)
        corr = (a * a * (2 * xf * xf - yf * yf) + b * b * (2 * yf * yf - xf * xf)) / (6.0 * rf2 * rf2 * rf)
        out[far] = 4.0 * a * b * (1.0 / rf + corr)
    return out / (np.pi * E_star)


def love_on_lattice(x, y, a: float, b: float, E_star: float) -> np.ndarray:
    """:func:`love_rectangle` on the lattice ``x[None, :], y[:, None]`` (``x`` (n,), ``y``
    (m,), mm; a new (m, n) array): the same values to the bit, made a block of rows at a
    time in small buffers kept for every block (the pointwise form's ~20 lattice-sized
    temporaries are fresh pages in a new process), the multipole on the whole block and
    the closed form on its entries within ``_FAR`` sides only."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    out = np.empty((y.size, x.size))
    rows = max(1, _LATTICE_BLOCK // max(x.size, 1))
    xx, x2 = x * x, 2 * x * x
    near_x = np.flatnonzero(~(xx > (_FAR * max(a, b)) ** 2))
    buffers = [np.empty((min(rows, y.size), x.size)) for _ in range(3)]
    for j0 in range(0, y.size, rows):
        yb = y[j0 : j0 + rows, None]
        _far_rows(xx, x2, yb, a, b, out[j0 : j0 + rows], [w[: len(yb)] for w in buffers])
        _near_rows(x, near_x, yb, a, b, out[j0 : j0 + rows])
    out /= np.pi * E_star
    return out


#: Entries of a block of :func:`love_on_lattice` (its buffers stay in the cache).
_LATTICE_BLOCK = 16384


def _far_rows(xx, x2, y, a: float, b: float, out: np.ndarray, buffers) -> None:
    """The far branch of :func:`love_rectangle`, operation for operation, on the rows
    ``y`` (m, 1) of the lattice (before the division by ``pi E*``), into ``out``."""
    r2, rf, num = buffers
    yy = y * y
    np.add(xx, yy, out=r2)
    np.sqrt(r2, out=rf)
    np.subtract(x2, yy, out=num)
    num *= a * a
    np.subtract(2 * y * y, xx, out=out)
    out *= b * b
    num += out
    np.multiply(r2, 6.0, out=out)
    out *= r2
    out *= rf
    with np.errstate(divide="ignore", invalid="ignore"):  # (r = 0 is near: replaced)
        np.divide(num, out, out=num)
        np.divide(1.0, rf, out=out)
    out += num
    out *= 4.0 * a * b


def _near_rows(x, near_x, y, a: float, b: float, out: np.ndarray) -> None:
    """The closed form of :func:`love_rectangle` on the entries of rows ``y`` (m, 1)
    within ``_FAR`` sides (only columns ``near_x`` can be), into ``out``."""
    L2 = (_FAR * max(a, b)) ** 2
    rows = np.flatnonzero(~(y[:, 0] * y[:, 0] > L2))
    if not (rows.size and near_x.size):
        return
    xs, ys = np.broadcast_arrays(x[near_x][None, :], y[rows])
    near = ~(xs * xs + ys * ys > L2)
    xn, yn = xs[near], ys[near]
    box = out[np.ix_(rows, near_x)]
    box[near] = _F(xn + a, yn + b) - _F(xn + a, yn - b) - _F(xn - a, yn + b) + _F(xn - a, yn - b)
    out[np.ix_(rows, near_x)] = box


def love_far_field(x, y, h: float, E_star: float, order: int = 4):
    """Love's square-cell displacement far from the cell, by its multipole expansion.

    Unit pressure (1 MPa) on the square cell of side ``h`` centred at the origin,
    displacement at ``(x, y)`` (mm): the mean of ``1/r`` over the cell expanded in
    ``h / r``,

    ``u = h^2 / (pi E*) [1/r + h^2/(24 r^3) + h^4 (T4) / r^9]``, with
    ``T4 = 3/1920 (11 r^4 - 70 x^2 y^2) + 3/576 (35 x^2 y^2 - 4 r^4)``

    (the cell average of ``f(x + s)``: ``f + h^2/24 lap f + h^4/1920 (f_xxxx + f_yyyy)
    + h^4/576 f_xxyy``), truncated after the term of ``order`` 0, 2 or 4. Relative
    error against :func:`love_rectangle`: at most ``0.1 (h/r)^2``, ``0.03 (h/r)^4``,
    ``0.01 (h/r)^6`` (``twoscale.influence.separated.FAR_FIELD_BOUND``; tested). Cheap: no
    logarithms, for the many kernel values of well-separated patches.
    """
    if order not in (0, 2, 4):
        raise ValueError(f"order must be 0, 2 or 4, got {order!r}")
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    r2 = x * x + y * y
    with np.errstate(divide="ignore"):
        inv_r = 1.0 / np.sqrt(r2)
    out = inv_r
    if order >= 2:
        inv_r2 = inv_r * inv_r
        out = inv_r * (1.0 + (h * h / 24.0) * inv_r2)
        if order >= 4:
            x2y2 = (x * x) * (y * y)
            r4 = r2 * r2
            t4 = (3.0 / 1920.0) * (11.0 * r4 - 70.0 * x2y2) + (3.0 / 576.0) * (35.0 * x2y2 - 4.0 * r4)
            out = out + h**4 * t4 * (inv_r2 * inv_r2) ** 2 * inv_r
    return (h * h / (np.pi * E_star)) * out
