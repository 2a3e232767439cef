"""Reading and writing block meshes with meshio (any format meshio knows)."""

from __future__ import annotations

import numpy as np


def read_block_mesh(path, *, up: str = "+z"):
    """Read a user's hexahedral block mesh into the block frame.

    The top face is the plane of largest ``z`` (``up="+z"``) or smallest
    (``up="-z"``); the returned mesh has depth ``= z_top - z`` (or ``z - z_top``)
    as third coordinate and ``x, y`` measured from the centre of the top face's
    bounding box. Only hexahedral cells are used (other cell types, e.g.
    boundary quads, are ignored).

    Parameters
    ----------
    path : str or Path
        Mesh file (e.g. ``.msh``, ``.vtu``, ``.xdmf``).
    up : {"+z", "-z"}, default "+z"
        Direction of the outward normal of the top face in the file.

    Returns
    -------
    skfem.MeshHex, coordinates ``(x, y, depth)`` in mm (the file must be in mm).
    """
    import meshio

    if up not in ("+z", "-z"):
        raise ValueError(f"up must be '+z' or '-z', got {up!r}")
    m = meshio.read(path)
    hexes = [c.data for c in m.cells if c.type == "hexahedron"]
    if not hexes:
        raise ValueError(f"{path!s} has no hexahedron cells (found {[c.type for c in m.cells]})")
    return _to_block_frame(m.points, np.vstack(hexes), up)


def _to_block_frame(points: np.ndarray, hexes: np.ndarray, up: str):
    from skfem import MeshHex

    p = np.asarray(points, dtype=float)[:, :3]
    used = np.unique(hexes)
    ztop = p[used, 2].max() if up == "+z" else p[used, 2].min()
    depth = (ztop - p[:, 2]) if up == "+z" else (p[:, 2] - ztop)
    top = used[np.abs(depth[used]) < 1e-9 * max(1.0, np.ptp(p[used, 2]))]
    cx = 0.5 * (p[top, 0].min() + p[top, 0].max())
    cy = 0.5 * (p[top, 1].min() + p[top, 1].max())
    q = np.column_stack([p[:, 0] - cx, p[:, 1] - cy, depth])
    if up == "+z":
        # z -> -z mirrors the cells: reflect y too (x, y, z) -> (x, -y, -z) is a rotation
        q[:, 1] = -q[:, 1]
    from skfem.io.meshio import INV_HEX_MAPPING

    # meshio (VTK) hexahedron order -> scikit-fem order
    t = np.asarray(hexes)[:, INV_HEX_MAPPING[:8]].T
    return MeshHex(q.T.copy(), np.ascontiguousarray(t))


def write_block_mesh(mesh, path) -> None:
    """Write a block-frame ``MeshHex`` with meshio (``z = -depth``, top face at z = 0).

    Parameters
    ----------
    mesh : skfem.MeshHex
        Mesh in the block frame ``(x, y, depth)``, mm.
    path : str or Path
        Output file; the format follows the suffix.
    """
    import meshio

    p = mesh.p.T.copy()
    p[:, 2] = -p[:, 2]
    p[:, 1] = -p[:, 1]
    from skfem.io.meshio import HEX_MAPPING

    # scikit-fem hexahedron order -> meshio (VTK) order
    t = mesh.t.T[:, HEX_MAPPING[:8]]
    meshio.write(path, meshio.Mesh(p, [("hexahedron", t)]))
