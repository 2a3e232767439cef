"""Checks shared by the study files' readers (:mod:`.spec`, :mod:`.rolling_spec`): arrays of
tables and the names of their entries, each failure one :class:`~twoscale.errors.StudyError`
naming the key and the value."""

from __future__ import annotations

from typing import Any

from ..errors import StudyError
from ..io.scene_file import table_of


def tables(path: str, v: Any) -> list:
    """``v``, a non-empty array of tables (``[[path]]``)."""
    if not isinstance(v, list) or not v:
        raise StudyError(f"{path} must be a non-empty array of tables ([[{path}]]), got {v!r}")
    for k, t in enumerate(v):
        table_of(f"{path} {k + 1}", t)
    return v


def name(path: str, v: Any, seen: set) -> None:
    """Check that ``v`` is a name (no slashes) not in ``seen``, and add it."""
    if not isinstance(v, str) or not v or any(c in v for c in "/\\\n"):
        raise StudyError(f"{path} must be a non-empty name without slashes, got {v!r}")
    if v in seen:
        raise StudyError(f"{path} repeats the name {v!r}")
    seen.add(v)
