"""Whose is an output folder: a study writes only into a folder that is new, empty, or
already this study's (to resume it).

A study folder carries ``.twoscale-study.json`` (the study's name and the digest of its
case keys). Another study's folder is replaced only with ``--overwrite``, which removes
that study's tables, summary and figures but keeps ``cases/`` (each case folder is keyed
by its own inputs, so a case shared by both studies is reused, never wrong). A non-empty
folder without the marker is refused: the program never writes among files it did not
write.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from ..io.atomic import atomic_output
from .cases import expand
from .keys import case_key, digest
from .lock import LOCK_NAME

#: The marker file of a study folder.
MARKER = ".twoscale-study.json"
#: What a study writes at the top of its folder, besides ``cases/`` and the marker.
OUTPUTS = tuple(
    f"{name}.{ext}"
    for name in ("cases", "asperities", "indicators", "bands")
    for ext in ("csv", "csv-metadata.json", "parquet")
) + ("summary.json", "figures")


def study_digest(study) -> str:
    """Digest of the study's set of case keys (two files giving the same cases agree)."""
    from .rolling_spec import RollingStudy

    if isinstance(study, RollingStudy):
        from . import rolling_cases

        return digest(sorted(set(rolling_cases.case_key(c, study) for c in rolling_cases.expand(study))))
    return digest(sorted(set(case_key(c, study) for c in expand(study))))


def check_study_folder(out: Path, study, *, overwrite: bool = False) -> str:
    """Raise ``ValueError`` (one line) unless ``out`` may take ``study``'s outputs; with
    ``overwrite``, another study's outputs are removed first (its ``cases/`` kept).
    Returns the study's digest (:func:`study_digest`), for :func:`mark_study_folder`."""
    out = Path(out)
    digest_now = study_digest(study)
    if not out.exists():
        return digest_now
    if not out.is_dir():
        raise ValueError(f"--out {str(out)!r} exists and is not a folder")
    entries = sorted(p.name for p in out.iterdir() if p.name != LOCK_NAME)
    if not entries:
        return digest_now
    marker = out / MARKER
    if not marker.is_file():
        raise ValueError(
            f"--out {str(out)!r} is not empty and is no twoscale study folder (it holds "
            f"{entries[0]!r}): choose a new or empty folder"
        )
    try:
        record = json.loads(marker.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        record = {}
    if record.get("digest") == digest_now:
        return digest_now  # this study: resume
    if not overwrite:
        raise ValueError(
            f"--out {str(out)!r} holds another study ({record.get('name', '?')!r}): rerun that "
            f"study there, choose another folder, or add --overwrite to replace its tables and "
            f"figures (finished cases are kept and reused where the inputs match)"
        )
    for name in OUTPUTS:
        path = out / name
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()
    return digest_now


def mark_study_folder(out: Path, study, digest_now: str | None = None) -> None:
    """Write the marker of ``study`` (its digest, when already computed) into ``out``
    (created if needed)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with atomic_output(out / MARKER) as tmp:
        tmp.write_text(
            json.dumps({"name": study.name, "digest": digest_now or study_digest(study)}) + "\n", encoding="utf-8"
        )
