"""Words on figures: the body and the scene in titles, one style for axis labels.

A figure title names what was solved: the scene (its file's stem when known) and the
body, e.g. ``S1 on a 140 x 140 x 20 mm block, bonded base``. The body is read from what
the scene already says (its ``influence``), so the same words come from a
:class:`~twoscale.scene.Scene`, its dict record (as written in ``result.json``), or a
result that carries a body label of its own.
"""

from __future__ import annotations

from typing import Any, Mapping

#: Axis labels, one style everywhere: "quantity (unit)".
X_MM, Y_MM = "x (mm)", "y (mm)"


def _num(v: float) -> str:
    return f"{float(v):g}"


def body_text(influence: Mapping[str, Any] | None) -> str:
    """The elastic body in words: ``half-space`` or ``140 x 140 x 20 mm block, bonded base``.

    Parameters
    ----------
    influence : mapping or None
        A scene's ``influence`` (``{"kind": "halfspace"}`` or the block's kind, size (mm)
        and base); None reads as the half-space.
    """
    if not influence or influence.get("kind", "halfspace") == "halfspace":
        return "half-space"
    size = influence.get("size")
    dims = " x ".join(_num(v) for v in size) + " mm " if size else ""
    base = influence.get("base")
    return f"{dims}{influence.get('kind', 'block')}" + (f", {base} base" if base else "")


def _influence_of(scene) -> Mapping | None:
    if scene is None:
        return None
    if isinstance(scene, Mapping):
        return scene.get("influence")
    return getattr(scene, "influence", None)


def scene_text(scene=None, name: str | None = None, *, result=None) -> str:
    """``<name> on <body>`` for a title (``on <body>`` alone without a name; "" with neither).

    Parameters
    ----------
    scene : Scene or mapping, optional
        The scene (or its dict record); its ``influence`` names the body.
    name : str, optional
        The scene's name, e.g. its file's stem (``S1`` for ``examples/S1.toml``).
    result : ContactResult, optional
        Used when it carries a ``body`` label of its own (preferred to the scene's).
    """
    body = getattr(result, "body", None)
    body = getattr(body, "label", body)  # a typed body (twoscale.setting.Body) or a label
    if not isinstance(body, str) or not body:
        inf = _influence_of(scene)
        body = body_text(inf) if (inf is not None or scene is not None) else ""
    if body and body != "half-space" and not body.startswith(("a ", "an ")):
        body = f"a {body}" if body[0].isdigit() else body
    body = "the half-space" if body == "half-space" else body
    if name and body:
        return f"{name} on {body}"
    return name or (f"on {body}" if body else "")


def join_title(*parts: str) -> str:
    """Non-empty parts joined by ": " (the scene first, then what is drawn)."""
    return ": ".join(p for p in parts if p)


def set_fitted_title(ax, title: str) -> None:
    """``ax.set_title(title)`` within the axes' width (a study case's label names section,
    body, material, load and speed: on one line at the default size it ran off the
    figure's edge): a smaller font down to 8 pt, then lines broken at spaces. Characters
    are taken as 0.6 of the font size wide."""
    import textwrap

    from matplotlib import rcParams
    from matplotlib.font_manager import FontProperties

    points = FontProperties(size=rcParams["axes.titlesize"]).get_size_in_points()
    width_pt = ax.get_position().width * ax.figure.get_figwidth() * 72.0
    if len(title) * 0.6 * points <= width_pt:
        ax.set_title(title)
        return
    size = max(8.0, width_pt / (0.6 * len(title)))
    chars = max(20, int(width_pt / (0.6 * size)))
    ax.set_title(textwrap.fill(title, chars, break_long_words=False, break_on_hyphens=False), fontsize=size)
