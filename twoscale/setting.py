"""What was solved, in words and in the numbers a reader looks for first: the body and the
nominal area.

:class:`Body` describes the elastic body a solve ran on (kind, block size and base) with a
short label for titles and summaries (``"half-space"``, ``"block 60 x 60 x 10 mm, bonded
base"``). :func:`nominal_area` is the area the contact area is compared with:

* a height map (a scene with a ``surface``): the map's area;
* discrete tips: the box holding every tip's base, a disc around each tip of radius R for a
  sphere (its base: a sphere has no material beyond it) and, for a paraboloid, the radius
  where it stands twice the deepest expected approach above its tip;

each cut to the block's top face when the body is a finite block (only contact inside the
face is possible). The ratio ``contact_area / nominal_area`` is the real-to-nominal contact
area ratio of tribology.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: Labels of the body kinds (other kinds are shown by their own name).
KIND_LABELS = {"halfspace": "half-space", "block": "block"}


@dataclass(frozen=True)
class Body:
    """The elastic body of a solve.

    Attributes
    ----------
    kind : str
        ``"halfspace"``, ``"block"``, or a provider's own ``kind``.
    size : (Lx, Ly, t) or None
        Block width, depth and thickness, mm (None for the half-space).
    base : str or None
        Block base, ``"bonded"`` or ``"sliding"`` (None for the half-space).
    origin : (x0, y0) or None
        Where the scene's (0, 0) sits from the block top face's centre, mm.
    """

    kind: str = "halfspace"
    size: tuple | None = None
    base: str | None = None
    origin: tuple | None = None

    @classmethod
    def of(cls, provider) -> "Body":
        """The body of an influence provider (its ``kind``, and a block's size, base, origin)."""
        size, origin = getattr(provider, "size", None), getattr(provider, "origin", None)
        return cls(
            kind=str(getattr(provider, "kind", type(provider).__name__)),
            size=None if size is None else tuple(float(v) for v in size),
            base=getattr(provider, "base", None),
            origin=None if origin is None else tuple(float(v) for v in origin),
        )

    @property
    def label(self) -> str:
        """Short human description: ``"half-space"``, ``"block 60 x 60 x 10 mm, bonded base"``."""
        text = KIND_LABELS.get(self.kind, self.kind)
        if self.size is not None:
            text += " " + " x ".join(f"{v:g}" for v in self.size) + " mm"
        if self.base is not None:
            text += f", {self.base} base"
        return text

    def top_face(self) -> tuple[float, float, float, float] | None:
        """The block's top face as ``(x0, x1, y0, y1)`` in the scene frame, mm (None: unbounded)."""
        if self.size is None:
            return None
        ox, oy = self.origin or (0.0, 0.0)
        lx, ly = self.size[0] / 2.0, self.size[1] / 2.0
        return (-ox - lx, -ox + lx, -oy - ly, -oy + ly)

    def as_dict(self) -> dict:
        """JSON-ready (result.json's ``body``)."""
        out: dict = {"kind": self.kind, "label": self.label}
        if self.size is not None:
            out["size_mm"] = list(self.size)
        if self.base is not None:
            out["base"] = self.base
        if self.origin is not None:
            out["origin_mm"] = list(self.origin)
        return out


def indenter_box(scene) -> tuple[tuple[float, float, float, float], str]:
    """The indenter's extent ``(x0, x1, y0, y1)`` mm and what it is (see module doc)."""
    if getattr(scene, "surface", None) is not None:
        g = scene.surface.hmap.grid
        x0, y0 = g.x0 - g.h / 2.0, g.y0 - g.h / 2.0
        return (x0, x0 + g.nx * g.h, y0, y0 + g.ny * g.h), "height map"
    from .scene import expected_approaches

    try:
        reach = 2.0 * float(expected_approaches(scene).max())
    except ValueError:
        reach = math.inf
    r = [a.R if a.shape == "sphere" else a.reach(reach) for a in scene.asperities]
    xs = [a.x for a in scene.asperities]
    ys = [a.y for a in scene.asperities]
    return (
        (
            min(x - rk for x, rk in zip(xs, r)),
            max(x + rk for x, rk in zip(xs, r)),
            min(y - rk for y, rk in zip(ys, r)),
            max(y + rk for y, rk in zip(ys, r)),
        ),
        "tips' bases",
    )


def nominal_area(scene, body: Body) -> tuple[float, str]:
    """Nominal area (mm2) and a few words on what it is (see module doc)."""
    (x0, x1, y0, y1), basis = indenter_box(scene)
    face = body.top_face()
    if face is not None:
        x0, x1, y0, y1 = max(x0, face[0]), min(x1, face[1]), max(y0, face[2]), min(y1, face[3])
        basis += " within the block's top face"
    return max(x1 - x0, 0.0) * max(y1 - y0, 0.0), basis


def with_setting(result, scene, provider, *, scene_name: str = ""):
    """``result`` with its body, nominal area and scene name filled in (a result of another
    type, from a solver of the caller's own, is returned as it is)."""
    import dataclasses

    from .results import ContactResult

    if not isinstance(result, ContactResult):
        return result
    body = Body.of(provider)
    area, basis = nominal_area(scene, body)
    return dataclasses.replace(
        result, body=body, nominal_area=area, nominal_area_basis=basis, scene_name=scene_name or result.scene_name
    )


__all__ = ["Body", "nominal_area", "indenter_box", "with_setting"]
