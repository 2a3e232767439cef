"""Penetration or load control: the one check that exactly one of the two is given, and
:class:`Loading`, the two with the tilt joint as one value passed to the solvers.

Every solver and the scene take either a rigid approach d (mm, penetration control) or a
total load W (N, load control). :func:`check_control` is the single place that says
"exactly one"; callers name the two quantities as their users know them (``penetration``
and ``total_load`` for the Python functions, ``load.penetration`` and ``load.total`` for
the scene file).
"""

from __future__ import annotations

from dataclasses import dataclass

#: Names of the two quantities in the Python functions.
PYTHON_NAMES = ("penetration", "total_load")


def check_control(
    penetration, total_load, *, names: tuple[str, str] = PYTHON_NAMES, error: type[Exception] = ValueError
) -> str:
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
        raise error(
            f"give exactly one of {names[0]} (mm) or {names[1]} (N), got "
            f"{names[0]}={penetration!r}, {names[1]}={total_load!r}"
        )
    return "penetration" if penetration is not None else "load"


@dataclass(frozen=True)
class Loading:
    """How the rigid indenter is driven (checked by the solver that receives it).

    Attributes
    ----------
    penetration : float or None, default None
        Rigid approach d, mm (penetration control).
    total_load : float or None, default None
        Total load W, N (load control); exactly one of the two.
    tilt : bool, default False
        Ball-and-socket joint (with ``total_load``): the tilt angles are solved so that
        the moments about ``pivot`` vanish.
    pivot : (float, float), default (0, 0)
        Pivot of the joint, mm.
    """

    penetration: float | None = None
    total_load: float | None = None
    tilt: bool = False
    pivot: tuple = (0.0, 0.0)
