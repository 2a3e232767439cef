"""Output folders: appear whole or not at all, and replace only what twoscale wrote.

The subcommands write their files into a hidden temporary folder beside the target
(``.DIR.tmp-XXXX``) and rename it to ``DIR`` once every file is written; any exception,
Ctrl-C (``KeyboardInterrupt``) included, removes the temporary folder and leaves ``DIR``
as it was. Ctrl-C during the rename or the clean-up is held until they finish, so
neither is left half done.

Every output folder holds a manifest, ``.twoscale-manifest.json``: the program, its
version, the command and the list of files written (paths relative to the folder).
An existing ``DIR`` is accepted when it is empty. A non-empty ``DIR`` is refused
(:class:`OutputFolderError`, checked by :func:`check_output_folder` before any solve)
unless ``overwrite`` is set; then the files its manifest lists are removed (with the
folders left empty) just before the new output takes their place, so no stale file of
an earlier run stays beside the new ones. Files the manifest does not list (or a folder
without a manifest) are never removed: such a folder is refused even with
``overwrite``, naming one of the files, so the user moves them or picks another folder.

Example
-------
>>> import pathlib, tempfile
>>> root = pathlib.Path(tempfile.mkdtemp())
>>> with staged_directory(root / "run") as tmp:
...     _ = (tmp / "a.txt").write_text("x")
>>> sorted(p.name for p in (root / "run").iterdir())
['.twoscale-manifest.json', 'a.txt']
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import tempfile
import threading
from pathlib import Path
from typing import Iterator

from .._version import __version__
from ..errors import OutputFolderError
from ..io.atomic import current_umask

#: The list of files a run wrote, kept in its output folder.
MANIFEST_NAME = ".twoscale-manifest.json"


class Terminated(KeyboardInterrupt):
    """SIGTERM received (the command line turns it into this): unwinds like Ctrl-C, so every
    clean-up that handles Ctrl-C runs."""


@contextlib.contextmanager
def held_interrupts() -> Iterator[None]:
    """Hold SIGINT (Ctrl-C) and, where the command line handles it, SIGTERM until the block
    ends, then raise ``KeyboardInterrupt`` (:class:`Terminated` for SIGTERM) if one came.
    Outside the main thread (where Python cannot install handlers) it holds nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    held = [signal.SIGINT]
    if callable(signal.getsignal(signal.SIGTERM)):  # a Python handler: the command line's
        held.append(signal.SIGTERM)
    previous = {sig: signal.signal(sig, lambda signum, frame: caught.append(signum)) for sig in held}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if signal.SIGTERM in caught:
        raise Terminated
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


def _entries(folder: Path) -> tuple[set, set]:
    """Relative paths (posix) of the files (symbolic links included) and of the folders under ``folder``."""
    files, dirs = set(), set()
    for root, dirnames, filenames in os.walk(folder):
        rel = Path(root).relative_to(folder)
        for d in dirnames:
            (files if (Path(root) / d).is_symlink() else dirs).add((rel / d).as_posix())
        files.update((rel / f).as_posix() for f in filenames)
    return files, dirs


def _manifest_files(folder: Path) -> list[str] | None:
    """The files listed by ``folder``'s manifest, or None without a (readable) manifest."""
    try:
        data = json.loads((folder / MANIFEST_NAME).read_text(encoding="utf-8"))
        files = data["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not (isinstance(files, list) and all(isinstance(f, str) for f in files)):
        return None
    return files


def _foreign(folder: Path, listed: list[str]) -> list[str]:
    """Entries of ``folder`` that are neither listed files, the manifest, nor folders holding them."""
    files, dirs = _entries(folder)
    ours = set(listed) | {MANIFEST_NAME}
    parents = {p.as_posix() for f in listed for p in Path(f).parents if p != Path(".")}
    return sorted((files - ours) | (dirs - parents))


def check_output_folder(out: str | os.PathLike, *, overwrite: bool = False, option: str = "--out") -> None:
    """Refuse an output folder that cannot be written (call it before any solve).

    Accepted: a missing path, an empty folder, and with ``overwrite`` a folder holding
    only files its twoscale manifest lists.

    Raises
    ------
    OutputFolderError
        One line naming ``option``, the path and the reason.
    """
    out = Path(out)
    if not out.exists() and not out.is_symlink():
        return
    if not out.is_dir():
        raise OutputFolderError(f"{option} must be a folder, got {str(out)!r}, which is an existing file")
    if not any(out.iterdir()):
        return
    listed = _manifest_files(out)
    if listed is None:
        raise OutputFolderError(
            f"{option} {str(out)!r} is not empty and was not written by twoscale "
            f"(no {MANIFEST_NAME}): choose another folder"
        )
    if not overwrite:
        raise OutputFolderError(
            f"{option} {str(out)!r} holds the output of an earlier run "
            f"({len(listed)} files): add --overwrite to replace it, or choose another folder"
        )
    foreign = _foreign(out, listed)
    if foreign:
        raise OutputFolderError(
            f"{option} {str(out)!r} holds {len(foreign)} entries twoscale did not write "
            f"(e.g. {foreign[0]!r}); --overwrite removes only its own files: "
            f"move them or choose another folder"
        )


def _clear(out: Path) -> None:
    """Remove the files ``out``'s manifest lists, the manifest, then the folders left empty
    and ``out`` itself (which then holds nothing: checked by :func:`check_output_folder`)."""
    listed = _manifest_files(out) or []
    for f in listed:
        (out / f).unlink(missing_ok=True)
    (out / MANIFEST_NAME).unlink(missing_ok=True)
    for d in sorted(_entries(out)[1], key=lambda p: p.count("/"), reverse=True):
        (out / d).rmdir()
    out.rmdir()


def _write_manifest(folder: Path, command: str) -> None:
    files = sorted(_entries(folder)[0])
    text = json.dumps({"program": "twoscale", "version": __version__, "command": command, "files": files}, indent=1)
    (folder / MANIFEST_NAME).write_text(text + "\n", encoding="utf-8")


@contextlib.contextmanager
def staged_directory(out: str | os.PathLike, *, overwrite: bool = False, command: str = "") -> Iterator[Path]:
    """Yield a temporary folder to write into; on success its content becomes ``out``.

    Parameters
    ----------
    out : path-like
        The output folder. Missing parents are created (and removed again on failure).
    overwrite : bool, default False
        Replace an earlier twoscale output in ``out`` (only the files its manifest lists).
    command : str, default ""
        Recorded in the manifest (e.g. ``"solve scene.toml"``).

    Raises
    ------
    OutputFolderError
        When ``out`` cannot be used (see :func:`check_output_folder`): before anything is
        written, and again at the end if the folder changed meanwhile (then nothing is
        moved into it).
    """
    out = Path(out)
    check_output_folder(out, overwrite=overwrite)
    created = _missing_parents(out.absolute())
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    try:
        yield tmp
        _write_manifest(tmp, command)
        with held_interrupts():
            check_output_folder(out, overwrite=overwrite)  # the folder may have changed during the solve
            os.chmod(tmp, 0o777 & ~current_umask())  # mkdtemp makes it owner-only
            if out.is_dir():
                _clear(out)
            os.rename(tmp, out)
    except BaseException:
        with held_interrupts():
            shutil.rmtree(tmp, ignore_errors=True)
            for parent in created:  # nearest first; only the folders made for this output
                with contextlib.suppress(OSError):
                    parent.rmdir()
        raise
