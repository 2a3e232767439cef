"""Tidy tables: CSV any tool opens, its metadata in a JSON beside it, Parquet for long ones.

Every table the program writes goes through :func:`write_table`, so they all read the same
way:

* ``NAME.csv``: the header on the first line, then one row per observation; numbers as
  numbers (units in the column names, e.g. ``force_N``) written to 10 significant digits,
  which is more than any solve carries and drops binary noise (``7.49``, not
  ``7.490000000000001``); an empty field for a value that does not apply. ``pandas.read_csv``,
  Python's ``csv.DictReader``, R and spreadsheets read it without options.
* ``NAME.csv-metadata.json``: what the CSV cannot say in its cells (program version, units,
  the scene or study, what each column holds), in the layout of the W3C "CSV on the Web"
  metadata (``url``, ``tableSchema.columns`` with ``name``, ``datatype``,
  ``dc:description``) plus a ``twoscale`` record.
* ``NAME.parquet`` beside long tables: a study's tables always, a solve's or a comparison's
  per-tip tables from :data:`LONG_TABLE` rows on (a short table gains nothing from a binary
  copy, and importing pyarrow costs a solve some 30 MB of memory); written only when
  ``pyarrow`` is importable (the ``study`` extra installs it). The CSV is always written.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from .._version import __version__
from .atomic import atomic_output

#: Significant digits of the numbers written (see module doc).
DIGITS = 10
#: Rows from which a per-tip table is long enough for a Parquet copy (``parquet=LONG_TABLE``).
LONG_TABLE = 1000


def cell(v: Any) -> str:
    """One CSV field: "" for None or NaN, integers as integers, floats to :data:`DIGITS`
    significant digits, booleans as ``true`` / ``false``."""
    if v is None:
        return ""
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        v = float(v)
        if not math.isfinite(v):
            return "" if math.isnan(v) else ("inf" if v > 0 else "-inf")
        text = f"{v:.{DIGITS}g}"
        return "0" if text in ("0", "-0") else text
    return str(v)


def csv_text(rows: Iterable[Mapping], columns: Sequence[str]) -> str:
    """The rows as CSV text, header first (keys outside ``columns`` are an error)."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), lineterminator="\n")
    w.writeheader()
    for row in rows:
        w.writerow({k: cell(v) for k, v in row.items()})
    return buf.getvalue()


def _datatype(values: list) -> str:
    present = [v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))]
    if present and all(isinstance(v, (bool, np.bool_)) for v in present):
        return "boolean"
    if present and all(isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)) for v in present):
        return "integer"
    if present and all(
        isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_)) for v in present
    ):
        return "number"
    return "string"


def metadata(
    name: str,
    rows: list,
    columns: Sequence[str],
    *,
    title: str,
    record: Mapping,
    descriptions: Mapping[str, str] | None = None,
) -> dict:
    """The ``NAME.csv-metadata.json`` content (see module doc)."""
    descriptions = descriptions or {}
    cols = []
    for c in columns:
        entry = {"name": c, "titles": c, "datatype": _datatype([r.get(c) for r in rows])}
        if c in descriptions:
            entry["dc:description"] = descriptions[c]
        cols.append(entry)
    return {
        "@context": "http://www.w3.org/ns/csvw",
        "url": f"{name}.csv",
        "dc:title": title,
        "dc:creator": f"twoscale {__version__}",
        "tableSchema": {"columns": cols},
        "twoscale": {"version": __version__, "rows": len(rows), **dict(record)},
    }


def write_table(
    out_dir: str | Path,
    name: str,
    rows: Iterable[Mapping],
    columns: Sequence[str],
    *,
    title: str,
    record: Mapping | None = None,
    descriptions: Mapping[str, str] | None = None,
    parquet: int | None = None,
) -> list[Path]:
    """Write ``NAME.csv``, ``NAME.csv-metadata.json`` and (long tables, with pyarrow) ``NAME.parquet``.

    Parameters
    ----------
    out_dir : path-like
        Existing folder.
    name : str
        File stem.
    rows : iterable of mappings
        One per observation; keys among ``columns`` (a missing key is an empty field).
    columns : sequence of str
        Column names, units in the name (``force_N``, ``contact_area_mm2``).
    title : str
        What the table holds, one line (``dc:title``).
    record : mapping, optional
        JSON-ready data recorded under ``twoscale`` (units, scene, study, source, ...).
    descriptions : mapping, optional
        Column name -> one-line meaning.
    parquet : int, optional
        Also write Parquet, when ``pyarrow`` is importable, for a table of at least this
        many rows (0: always; None, the default: never).

    Returns
    -------
    list of Path written (CSV, metadata, then Parquet when written).
    """
    out = Path(out_dir)
    rows = list(rows)
    written = [out / f"{name}.csv", out / f"{name}.csv-metadata.json"]
    with atomic_output(written[0]) as tmp:
        tmp.write_text(csv_text(rows, columns), encoding="utf-8", newline="")
    meta = metadata(name, rows, columns, title=title, record=record or {}, descriptions=descriptions)
    with atomic_output(written[1]) as tmp:
        tmp.write_text(json.dumps(meta, indent=1, allow_nan=False, default=_json_default) + "\n", encoding="utf-8")
    if parquet is not None and len(rows) >= parquet:
        path = write_parquet(out / f"{name}.parquet", rows, columns)
        if path is not None:
            written.append(path)
    return written


def write_parquet(path: Path, rows: list, columns: Sequence[str]) -> Path | None:
    """The rows as Parquet at ``path``, or None (nothing written) without pyarrow."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return None
    data = {c: [_parquet_value(r.get(c)) for r in rows] for c in columns}
    with atomic_output(path) as tmp:
        pq.write_table(pa.table(data), tmp)
    return path


def _parquet_value(v):
    if isinstance(v, np.generic):
        return v.item()
    return None if v == "" else v


def _json_default(v):
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, (tuple, np.ndarray)):
        return list(v)
    raise TypeError(f"not JSON-serialisable: {v!r}")


__all__ = ["DIGITS", "cell", "csv_text", "metadata", "write_table", "write_parquet"]
