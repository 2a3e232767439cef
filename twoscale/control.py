"""Penetration or load control: the one check that exactly one of the two is given.

Every solver and the scene take either a rigid approach d (mm, penetration control) or a
total load W (N, load control). :func:`check_control` is the single place that says
"exactly one"; callers name the two quantities as their users know them (``penetration``
and ``total_load`` for the Python functions, ``load.penetration`` and ``load.total`` for
the scene file).
"""
from __future__ import annotations

#: Names of the two quantities in the Python functions.
PYTHON_NAMES = ("penetration", "total_load")


def check_control(penetration, total_load, *, names: tuple[str, str] = PYTHON_NAMES,
                  error: type[Exception] = ValueError) -> str:
    """``"penetration"`` or ``"load"``: which control the caller chose.

    Parameters
    ----------
    penetration : float or None
        Rigid approach d, mm.
    total_load : float or None
        Total load W, N.
    names : (str, str), default ("penetration", "total_load")
        How the message names the two (e.g. ``("load.penetration", "load.total")``).
    error : exception class, default ValueError
        Raised when both or neither are given (e.g. :class:`twoscale.scene.SceneError`).

    Raises
    ------
    error
        One line naming both values: ``give exactly one of penetration (mm) or
        total_load (N), got penetration=None, total_load=None``.
    """
    if (penetration is None) == (total_load is None):
        raise error(f"give exactly one of {names[0]} (mm) or {names[1]} (N), got "
                    f"{names[0]}={penetration!r}, {names[1]}={total_load!r}")
    return "penetration" if penetration is not None else "load"
