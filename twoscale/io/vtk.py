"""Micro-grid fields of a :class:`~twoscale.results.ContactResult` as VTK (``.vtu``).

Each cell of each pressure patch becomes a quadrilateral in the plane z = 0 (the
undeformed surface; coordinates in mm), with cell data

* ``pressure_MPa``: contact pressure, MPa;
* ``gap_mm``: ``z + u - d``, mm (NaN where no indenter has material, ``inf`` in memory);
* ``owner``: owning asperity (0-based, scene order; -1 where none);
* ``patch``: index of the patch the cell came from;
* ``indenter_height_mm``: rigid-surface height incl. tilt, mm (when the asperities are
  given; NaN where no indenter has material).

The file records the program version, the units, the patch grids and the scene (a
JSON-able mapping) twice: as a readable XML comment at the top, and as the VTK field
array ``twoscale_metadata`` (the UTF-8 bytes of the same JSON, so ParaView and meshio
can carry it). Writing goes to a temporary file in the target directory, then
``os.replace``: a reader never sees half a file.

meshio is imported here only (``import twoscale`` stays light).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .._version import __version__
from ..grid import Grid
from ..indenters import Asperity, Tilt, surface_on
from ..results import ContactResult, PressureField
from .atomic import atomic_output

UNITS = {"length": "mm", "force": "N", "pressure": "MPa", "angle": "rad"}
LAYOUTS = ("patches", "union")
_META = "twoscale_metadata"


@dataclass(frozen=True)
class VtkContent:
    """What :func:`read_vtk` returns.

    Attributes
    ----------
    fields : tuple of PressureField
        The patches as written (``gap`` back to ``inf`` where it was NaN).
    indenter_height : tuple of (ny, nx) arrays (mm) or None
        Per patch, when the file carries it.
    metadata : dict
        Version, units, layout, grids, scene and result figures as written.
    """

    fields: tuple
    indenter_height: tuple | None
    metadata: dict


def _union_field(fields: Sequence[PressureField]) -> PressureField:
    """One aligned grid covering all patches: pressures add up; owner and gap come from
    the patch whose gap is smallest at the cell (the indenter nearest the body)."""
    h = fields[0].grid.h
    b = np.array([f.grid.bounds for f in fields])
    anchor = (fields[0].grid.x0, fields[0].grid.y0)
    eps = 1e-9 * h
    g = Grid.covering(b[:, 0].min() + eps, b[:, 1].max() - eps, b[:, 2].min() + eps,
                      b[:, 3].max() - eps, h, anchor=anchor)
    p = np.zeros(g.shape)
    owner = np.full(g.shape, -1, dtype=np.int64)
    gap = np.full(g.shape, np.inf)
    for f in fields:
        di, dj = f.grid.offset_in(g)
        sl = (slice(dj, dj + f.grid.ny), slice(di, di + f.grid.nx))
        p[sl] += f.pressure
        better = f.gap < gap[sl]
        gap[sl] = np.where(better, f.gap, gap[sl])
        owner[sl] = np.where(better, f.owner, owner[sl])
    return PressureField(g, p, owner, gap)


def _quads(grid: Grid, offset: int) -> tuple[np.ndarray, np.ndarray]:
    """Corner points (z = 0) and quad connectivity of a grid's cells, row-major x fastest."""
    xmin, _, ymin, _ = grid.bounds
    xs = xmin + grid.h * np.arange(grid.nx + 1)
    ys = ymin + grid.h * np.arange(grid.ny + 1)
    X, Y = np.meshgrid(xs, ys)
    pts = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    n1 = grid.nx + 1
    j, i = np.meshgrid(np.arange(grid.ny), np.arange(grid.nx), indexing="ij")
    a = (j * n1 + i).ravel()
    quads = np.column_stack([a, a + 1, a + 1 + n1, a + n1]) + offset
    return pts, quads


def _grid_dict(g: Grid) -> dict:
    return {"x0": g.x0, "y0": g.y0, "h": g.h, "nx": g.nx, "ny": g.ny}


def _metadata(result: ContactResult, layout: str, grids: Sequence[Grid],
              scene: Mapping[str, Any] | None, has_height: bool) -> dict:
    return {
        "program": "twoscale", "version": __version__, "units": UNITS,
        "layout": layout, "grids": [_grid_dict(g) for g in grids],
        "has_indenter_height": has_height,
        "result": {"method": result.method, "converged": bool(result.converged),
                   "penetration": float(result.penetration),
                   "tilt": None if result.tilt is None else [float(t) for t in result.tilt],
                   "total_load": float(result.total_load),
                   "forces": [float(f) for f in result.asperities.forces]},
        "scene": None if scene is None else dict(scene),
    }


def write_vtk(result: ContactResult, path: str | Path, *, layout: str = "patches",
              asperities: Sequence[Asperity] | None = None, pivot: tuple[float, float] = (0.0, 0.0),
              scene: Mapping[str, Any] | None = None, binary: bool = True) -> Path:
    """Write the micro-grid fields of ``result`` to a ``.vtu`` file.

    Parameters
    ----------
    result : ContactResult
    path : path-like
        Output file; must end in ``.vtu``.
    layout : {"patches", "union"}, default "patches"
        ``"patches"``: every patch as it is (overlapping patches stay separate, see the
        ``patch`` array); ``"union"``: one aligned grid covering all patches (pressures
        summed as in :meth:`ContactResult.pressure_on`; can be large for sparse scenes).
    asperities : sequence of Asperity, optional
        The scene's indenters; when given, ``indenter_height_mm`` is written (with the
        result's tilt about ``pivot`` when it has one).
    pivot : (float, float), default (0, 0)
        Ball-and-socket joint position, mm (used with ``result.tilt``).
    scene : mapping, optional
        The scene as plain JSON-able data, recorded in the file.
    binary : bool, default True
        Compressed binary arrays (exact float64) or ASCII.

    Returns
    -------
    Path of the file written.
    """
    import meshio

    path = Path(path)
    if path.suffix.lower() != ".vtu":
        raise ValueError(f"VTK output path must end in .vtu, got {str(path)!r}")
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    if not result.fields:
        raise ValueError("result has no pressure fields to write")
    fields = list(result.fields) if layout == "patches" else [_union_field(result.fields)]
    tilt = None
    if result.tilt is not None:
        tilt = Tilt(alpha=float(result.tilt[0]), beta=float(result.tilt[1]), pivot=tuple(pivot))

    points, quads, data = [], [], {k: [] for k in ("pressure_MPa", "gap_mm", "owner", "patch",
                                                    "indenter_height_mm")}
    offset = 0
    for k, f in enumerate(fields):
        pts, q = _quads(f.grid, offset)
        offset += len(pts)
        points.append(pts)
        quads.append(q)
        data["pressure_MPa"].append(f.pressure.ravel())
        data["gap_mm"].append(np.where(np.isfinite(f.gap), f.gap, np.nan).ravel())
        data["owner"].append(f.owner.ravel())
        data["patch"].append(np.full(f.grid.size, k, dtype=np.int64))
        if asperities is not None:
            z = surface_on(f.grid, asperities, tilt).height
            data["indenter_height_mm"].append(np.where(np.isfinite(z), z, np.nan).ravel())
    if asperities is None:
        del data["indenter_height_mm"]
    mesh = meshio.Mesh(np.vstack(points), [("quad", np.vstack(quads))],
                       cell_data={k: [np.concatenate(v)] for k, v in data.items()})
    meta = _metadata(result, layout, [f.grid for f in fields], scene, asperities is not None)
    _atomic_write(mesh, path, meta, binary)
    return path


def _metadata_text(meta: dict) -> str:
    # "--" may not appear inside an XML comment; it can only occur inside JSON strings,
    # where the escape \u002d reads back as the same "-"
    return json.dumps(meta, ensure_ascii=True, allow_nan=False).replace("--", "-\\u002d")


def _atomic_write(mesh, path: Path, meta: dict, binary: bool) -> None:
    import meshio

    text = _metadata_text(meta)
    codes = " ".join(str(b) for b in text.encode("utf-8"))
    field = (f'<FieldData>\n<DataArray type="UInt8" Name="{_META}" NumberOfTuples="{len(text.encode("utf-8"))}" '
             f'format="ascii">\n{codes}\n</DataArray>\n</FieldData>\n')
    with atomic_output(path) as tmp:
        meshio.vtu.write(str(tmp), mesh, binary=binary)
        xml = tmp.read_text(encoding="utf-8")
        head, sep, rest = xml.partition("<UnstructuredGrid>\n")
        if not sep:
            raise RuntimeError("unexpected VTU layout from meshio: no <UnstructuredGrid> line")
        head = head.replace("?>\n", f"?>\n<!-- twoscale {__version__} (units mm, N, MPa) {text} -->\n", 1)
        tmp.write_text(head + sep + field + rest, encoding="utf-8")


def read_vtk(path: str | Path) -> VtkContent:
    """Read a file written by :func:`write_vtk` back into patches and metadata."""
    import meshio

    mesh = meshio.read(str(path), file_format="vtu")
    if _META not in mesh.field_data:
        raise ValueError(f"{path} was not written by twoscale (no {_META} field)")
    meta = json.loads(bytes(np.asarray(mesh.field_data[_META], dtype=np.uint8)).decode("utf-8"))
    cd = {k: np.concatenate(v) for k, v in mesh.cell_data.items()}
    fields, heights, start = [], [], 0
    for gd in meta["grids"]:
        g = Grid(gd["x0"], gd["y0"], gd["h"], gd["nx"], gd["ny"])
        sl = slice(start, start + g.size)
        start += g.size
        gap = cd["gap_mm"][sl].reshape(g.shape)
        fields.append(PressureField(g, cd["pressure_MPa"][sl].reshape(g.shape),
                                    cd["owner"][sl].reshape(g.shape),
                                    np.where(np.isnan(gap), np.inf, gap)))
        if "indenter_height_mm" in cd:
            z = cd["indenter_height_mm"][sl].reshape(g.shape)
            heights.append(np.where(np.isnan(z), np.inf, z))
    if start != len(cd["pressure_MPa"]):
        raise ValueError(f"{path}: {len(cd['pressure_MPa'])} cells, metadata grids hold {start}")
    return VtkContent(tuple(fields), tuple(heights) if heights else None, meta)
