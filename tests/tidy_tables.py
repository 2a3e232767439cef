"""A check shared by the tests of every command that writes tables: the table opens as a
user opens it (pandas and the csv module, no options) and says what it holds."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

#: Column-name endings that carry a unit: such a column holds numbers (or nothing).
NUMERIC = re.compile(r"_(N|mm|mm2|MPa|percent|s|rad)$")


def assert_tidy(path: Path, rows: int | None = None) -> list[dict]:
    """Assert ``path`` is a tidy table (see module doc); returns its rows as dicts of strings."""
    import pandas as pd

    path = Path(path)
    text = path.read_text(encoding="utf-8")
    assert not text.startswith("#"), f"{path.name}: a comment line before the header"
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        records = list(reader)
        header = reader.fieldnames
    frame = pd.read_csv(path)
    assert list(frame.columns) == header, path.name
    assert len(frame) == len(records), path.name
    if rows is not None:
        assert len(records) == rows, path.name
    for col in header:
        if NUMERIC.search(col) and frame[col].notna().any():
            assert pd.api.types.is_numeric_dtype(frame[col]), f"{path.name}: {col} is not numeric"
    for r in records:  # numbers written with the precision they carry: at most 10 digits
        for col, v in r.items():
            if NUMERIC.search(col) and v:
                mantissa = v.lstrip("-").split("e")[0].replace(".", "").lstrip("0")
                assert len(mantissa) <= 10, f"{path.name}: {col} = {v}"
    meta = json.loads(path.with_name(path.name + "-metadata.json").read_text(encoding="utf-8"))
    assert meta["url"] == path.name and [c["name"] for c in meta["tableSchema"]["columns"]] == header
    assert meta["twoscale"]["version"] and meta["twoscale"]["rows"] == len(records)
    return records
