"""List or clear the on-disk caches (block corrections, surface laws): what, where, how large.

``twoscale cache [list]`` prints one line per cache: its name, folder, entries and size.
``twoscale cache clear [NAME]`` deletes the entries of every cache, or of the one named
(``block-corrections`` or ``surface-laws``); other files in the folders are left alone. Clearing is
always safe: entries are computed again when a solve needs them (the block's FEM solves and
the surface's law tabulation then take their time again). The folders are
``$TWOSCALE_CACHE_DIR`` (block corrections) and ``$TWOSCALE_CACHE_DIR/surface-laws`` when it is set,
else ``~/.cache/twoscale/fem`` and ``~/.cache/twoscale/surface-laws`` (see
:mod:`twoscale.caches`).

Exit codes: 0 done; 2 bad input (an unknown cache name), or a folder that cannot be read
or cleared (one ``error: ...`` line).
"""

from __future__ import annotations

import argparse
import sys

from ..caches import ENV_VAR, caches

#: Actions of ``twoscale cache``.
ACTIONS = ("list", "clear")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``twoscale cache``."""
    names = tuple(c.name for c in caches())
    parser.add_argument(
        "action",
        nargs="?",
        choices=ACTIONS,
        default="list",
        help="list (default): each cache's folder, entries and size; clear: delete entries",
    )
    parser.add_argument(
        "name",
        nargs="?",
        choices=names,
        default=None,
        help=f"with clear: only this cache ({' or '.join(names)}); default every cache",
    )


def human_size(n: int) -> str:
    """Bytes as B, kB, MB or GB (powers of 1000), three significant digits."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n} B"


def not_a_folder(folder) -> str:
    """Where ``folder`` (or the nearest of its parents that exists) is not a folder: that
    path, else "" (a folder not made yet is an empty cache)."""
    p = folder
    while not p.exists() and p != p.parent:
        p = p.parent
    return "" if p.is_dir() else str(p)


def run(args: argparse.Namespace) -> int:
    """Run ``twoscale cache``; returns the exit code (see the module doc)."""
    for c in caches():
        blocked = not_a_folder(c.folder) if args.name in (None, c.name) else ""
        if blocked:
            print(f"error: {c.name}: {blocked} is a file, not a folder (check ${ENV_VAR})", file=sys.stderr)
            return 2
    if args.action == "list":
        if args.name is not None:
            chosen = [c for c in caches() if c.name == args.name]
        else:
            chosen = list(caches())
        rows = [(c.name, str(c.folder), str(len(c.entries())), human_size(c.size()), c.description) for c in chosen]
        widths = [max(len(r[i]) for r in rows + [("cache", "folder", "entries", "size")]) for i in range(4)]
        print(
            f"{'cache':<{widths[0]}}  {'folder':<{widths[1]}}  {'entries':>{widths[2]}}  {'size':>{widths[3]}}  holds"
        )
        for r in rows:
            print(f"{r[0]:<{widths[0]}}  {r[1]:<{widths[1]}}  {r[2]:>{widths[2]}}  {r[3]:>{widths[3]}}  {r[4]}")
        return 0
    for c in caches():
        if args.name is None or c.name == args.name:
            n, freed = c.clear()
            print(f"cleared {c.name}: {n} entries, {human_size(freed)} ({c.folder})")
    return 0
