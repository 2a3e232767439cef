"""The body a command solves on, built once.

A finite block reads its FEM corrections from the on-disk cache when it is built (and drops
a damaged entry there). Built once for the memory check and the solve, the read (or the
drop) is recorded in the solve's ``caches`` (result.json), as a solve that builds its own
body records it; built twice, the second build would find the damaged entry gone and the
record would say nothing was dropped.
"""

from __future__ import annotations

import dataclasses

from ..io.cache_entry import with_construction
from ..scene import Scene


def build_body(scene: Scene, *, quiet: bool = False):
    """The scene's finite block and what its caches did while it was built
    (``provider.cache_usage()``); ``(None, ())`` on the half-space, which is built by the
    solve (it costs nothing and reads no cache)."""
    if scene.influence["kind"] != "block":
        return None, ()
    provider = scene.provider(**({"progress": False} if quiet else {}))
    return provider, provider.cache_usage()


def with_build(result, built: tuple):
    """``result`` (a ContactResult or a HistoryResult) with ``built``, the cache usage of its
    body's build, added to its ``caches``."""
    if not built:
        return result
    return dataclasses.replace(result, caches=with_construction(result.caches, built))
