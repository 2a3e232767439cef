"""Micro-grid fields of a contact result as VTK image data (``.vtm`` + ``.vti``).

Every pressure patch is a regular grid, so each is written as one VTK image (``.vti``:
origin, spacing and cell arrays, no point list), and a multiblock file (``.vtm``) lists
them: ``fields.vtm`` beside a folder ``fields/`` holding ``patch_001.vti``, ... in patch
order. ParaView and pyvista open the ``.vtm`` as one dataset. Cell arrays (the image lies
in the plane z = 0, the undeformed surface; x, y in mm):

* ``pressure_MPa``: contact pressure, MPa;
* ``gap_mm``: ``z + u - d``, mm (NaN where no indenter has material, ``inf`` in memory);
* ``owner``: owning asperity, numbered from 1 in scene order as in every table and
  figure; 0 where no asperity owns the cell (``-1`` and 0-based in memory);
* ``patch``: number of the patch the cell came from (from 1; the block ``patch k``);
* ``indenter_height_mm``: rigid-surface height incl. tilt, mm (when the asperities are
  given; NaN where no indenter has material).

The ``.vtm`` records the program version, the units, the patch grids, the result's
figures and the scene (a JSON-able mapping) as JSON in an XML comment on its second line;
each ``.vti`` records the version, the units and its patch number the same way and as the
VTK field array ``twoscale_metadata`` (the UTF-8 bytes of that JSON). The images are
written into a temporary folder renamed into place, then the ``.vtm``: a reader never sees
half a file.

Neither meshio nor pyvista is needed: the format is written with numpy
(:mod:`twoscale.io.vti`).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .._version import __version__
from ..grid import Grid
from ..indenters import Asperity, Tilt, surface_on
from ..results import PressureField
from .atomic import current_umask, atomic_output
from .vti import read_image, read_multiblock, write_image, write_multiblock

UNITS = {"length": "mm", "force": "N", "pressure": "MPa", "angle": "rad"}
FIELD_LAYOUTS = ("patches", "union")
_META = "twoscale_metadata"


@dataclass(frozen=True)
class VtkContent:
    """What :func:`read_vtk` returns.

    Attributes
    ----------
    fields : tuple of PressureField
        The patches as written (``gap`` back to ``inf`` where it was NaN; ``owner``
        0-based with -1 for none, as in memory: the file's number minus 1).
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
    g = Grid.covering(
        b[:, 0].min() + eps, b[:, 1].max() - eps, b[:, 2].min() + eps, b[:, 3].max() - eps, h, anchor=anchor
    )
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


def _grid_dict(g: Grid) -> dict:
    return {"x0": g.x0, "y0": g.y0, "h": g.h, "nx": g.nx, "ny": g.ny}


def _metadata(result, layout: str, grids: Sequence[Grid], scene: Mapping[str, Any] | None, has_height: bool) -> dict:
    return {
        "program": "twoscale",
        "version": __version__,
        "units": UNITS,
        "layout": layout,
        "grids": [_grid_dict(g) for g in grids],
        "has_indenter_height": has_height,
        "result": {
            "method": result.method,
            "converged": bool(result.converged),
            "penetration": float(result.penetration),
            "tilt": None if result.tilt is None else [float(t) for t in result.tilt],
            "total_load": float(result.total_load),
            "forces": [float(f) for f in result.forces],
        },
        "numbering": {"owner": "asperity number from 1 in scene order; 0: none", "patch": "from 1"},
        "scene": None if scene is None else dict(scene),
    }


def _metadata_text(meta: dict) -> str:
    # "--" may not appear inside an XML comment; it can only occur inside JSON strings,
    # where the escape \u002d reads back as the same "-"
    return json.dumps(meta, ensure_ascii=True, allow_nan=False).replace("--", "-\\u002d")


def _lowest_on(grid: Grid, tips: np.ndarray, sphere: np.ndarray) -> np.ndarray:
    """For each tip (rows x, y, z, R), a lower bound of its indenter height over the grid's
    cell centres: its height at the nearest point of that box (heights grow with the
    distance to the tip); inf for a sphere whose base does not reach the box."""
    x, y, z, R = tips.T
    r2 = (np.clip(x, grid.x[0], grid.x[-1]) - x) ** 2 + (np.clip(y, grid.y[0], grid.y[-1]) - y) ** 2
    with np.errstate(invalid="ignore"):
        cap = np.where(r2 < R * R, z + r2 / (R + np.sqrt(np.maximum(R * R - r2, 0.0))), np.inf)
    return np.where(sphere, cap, z + r2 / (2.0 * R))


def _tip_table(asperities: Sequence[Asperity]) -> tuple[np.ndarray, np.ndarray]:
    """Rows (x, y, z, R) of the asperities, mm, and which are spheres (built once per file)."""
    tips = np.array([[a.x, a.y, a.z, a.R] for a in asperities], float).reshape(-1, 4)
    return tips, np.array([a.shape == "sphere" for a in asperities], bool)


def _indenter_height(grid: Grid, asperities: Sequence[Asperity], table, tilt: Tilt | None) -> np.ndarray:
    """Lowest indenter height at the cell centres (inf where none has material), mm, as
    :func:`twoscale.indenters.surface_on` gives it; indenters are taken lowest bound first
    and stop once none can be lower anywhere, and a sphere is evaluated only under its
    base, so thousands of tips on thousands of patches stay cheap. ``table``:
    :func:`_tip_table` of ``asperities``."""
    if any(getattr(a, "group", None) is not None for a in asperities):
        # a height map's basins: one look-up of the map (no lower bound per basin to prune by)
        return surface_on(grid, asperities, tilt).height
    tips, sphere = table
    low = _lowest_on(grid, tips, sphere)
    X, Y = grid.centres()
    z = np.full(grid.shape, np.inf)
    for k in np.argsort(low, kind="stable"):
        if not low[k] < z.max():  # neither this indenter nor the ones after it can be lowest anywhere
            break
        a = asperities[k]
        i0, j0, i1, j1 = 0, 0, grid.nx, grid.ny
        if sphere[k]:
            i0, i1 = np.searchsorted(grid.x, [a.x - a.R, a.x + a.R])
            j0, j1 = np.searchsorted(grid.y, [a.y - a.R, a.y + a.R])
        win = (slice(j0, j1), slice(i0, i1))
        np.minimum(z[win], a.height(X[win], Y[win]), out=z[win])
    return z if tilt is None else z + tilt.height(X, Y)


def _cell_arrays(f: PressureField, k: int, height: np.ndarray | None) -> dict:
    """A patch's cell arrays as written: NaN for inf, owner and patch numbered from 1."""
    out = {
        "pressure_MPa": f.pressure,
        "gap_mm": np.where(np.isfinite(f.gap), f.gap, np.nan),
        "owner": (f.owner + 1).astype(np.int32),
        "patch": np.full(f.grid.shape, k, dtype=np.int32),
    }
    if height is not None:
        out["indenter_height_mm"] = np.where(np.isfinite(height), height, np.nan)
    return out


def _replace_folder(tmp: Path, folder: Path) -> None:
    """Put the finished folder ``tmp`` in place of ``folder`` (a previous one is removed)."""
    old = None
    if folder.exists():
        old = folder.with_name(f"{tmp.name}.old")
        folder.rename(old)
    tmp.rename(folder)
    if old is not None:
        shutil.rmtree(old)


def _check_data_folder(folder: Path) -> None:
    if folder.exists() and (
        not folder.is_dir()
        or any(not (p.is_file() and p.name.startswith("patch_") and p.suffix == ".vti") for p in folder.iterdir())
    ):
        raise ValueError(f"{folder} exists and holds other files than patch_*.vti: not replaced")


def _write_images(folder: Path, fields: Sequence[PressureField], asperities, tilt, binary: bool) -> list[str]:
    """One ``patch_NNN.vti`` per field into ``folder``, numbered from 1; returns the names."""
    width = max(3, len(str(len(fields))))
    names = []
    table = None if asperities is None else _tip_table(asperities)
    for k, f in enumerate(fields, start=1):
        names.append(f"patch_{k:0{width}d}.vti")
        own = {
            "program": "twoscale",
            "version": __version__,
            "units": UNITS,
            "patch": k,
            "patches": len(fields),
            "grid": _grid_dict(f.grid),
        }
        text = _metadata_text(own)
        height = None if asperities is None else _indenter_height(f.grid, asperities, table, tilt)
        write_image(
            folder / names[-1],
            f.grid,
            _cell_arrays(f, k, height),
            binary=binary,
            field_data={_META: np.frombuffer(text.encode("utf-8"), dtype=np.uint8)},
            comment=f"twoscale {__version__} (units mm, N, MPa) {text}",
        )
    return names


def write_vtk(
    result,
    path: str | Path,
    *,
    layout: str = "patches",
    asperities: Sequence[Asperity] | None = None,
    pivot: tuple[float, float] = (0.0, 0.0),
    scene: Mapping[str, Any] | None = None,
    binary: bool = True,
) -> Path:
    """Write the micro-grid fields of ``result`` as ``path`` (``.vtm``) and its images.

    Parameters
    ----------
    result : ContactResult
    path : path-like
        Output multiblock file; must end in ``.vtm``. The images go into the folder of
        the same name without the suffix (``fields.vtm`` -> ``fields/patch_001.vti``),
        which is replaced when it holds nothing but such images.
    layout : {"patches", "union"}, default "patches"
        ``"patches"``: every patch as it is (overlapping patches stay separate images);
        ``"union"``: one aligned grid covering all patches (pressures summed as in
        :meth:`ContactResult.pressure_on`; can be large for sparse scenes).
    asperities : sequence of Asperity, optional
        The scene's indenters; when given, ``indenter_height_mm`` is written (with the
        result's tilt about ``pivot`` when it has one).
    pivot : (float, float), default (0, 0)
        Ball-and-socket joint position, mm (used with the result's tilt).
    scene : mapping, optional
        The scene as plain JSON-able data, recorded in the ``.vtm``.
    binary : bool, default True
        Raw binary arrays (exact float64, fast) or ASCII text (exact, slower).

    Returns
    -------
    Path of the ``.vtm`` written.
    """
    path = Path(path)
    if path.suffix.lower() != ".vtm":
        raise ValueError(f"VTK output path must end in .vtm, got {str(path)!r}")
    if layout not in FIELD_LAYOUTS:
        raise ValueError(f"layout must be one of {FIELD_LAYOUTS}, got {layout!r}")
    if not result.fields:
        raise ValueError("result has no pressure fields to write")
    folder = path.with_suffix("")
    _check_data_folder(folder)
    fields = list(result.fields) if layout == "patches" else [_union_field(result.fields)]
    tilt = (
        None
        if result.tilt is None
        else Tilt(alpha=float(result.tilt[0]), beta=float(result.tilt[1]), pivot=tuple(pivot))
    )
    meta = _metadata(result, layout, [f.grid for f in fields], scene, asperities is not None)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.tmp-", dir=path.parent))
    try:
        os.chmod(tmp, 0o777 & ~current_umask())  # mkdtemp makes it owner-only
        names = _write_images(tmp, fields, asperities, tilt, binary)
        _replace_folder(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    blocks = [(f"patch {k}", f"{folder.name}/{name}") for k, name in enumerate(names, start=1)]
    with atomic_output(path) as out:
        write_multiblock(out, blocks, comment=f"twoscale {__version__} (units mm, N, MPa) {_metadata_text(meta)}")
    return path


def _meta_from_comment(path, comment: str) -> dict:
    if not comment.startswith("twoscale ") or "{" not in comment:
        raise ValueError(f"{path} was not written by twoscale (no metadata comment)")
    return json.loads(comment[comment.index("{") :])


def read_vtk(path: str | Path) -> VtkContent:
    """Read a ``.vtm`` written by :func:`write_vtk` back into patches (owner 0-based, -1
    for none, as in memory), indenter heights and metadata."""
    path = Path(path)
    if path.suffix.lower() != ".vtm":
        raise ValueError(f"twoscale fields are read from a .vtm file, got {str(path)!r}")
    blocks, comment = read_multiblock(path)
    meta = _meta_from_comment(path, comment)
    if len(blocks) != len(meta["grids"]):
        raise ValueError(f"{path}: {len(blocks)} blocks, metadata lists {len(meta['grids'])} grids")
    fields, heights = [], []
    for (_, file), gd in zip(blocks, meta["grids"]):
        image = read_image(file)
        g, cd = image.grid, image.cell_data
        if (g.nx, g.ny) != (gd["nx"], gd["ny"]):
            raise ValueError(f"{file}: {g.ny} x {g.nx} cells, metadata says {gd['ny']} x {gd['nx']}")
        g = Grid(gd["x0"], gd["y0"], gd["h"], gd["nx"], gd["ny"])  # exact values from the JSON
        gap = cd["gap_mm"]
        fields.append(
            PressureField(g, cd["pressure_MPa"], cd["owner"].astype(np.int64) - 1, np.where(np.isnan(gap), np.inf, gap))
        )
        if "indenter_height_mm" in cd:
            heights.append(np.where(np.isnan(cd["indenter_height_mm"]), np.inf, cd["indenter_height_mm"]))
    return VtkContent(tuple(fields), tuple(heights) if heights else None, meta)
