"""``block_displacement.vtu``: the finite block's displacement field for a solved scene.

Written by ``twoscale solve SCENE --out DIR --block-field`` (block provider only). The
solved pressure is turned into point forces ``h^2 p`` at the loaded micro-cell centres
(cells owned by an asperity, as in the per-asperity forces) and
:meth:`fem_influence.BlockProvider.displacement_field` gives the displacement at the
block mesh vertices: Boussinesq's interior field of those forces (merged into square
aggregates of side ``aggregate``) plus the FEM correction for the same loading. The
half-space part is poor at vertices within a few aggregates of the loaded surface
(point forces instead of the distributed pressure; see :mod:`fem_influence.field`).

File layout (VTK unstructured grid of hexahedra, through meshio): points ``(x, y, z)``
in mm with x, y in the scene frame and ``z = -depth`` (top face at z = 0, the block
below, as in ``fields.vtm``); point arrays ``displacement_mm`` (3 components, z up: a
pressed surface moves to negative z), ``displacement_halfspace_mm`` (its Boussinesq
part) and ``depth_mm``. Metadata (version, units, scene, block, aggregation, total
force) as in :mod:`twoscale.io.vtk`: an XML comment and the field array
``twoscale_metadata``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._version import __version__
from ..results import ContactResult
from .atomic import atomic_output
from .vtk import UNITS, _META, _metadata_text

BLOCK_FIELD_NAME = "block_displacement.vtu"

#: Default aggregate side for the Boussinesq part, mm.
DEFAULT_AGGREGATE = 1.0


@dataclass(frozen=True)
class BlockFieldContent:
    """What :func:`read_block_field` returns.

    points : (n, 3) mm, z up; displacement, halfspace : (n, 3) mm, z up;
    cells : (m, 8) VTK hexahedra; metadata : dict.
    """

    points: np.ndarray
    displacement: np.ndarray
    halfspace: np.ndarray
    cells: np.ndarray
    metadata: dict


def loaded_point_forces(result: ContactResult) -> tuple[np.ndarray, np.ndarray]:
    """Cell centres (N, 2, mm) and forces ``h^2 p`` (N,) of the owned, loaded cells."""
    pts, forces = [], []
    for f in result.fields:
        p = f.pressure.ravel()
        ok = (f.owner.ravel() >= 0) & (p > 0)
        pts.append(f.grid.points().reshape(-1, 2)[ok])
        forces.append(f.grid.h**2 * p[ok])
    if not pts:
        return np.zeros((0, 2)), np.zeros(0)
    return np.vstack(pts), np.concatenate(forces)


def write_block_field(
    result: ContactResult,
    provider,
    path,
    *,
    scene: dict | None = None,
    aggregate: float = DEFAULT_AGGREGATE,
    binary: bool = True,
) -> Path:
    """Write the block's displacement field for ``result`` to ``path`` (.vtu).

    Parameters
    ----------
    result : ContactResult
        A solve on the block ``provider``.
    provider : fem_influence.BlockProvider
    path : path-like
        Output file (parent created if needed; written atomically).
    scene : dict, optional
        The scene record (``scene_to_dict``) stored in the metadata.
    aggregate : float, default 1
        Aggregate side for the Boussinesq part, mm (0: one point force per cell).
    binary : bool, default True
        Binary (compressed) or ASCII data arrays.

    Returns
    -------
    Path written.
    """
    import meshio
    from skfem.io.meshio import HEX_MAPPING

    P, F = loaded_point_forces(result)
    fld = provider.displacement_field(P, F, aggregate=aggregate)
    up = np.array([1.0, 1.0, -1.0])
    points = fld.points * up
    # z = -depth mirrors the mesh: swap the two quad faces so VTK hexahedra keep a
    # positive volume
    cells = fld.cells[:, HEX_MAPPING[:8]][:, [4, 5, 6, 7, 0, 1, 2, 3]]
    mesh = meshio.Mesh(
        points,
        [("hexahedron", cells)],
        point_data={
            "displacement_mm": fld.displacement * up,
            "displacement_halfspace_mm": fld.halfspace * up,
            "depth_mm": fld.points[:, 2].copy(),
        },
    )
    meta = {
        "program": "twoscale",
        "version": __version__,
        "units": UNITS,
        "file": "block displacement",
        "frame": "x, y scene frame; z up (top face z = 0); displacement z up",
        "block": {"size": list(provider.size), "base": provider.base, "origin": list(provider.origin)},
        "material": {"E": provider.material.E, "nu": provider.material.nu},
        "aggregate_mm": fld.aggregate,
        "n_point_forces": fld.n_forces,
        "total_force": fld.total_force,
        "approximation": "Boussinesq point forces h^2 p merged into aggregates; poor within a few "
        "aggregates of the loaded surface",
        "scene": scene,
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    _atomic_write(mesh, path, meta, binary)
    return path


def read_block_field(path) -> BlockFieldContent:
    """Read a file written by :func:`write_block_field`."""
    import meshio

    mesh = meshio.read(str(path), file_format="vtu")
    if _META not in mesh.field_data:
        raise ValueError(f"{path}: no {_META} field array (not written by twoscale)")
    meta = json.loads(bytes(np.asarray(mesh.field_data[_META], dtype=np.uint8)).decode("utf-8"))
    pd = mesh.point_data
    return BlockFieldContent(
        points=np.asarray(mesh.points),
        displacement=np.asarray(pd["displacement_mm"]),
        halfspace=np.asarray(pd["displacement_halfspace_mm"]),
        cells=np.asarray(mesh.cells_dict["hexahedron"]),
        metadata=meta,
    )


def _atomic_write(mesh, path: Path, meta: dict, binary: bool) -> None:
    """Write ``mesh`` as ``.vtu`` through meshio with the metadata as an XML comment on the
    second line and as the field array ``twoscale_metadata`` (meshio writes no field data
    of bytes, so the array is added to its XML)."""
    import meshio

    text = _metadata_text(meta)
    codes = " ".join(str(b) for b in text.encode("utf-8"))
    field = (
        f'<FieldData>\n<DataArray type="UInt8" Name="{_META}" NumberOfTuples="{len(text.encode("utf-8"))}" '
        f'format="ascii">\n{codes}\n</DataArray>\n</FieldData>\n'
    )
    with atomic_output(path) as tmp:
        meshio.vtu.write(str(tmp), mesh, binary=binary)
        xml = tmp.read_text(encoding="utf-8")
        head, sep, rest = xml.partition("<UnstructuredGrid>\n")
        if not sep:
            raise RuntimeError("unexpected VTU layout from meshio: no <UnstructuredGrid> line")
        head = head.replace("?>\n", f"?>\n<!-- twoscale {__version__} (units mm, N, MPa) {text} -->\n", 1)
        tmp.write_text(head + sep + field + rest, encoding="utf-8")
