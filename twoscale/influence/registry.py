"""Elastic bodies by kind: the one place where ``twoscale`` reaches a provider it does not hold.

The half-space lives in this package. The finite block lives in the separate package
``fem_influence``, which builds on ``twoscale`` (its provider subclasses
:class:`~twoscale.influence.base.InfluenceProvider`); ``twoscale`` never imports it by an
import statement, only through :func:`body_class` on first use, so importing ``twoscale``
stays light and works without scikit-fem. The table below is the declared entry point
(a test checks that no other module of ``twoscale`` imports ``fem_influence``).

A caller with another body passes its provider object to the solver instead
(``twoscale.solve(..., provider=...)``); nothing needs registering.
"""

from __future__ import annotations

import importlib

from ..material import Material

#: Bodies by the scene file's ``influence.kind``: (module, class) of the provider.
PROVIDERS = {"halfspace": ("twoscale.influence.halfspace", "HalfSpace"), "block": ("fem_influence", "BlockProvider")}


def body_class(kind: str) -> type:
    """The provider class of ``kind`` ("halfspace" or "block"), imported now.

    Raises
    ------
    ValueError
        For an unknown kind.
    ImportError
        When the package holding it cannot be imported; the message names the package
        and the reason (e.g. scikit-fem missing).
    """
    if kind not in PROVIDERS:
        raise ValueError(f"body kind must be one of {tuple(PROVIDERS)}, got {kind!r}")
    module, name = PROVIDERS[kind]
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise ImportError(f"the {kind} body needs {module}.{name}, which cannot be imported ({exc})") from exc


def unavailable(kind: str) -> str:
    """Why ``kind`` cannot be built here ("" when it can)."""
    try:
        body_class(kind)
    except ImportError as exc:
        return str(exc)
    return ""


def make_body(kind: str, material: Material, **options):
    """A provider of ``kind`` for ``material``; ``options`` go to its constructor.

    Block options: ``size`` (Lx, Ly, t) mm, ``base`` "bonded" | "sliding", ``origin``
    (x0, y0) mm, and the builder's (``progress``, ``cache_dir``, ...). The half-space
    takes none.
    """
    if kind == "halfspace" and options:
        raise ValueError(f"the half-space provider takes no options, got {sorted(options)!r}")
    return body_class(kind)(material, **options)
