"""The law of an asperity from its shape."""

from __future__ import annotations

from ..indenters import Asperity
from ..material import Material
from .base import AsperityLaw
from .hertz import HertzLaw, SphereLaw


def law_for(asperity: Asperity, material: Material) -> AsperityLaw:
    """Half-space law of ``asperity``: :class:`HertzLaw` for shape "paraboloid",
    :class:`SphereLaw` (exact sphere) for "sphere"; radius ``asperity.R`` (mm),
    modulus ``material.E_star`` (MPa). Indenters with a law of their own (a method
    ``law(material)``, e.g. the basins of a height map, :mod:`twoscale.surface`) give it."""
    own = getattr(asperity, "law", None)
    if callable(own):
        return own(material)
    if asperity.shape == "paraboloid":
        return HertzLaw(asperity.R, material.E_star)
    if asperity.shape == "sphere":
        return SphereLaw(asperity.R, material.E_star)
    raise ValueError(f"no law for asperity shape {asperity.shape!r}")
