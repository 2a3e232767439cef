"""The study's headline numbers for the terminal, read back from its own tables.

One row per scene, body and load (the positions summarised): how many positions converged,
the cell size, the approach, the contact area and e_M against the study's first body (each
a range over the positions), then where the tables and the figures are. Read from ``cases.csv`` and ``indicators.csv`` with :mod:`csv`, as any user's
script would.
"""

from __future__ import annotations

import csv
from pathlib import Path

#: Rows printed before the table is cut short (the rest are in cases.csv).
MAX_ROWS = 40


def _read(path: Path) -> list[dict]:
    if not path.is_file():
        return []
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _span(values: list[str], spec: str = ".4g") -> str:
    nums = sorted(float(v) for v in values if v != "")
    if not nums:
        return "-"
    lo, hi = format(nums[0], spec), format(nums[-1], spec)
    return lo if lo == hi else f"{lo}-{hi}"


def _load(kind: str, value: str) -> str:
    return f"W = {float(value):g} N" if kind == "total" else f"d = {float(value):g} mm"


def headline_rows(out: Path) -> tuple[list[list[str]], str]:
    """Rows of the table (strings) and the reference body of e_M ("" without indicators)."""
    cases = _read(out / "cases.csv")
    ind = _read(out / "indicators.csv")
    groups: dict = {}
    for r in cases:
        groups.setdefault((r["scene"], r["body"], r["load_kind"], r["load"]), []).append(r)
    e_M: dict = {}
    for r in ind:
        e_M.setdefault((r["scene"], r["body"], r["load_kind"], r["load"]), []).append(r["e_M_percent"])
    reference = ind[0]["reference"] if ind else ""
    rows = []
    for (scene, body, kind, load), members in groups.items():
        done = [m for m in members if m["status"] == "converged"]
        e = e_M.get((scene, body, kind, load))
        rows.append(
            [
                scene,
                body,
                _load(kind, load),
                f"{len(done)}/{len(members)}",
                _span([m["h_mm"] for m in members]),
                _span([m["approach_mm"] for m in members]),
                _span([m["contact_area_mm2"] for m in members]),
                "-" if not e else _span(e, ".3g"),
            ]
        )
    return rows, reference


def study_table(out: Path) -> str:
    """The headline table and where the files are (see module doc)."""
    out = Path(out)
    rows, reference = headline_rows(out)
    head = [
        "scene",
        "body",
        "load",
        "converged",
        "h mm",
        "approach mm",
        "contact area mm2",
        f"e_M % vs {reference}" if reference else "e_M %",
    ]
    shown = rows[:MAX_ROWS]
    widths = [max(len(x) for x in col) for col in zip(head, *shown)]
    lines = ["  " + "  ".join(h.ljust(w) for h, w in zip(head, widths)).rstrip()]
    lines += ["  " + "  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in shown]
    if len(rows) > MAX_ROWS:
        lines.append(f"  ... {len(rows) - MAX_ROWS} more rows: {out / 'cases.csv'}")
    lines.append(
        "  (ranges over the positions; e_M: the tip forces against the first body's, "
        "100 sum|P - P_ref|^2 / sum|P_ref|^2 in percent)"
    )
    figures = sorted(p.name for p in (out / "figures").glob("*.png")) if (out / "figures").is_dir() else []
    lines.append(
        f"tables: {out}/cases.csv, asperities.csv, indicators.csv (each with .csv-metadata.json"
        f"{', .parquet' if (out / 'cases.parquet').exists() else ''}); summary: {out}/summary.json"
    )
    if figures:
        lines.append(
            f"figures: {out}/figures/: {', '.join(figures[:8])}"
            + (f" and {len(figures) - 8} more" if len(figures) > 8 else "")
        )
    return "\n".join(lines)


__all__ = ["study_table", "headline_rows"]
