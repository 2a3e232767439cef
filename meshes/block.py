"""The default block mesh: hexahedra, fine around the scene, graded to the sides."""

from __future__ import annotations

import math

import numpy as np

#: The most nodes a block mesh may have (Q1 geometry). The default 140 x 140 x 20 mm block
#: has about 2,200 (with its fine part at +-25 mm); a 1 m square block 20 mm thick about 41,000. Two million nodes is far
#: past what the finite-element solve on it can factorise, so a larger mesh is refused
#: before its axes are built (a size of 1e16 mm would otherwise be meshed until the
#: machine's memory ran out).
MAX_MESH_NODES = 2_000_000


def graded_axis(
    lo: float, hi: float, *, fine_lo: float, fine_hi: float, h_fine: float, h_coarse: float, growth: float = 1.3
) -> np.ndarray:
    """Node coordinates on ``[lo, hi]``: spacing ``<= h_fine`` on ``[fine_lo, fine_hi]``,
    growing geometrically by ``growth`` up to ``h_coarse`` outside it.

    Parameters
    ----------
    lo, hi : float
        Ends of the axis, mm.
    fine_lo, fine_hi : float
        The finely meshed interval (clipped to ``[lo, hi]``), mm.
    h_fine, h_coarse : float
        Element sizes, mm (``0 < h_fine <= h_coarse``).
    growth : float, default 1.3
        Ratio of successive element sizes in the graded part (> 1).

    Returns
    -------
    Strictly increasing array of node coordinates including both ends, mm.
    """
    if not (0 < h_fine <= h_coarse):
        raise ValueError(f"need 0 < h_fine <= h_coarse, got h_fine={h_fine!r}, h_coarse={h_coarse!r}")
    if not hi > lo:
        raise ValueError(f"axis needs hi > lo, got lo={lo!r}, hi={hi!r}")
    if not growth > 1:
        raise ValueError(f"growth must be > 1, got {growth!r}")
    a, b = max(lo, min(fine_lo, hi)), min(hi, max(fine_hi, lo))
    n = max(1, math.ceil((b - a) / h_fine - 1e-9)) if b > a else 0
    core = list(np.linspace(a, b, n + 1)) if n else [a]

    def grow(start: float, end: float) -> list[float]:
        # geometric steps away from the fine part, last interval stretched to hit ``end``
        out, x, h, sgn = [], start, h_fine, np.sign(end - start)
        while abs(end - x) > 1e-9:
            h = min(h * growth, h_coarse)
            if abs(end - x) < 1.5 * h:
                x = end
            else:
                x = x + sgn * h
            out.append(x)
        return out

    left = grow(core[0], lo)[::-1]
    right = grow(core[-1], hi)
    return np.array(left + core + right)


def axis_cells_bound(length: float, *, fine: float, h_fine: float, h_coarse: float, growth: float) -> float:
    """An upper bound on the elements :func:`graded_axis` puts on an axis ``length`` long
    (mm) whose fine part is ``fine`` long, computed without building it: the fine part's
    elements, and on each side the geometric steps up to ``h_coarse`` plus that side's
    length in ``h_coarse`` steps."""
    ramp = math.ceil(math.log(h_coarse / h_fine) / math.log(growth)) + 1 if h_coarse > h_fine else 1
    side = max(0.0, (length - fine) / 2.0)
    return math.ceil(min(fine, length) / h_fine) + 1 + 2 * (ramp + side / h_coarse + 1)


def check_mesh_size(size, *, h_fine: float, h_coarse: float, fine_box, nz: int | None, growth: float) -> None:
    """Refuse (``ValueError`` naming ``size``) a block whose mesh would have more than
    :data:`MAX_MESH_NODES` nodes, counted before anything is built."""
    Lx, Ly, t = (float(v) for v in size)
    nx = axis_cells_bound(Lx, fine=fine_box[1] - fine_box[0], h_fine=h_fine, h_coarse=h_coarse, growth=growth)
    ny = axis_cells_bound(Ly, fine=fine_box[3] - fine_box[2], h_fine=h_fine, h_coarse=h_coarse, growth=growth)
    nzz = t / h_fine + 1 if nz is None else float(nz)
    nodes = (nx + 1) * (ny + 1) * (nzz + 1)
    if not nodes <= MAX_MESH_NODES:
        raise ValueError(
            f"block size {tuple(size)!r} mm needs a mesh of about {nodes:.3g} nodes at h_fine = {h_fine:g} mm, "
            f"more than the {MAX_MESH_NODES:,} the finite-element solve can hold: give a smaller size"
        )


def block_mesh(
    size=(140.0, 140.0, 20.0),
    *,
    h_fine: float = 5.0,
    h_coarse: float = 12.0,
    fine_box=(-20.0, 20.0, -20.0, 20.0),
    nz: int | None = None,
    growth: float = 1.3,
):
    """Graded hexahedral mesh of the block (scikit-fem ``MeshHex``, Q1 geometry).

    Parameters
    ----------
    size : (3,) floats, default (140, 140, 20)
        Block length along x and y and thickness, mm.
    h_fine : float, default 5
        Element size over ``fine_box`` (the scene), mm. Elements are quadratic
        (Q2), so the nodal spacing there is ``h_fine / 2``.
    h_coarse : float, default 12
        Largest element size towards the sides, mm.
    fine_box : (xmin, xmax, ymin, ymax), default +-20 mm
        Region of the top face, measured from its centre, meshed at ``h_fine``.
    nz : int, optional
        Elements through the thickness; default ``ceil(thickness / h_fine)``.
    growth : float, default 1.3
        Size ratio of neighbouring elements in the graded part.

    Returns
    -------
    skfem.MeshHex with coordinates ``(x, y, depth)``, mm.
    """
    from skfem import MeshHex

    Lx, Ly, t = (float(v) for v in size)
    if not all(v > 0 for v in (Lx, Ly, t)):  # NaN too
        raise ValueError(f"block size must be positive (mm), got {size!r}")
    check_mesh_size((Lx, Ly, t), h_fine=h_fine, h_coarse=h_coarse, fine_box=fine_box, nz=nz, growth=growth)
    x = graded_axis(
        -Lx / 2, Lx / 2, fine_lo=fine_box[0], fine_hi=fine_box[1], h_fine=h_fine, h_coarse=h_coarse, growth=growth
    )
    y = graded_axis(
        -Ly / 2, Ly / 2, fine_lo=fine_box[2], fine_hi=fine_box[3], h_fine=h_fine, h_coarse=h_coarse, growth=growth
    )
    nz = max(1, math.ceil(t / h_fine - 1e-9)) if nz is None else int(nz)
    if nz < 1:
        raise ValueError(f"nz must be >= 1, got {nz!r}")
    z = np.linspace(0.0, t, nz + 1)
    return MeshHex.init_tensor(x, y, z)
