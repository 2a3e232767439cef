"""Checks of a TOML table shared by the scene file, its ``[surface]`` table and the study
file: unknown or missing keys, a value that must be a table, and the field path a message
names (``load.total``, ``asperity 4: R``). Every problem is a :class:`SceneError`.
"""

from __future__ import annotations

from typing import Any, Mapping

from ..errors import SceneError


def field_path(path: str, key: str) -> str:
    """``load.total``; ``asperity 4: R`` for a numbered table (numbered from 1)."""
    if not path:
        return key
    return f"{path}: {key}" if path[-1:].isdigit() else f"{path}.{key}"


def _shown(key: str) -> str:
    """A key as written in the message: plain when it is a bare TOML key, else quoted (a key
    holding a line break or spaces stays on the one line and visible)."""
    bare = key and all(c.isascii() and (c.isalnum() or c in "_-") for c in key)
    return key if bare else repr(key)


def check_keys(path: str, table: Mapping, allowed, *, required=()) -> None:
    """Refuse a key of ``table`` not in ``allowed`` and a missing ``required`` one."""
    for key in table:
        if key not in allowed:
            raise SceneError(
                f"unknown key {field_path(path, _shown(key))} = {table[key]!r} (allowed: {', '.join(allowed)})"
            )
    for key in required:
        if key not in table:
            raise SceneError(f"{field_path(path, key)} is missing (required)")


def table_of(path: str, v: Any) -> Mapping:
    """``v`` when it is a table (a mapping), else a :class:`SceneError` naming ``path``."""
    if not isinstance(v, Mapping):
        raise SceneError(f"{path} must be a table, got {v!r}")
    return v
