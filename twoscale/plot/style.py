"""What a figure says about itself (:class:`Caption`) and how it is drawn (:class:`FigureStyle`),
passed whole to the plotting functions instead of long keyword lists."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from .scale import ColourScale


@dataclass(frozen=True)
class Caption:
    """A figure's words and record.

    Attributes
    ----------
    title : str or None, default None
        The title; None: the function's own (most name the scene, the body and what is
        shown).
    scene : Scene or mapping, optional
        The scene solved: its ``influence`` names the body in the title; a mapping is also
        recorded in the PNG's ``Description``.
    name : str or None, default None
        The scene's name (e.g. the scene file's stem), first in the title.
    meta : mapping, optional
        Further JSON-ready entries of the PNG ``Description`` (e.g. the bodies compared).
    """

    title: str | None = None
    scene: Mapping[str, Any] | Any = None
    name: str | None = None
    meta: Mapping[str, Any] | None = None


@dataclass(frozen=True)
class FigureStyle:
    """How a figure is drawn, apart from what it shows (None: the function's default).

    Attributes
    ----------
    size : (float, float) or None
        Figure size, inches, when the function makes the Figure.
    dpi : int or None
        Resolution, dots per inch.
    cmap : str or None
        Colour map name.
    colourbar : bool, default True
        Draw the colour bar.
    scale : ColourScale or None
        The colour scale (its ``top`` ends the scale); default from the data.
    panel_size : float or None
        Width and height of one panel of a multi-panel figure, inches.
    """

    size: tuple[float, float] | None = None
    dpi: int | None = None
    cmap: str | None = None
    colourbar: bool = True
    scale: ColourScale | None = None
    panel_size: float | None = None

    def pick(self, name: str, default: Any) -> Any:
        """This style's ``name`` field, or ``default`` where it is None."""
        value = getattr(self, name)
        return default if value is None else value


#: Defaults of both (the functions take None for them).
NO_CAPTION = Caption()
PLAIN = FigureStyle()
