"""An output folder that appears whole or not at all.

The subcommands write their files into a hidden temporary folder beside the target
(``.DIR.tmp-XXXX``) and rename it to ``DIR`` once every file is written; any exception,
Ctrl-C (``KeyboardInterrupt``) included, removes the temporary folder and leaves ``DIR``
as it was. When ``DIR`` already exists, each new file replaces its namesake in one
``os.replace`` (files already there and not rewritten stay). Ctrl-C during the rename or
the clean-up is held until they finish, so neither is left half done.

Example
-------
>>> import pathlib, tempfile
>>> root = pathlib.Path(tempfile.mkdtemp())
>>> with staged_directory(root / "run") as tmp:
...     _ = (tmp / "a.txt").write_text("x")
>>> sorted(p.name for p in (root / "run").iterdir())
['a.txt']
"""
from __future__ import annotations

import contextlib
import os
import shutil
import signal
import tempfile
import threading
from pathlib import Path
from typing import Iterator


@contextlib.contextmanager
def held_interrupts() -> Iterator[None]:
    """Hold SIGINT (Ctrl-C) until the block ends, then raise ``KeyboardInterrupt`` if one
    came. Outside the main thread (where Python cannot install handlers) it holds nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if caught:
        raise KeyboardInterrupt


def _missing_parents(path: Path) -> list[Path]:
    """The ancestors of ``path`` that do not exist, nearest first."""
    missing = []
    for parent in path.parents:
        if parent.exists():
            break
        missing.append(parent)
    return missing


def _merge_into(src: Path, dst: Path) -> None:
    """Move every entry of ``src`` into the existing folder ``dst`` (files by ``os.replace``,
    folders merged the same way)."""
    for entry in src.iterdir():
        target = dst / entry.name
        if entry.is_dir() and target.is_dir():
            _merge_into(entry, target)
        else:
            if target.is_dir():
                shutil.rmtree(target)
            os.replace(entry, target)


@contextlib.contextmanager
def staged_directory(out: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary folder to write into; on success its content becomes ``out``.

    Parameters
    ----------
    out : path-like
        The output folder. Missing parents are created (and removed again on failure).

    Raises
    ------
    NotADirectoryError
        When ``out`` exists and is not a folder (before anything is written).
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"output {out} exists and is not a folder")
    created = _missing_parents(out.absolute())
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    try:
        yield tmp
    except BaseException:
        with held_interrupts():
            shutil.rmtree(tmp, ignore_errors=True)
            for parent in created:  # nearest first; only the folders made for this output
                with contextlib.suppress(OSError):
                    parent.rmdir()
        raise
    with held_interrupts():
        os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp makes it owner-only
        if out.is_dir():
            _merge_into(tmp, out)
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            os.rename(tmp, out)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
