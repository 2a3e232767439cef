"""VTK XML image data (``.vti``) and multiblock (``.vtm``) files, written with numpy.

A regular grid of square cells is what VTK calls image data: an origin, a spacing and
an extent; no point coordinates or connectivity are stored, only the cell arrays. The
arrays go after the XML header as raw little-endian bytes (``<AppendedData
encoding="raw">``, each array preceded by its byte count as UInt64), so writing costs
little more than the bytes themselves; ``binary=False`` writes them as ASCII text
inside the XML instead (exact: every float is written by ``repr``).

A multiblock file lists such images by relative path; ParaView and pyvista open it as
one dataset. Neither pyvista nor VTK is needed to write or read these files.

Example
-------
>>> import pathlib, tempfile, numpy as np
>>> from twoscale.grid import Grid
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> g = Grid(0.5, 0.5, 1.0, 3, 2)
>>> _ = write_image(d / "a.vti", g, {"p": np.arange(6.0).reshape(2, 3)})
>>> image = read_image(d / "a.vti")
>>> image.grid == g, float(image.cell_data["p"][1, 2])
(True, 5.0)
"""

from __future__ import annotations

import contextlib
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Mapping, Sequence
from xml.sax.saxutils import quoteattr

import numpy as np

from ..grid import Grid

#: numpy dtype -> VTK type name, for the arrays these files hold.
VTK_TYPES = {
    np.dtype("<f8"): "Float64",
    np.dtype("<f4"): "Float32",
    np.dtype("<i8"): "Int64",
    np.dtype("<i4"): "Int32",
    np.dtype("u1"): "UInt8",
}
_NUMPY = {v: k for k, v in VTK_TYPES.items()}
_HEADER = '<VTKFile type="{kind}" version="1.0" byte_order="LittleEndian" header_type="UInt64">\n'


@dataclass(frozen=True)
class Image:
    """What :func:`read_image` returns: the grid, cell arrays shaped ``(ny, nx)``, field
    arrays (1-D) and the first XML comment of the file (``""`` if none)."""

    grid: Grid
    cell_data: dict
    field_data: dict
    comment: str


def _le(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a)
    a = np.ascontiguousarray(a, dtype=a.dtype.newbyteorder("<") if a.dtype.itemsize > 1 else a.dtype)
    if a.dtype not in VTK_TYPES:
        raise ValueError(f"no VTK type for arrays of dtype {a.dtype}")
    return a


def _array_xml(name: str, a: np.ndarray, tuples_attr: str, binary: bool, offset: int) -> str:
    head = f'<DataArray type="{VTK_TYPES[a.dtype]}" Name={quoteattr(name)}{tuples_attr}'
    if binary:
        return f'{head} format="appended" offset="{offset}"/>\n'
    text = " ".join(map(repr, a.ravel().tolist()))
    return f'{head} format="ascii">\n{text}\n</DataArray>\n'


def write_image(
    path: str | Path,
    grid: Grid,
    cell_data: Mapping[str, np.ndarray],
    *,
    field_data: Mapping[str, np.ndarray] | None = None,
    comment: str | None = None,
    binary: bool = True,
) -> Path:
    """Write cell arrays on ``grid`` (each ``(ny, nx)``, row = y) as a ``.vti`` file.

    Parameters
    ----------
    path : path-like
        Output file (written directly: callers stage it when it must appear whole).
    grid : Grid
        Cell centres ``(x0 + i h, y0 + j h)``, mm; the image lies in the plane z = 0.
    cell_data : mapping name -> (ny, nx) array
        Float64/Float32/Int64/Int32/UInt8 arrays.
    field_data : mapping name -> 1-D array, optional
        Arrays not tied to cells (e.g. UTF-8 bytes of a JSON text as UInt8).
    comment : str, optional
        An XML comment on the second line (must not contain ``--``).
    binary : bool, default True
        Raw appended bytes (fast, exact) or ASCII text (exact, larger, slower).

    Returns
    -------
    Path written.
    """
    path = Path(path)
    arrays, parts, offset = [], [], 0

    def add(name, a, tuples_attr):
        nonlocal offset
        a = _le(a)
        parts.append(_array_xml(name, a, tuples_attr, binary, offset))
        arrays.append(a)
        offset += 8 + a.nbytes

    x_min, _, y_min, _ = grid.bounds
    extent = f"0 {grid.nx} 0 {grid.ny} 0 0"
    parts.append(
        f'<ImageData WholeExtent="{extent}" Origin="{x_min!r} {y_min!r} 0.0" '
        f'Spacing="{grid.h!r} {grid.h!r} {grid.h!r}">\n'
    )
    if field_data:
        parts.append("<FieldData>\n")
        for name, a in field_data.items():
            add(name, np.asarray(a).ravel(), f' NumberOfTuples="{np.asarray(a).size}"')
        parts.append("</FieldData>\n")
    parts.append(f'<Piece Extent="{extent}">\n<PointData>\n</PointData>\n<CellData>\n')
    for name, a in cell_data.items():
        if np.shape(a) != grid.shape:
            raise ValueError(f"cell array {name!r} has shape {np.shape(a)}, grid is {grid.shape}")
        add(name, a, "")
    parts.append("</CellData>\n</Piece>\n</ImageData>\n")
    _write(path, "ImageData", parts, arrays if binary else [], comment)
    return path


def _write(path: Path, kind: str, parts: list, arrays: list, comment: str | None) -> None:
    head = '<?xml version="1.0"?>\n'
    if comment is not None:
        if "--" in comment:
            raise ValueError("an XML comment may not contain '--'")
        head += f"<!-- {comment} -->\n"
    with open(path, "wb") as f:
        f.write((head + _HEADER.format(kind=kind) + "".join(parts)).encode("utf-8"))
        if arrays:
            f.write(b'<AppendedData encoding="raw">\n_')
            for a in arrays:
                f.write(np.uint64(a.nbytes).tobytes())
                f.write(memoryview(a).cast("B"))
            f.write(b"\n</AppendedData>\n")
        f.write(b"</VTKFile>\n")


def write_multiblock(path: str | Path, blocks: Sequence[tuple[str, str]], *, comment: str | None = None) -> Path:
    """Write a ``.vtm`` file listing ``(name, relative file)`` blocks, in order."""
    path = Path(path)
    parts = ["<vtkMultiBlockDataSet>\n"]
    parts += [
        f'<DataSet index="{k}" name={quoteattr(name)} file={quoteattr(file)}/>\n'
        for k, (name, file) in enumerate(blocks)
    ]
    parts.append("</vtkMultiBlockDataSet>\n")
    _write(path, "vtkMultiBlockDataSet", parts, [], comment)
    return path


@contextlib.contextmanager
def _damaged_is_value_error(path: str | Path) -> Iterator[None]:
    """What parsing a damaged file raises (XML cut short, arrays shorter than their byte
    counts, attributes missing) as one ``ValueError`` that names the file."""
    try:
        yield
    except (ValueError, ET.ParseError, IndexError, KeyError, TypeError, AttributeError) as exc:
        text = str(exc).strip().splitlines()
        reason = text[0] if text else type(exc).__name__
        if reason.startswith(str(path)):
            raise
        raise ValueError(f"{path}: damaged or not a VTK file written by twoscale ({reason})") from None


def _header(data: bytes) -> tuple[ET.Element, str, int]:
    """The XML tree (appended data cut off), the first comment, and where raw data start."""
    cut = data.find(b"<AppendedData")
    start = -1
    if cut >= 0:
        start = data.index(b"_", cut) + 1
        text = data[:cut].decode("utf-8") + "</VTKFile>"
    else:
        text = data.decode("utf-8")
    comment = ""
    i = text.find("<!--")
    if 0 <= i < text.find("<VTKFile"):
        comment = text[i + 4 : text.index("-->", i)].strip()
    return ET.fromstring(text[text.index("<VTKFile") :]), comment, start


def _array(el: ET.Element, data: bytes, start: int) -> np.ndarray:
    dtype = _NUMPY.get(el.get("type"))
    if dtype is None:
        raise ValueError(f"unsupported VTK array type {el.get('type')!r}")
    if el.get("format") == "ascii":
        return np.array((el.text or "").split(), dtype=dtype)
    if el.get("format") != "appended" or start < 0:
        raise ValueError(f"unsupported VTK array format {el.get('format')!r}")
    at = start + int(el.get("offset"))
    n = int(np.frombuffer(data, dtype="<u8", count=1, offset=at)[0])
    return np.frombuffer(data, dtype=dtype, count=n // dtype.itemsize, offset=at + 8).copy()


def read_image(path: str | Path) -> Image:
    """Read a ``.vti`` file written by :func:`write_image` (raw appended or ASCII arrays).
    A damaged file (cut short, overwritten) is a ``ValueError`` naming it."""
    with _damaged_is_value_error(path):
        return _read_image(path, Path(path).read_bytes())


def _read_image(path: str | Path, data: bytes) -> Image:
    root, comment, start = _header(data)
    image = root.find("ImageData")
    if root.get("type") != "ImageData" or image is None:
        raise ValueError(f"{path} is not VTK image data")
    x_min, y_min, _ = (float(v) for v in image.get("Origin").split())
    h = float(image.get("Spacing").split()[0])
    e = [int(v) for v in image.get("WholeExtent").split()]
    nx, ny = e[1] - e[0], e[3] - e[2]
    grid = Grid(x_min + h / 2, y_min + h / 2, h, nx, ny)
    fields = {el.get("Name"): _array(el, data, start) for el in image.iterfind("FieldData/DataArray")}
    cells = {
        el.get("Name"): _array(el, data, start).reshape(grid.shape) for el in image.iterfind("Piece/CellData/DataArray")
    }
    return Image(grid, cells, fields, comment)


def read_multiblock(path: str | Path) -> tuple[list[tuple[str, Path]], str]:
    """The ``(name, path)`` blocks of a ``.vtm`` file (paths resolved beside it) and its comment."""
    path = Path(path)
    with _damaged_is_value_error(path):
        root, comment, _ = _header(path.read_bytes())
    mb = root.find("vtkMultiBlockDataSet")
    if root.get("type") != "vtkMultiBlockDataSet" or mb is None:
        raise ValueError(f"{path} is not a VTK multiblock file")
    return [(el.get("name", ""), path.parent / el.get("file")) for el in mb.iter("DataSet")], comment
