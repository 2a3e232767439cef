"""Expansion of a study into cases, and the scene each case solves.

A case is one scene on one body at one load and one position. Its scene is the study's
scene with the body's ``[influence]``, the case's load, and the tips shifted by the
position; only the tips whose shifted (x, y) lies in the body's footprint are kept (the
others do not touch: beyond the block's top face there is no body, and a window on the
half-space lets a long texture pass under it). The kept tips keep their index in the
scene file (``Case`` results report forces by that index).

The cell size is one per scene, body and position across the study's loads, so a load
sweep does not change the discretisation: ``[solver] h`` when given, else the scene's
``grid.h``, else the default rule (:func:`twoscale.scene.default_h`) applied at the
lightest load of the case's kind (smallest total load, or smallest penetration), whose
contacts are the smallest (:func:`case_h`; ``h_source`` in the cases table says which).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from .keys import h_source, lightest_load  # noqa: F401  (the rule lives with the case's key)
from .spec import Body, Study, StudyScene


@dataclass(frozen=True)
class Case:
    """One case of a study.

    Attributes
    ----------
    scene : StudyScene
    body : Body
    load : (kind, value)
        ``("total", W N)`` or ``("penetration", d mm)``.
    position : int
        Index into the study's positions.
    shift : (float, float)
        Shift of every tip, mm.
    ref : (int, int, (kind, value), int)
        Scene index, body index, load and position index: enough to rebuild the case from
        the study (:func:`case_at`), which is what a Dask task is sent.
    """

    scene: StudyScene
    body: Body
    load: tuple
    position: int
    shift: tuple
    ref: tuple

    @property
    def label(self) -> str:
        """Readable name, e.g. ``S2 halfspace W=200N p3``."""
        kind, v = self.load
        load = f"W={v:g}N" if kind == "total" else f"d={v:g}mm"
        return f"{self.scene.name} {self.body.name} {load} p{self.position}"


def case_at(study: Study, scene: int, body: int, load: tuple, position: int) -> Case:
    """The case of ``study`` at these indices (see ``Case.ref``)."""
    return Case(
        study.scenes[scene],
        study.bodies[body],
        tuple(load),
        position,
        tuple(study.positions[position]),
        (scene, body, tuple(load), position),
    )


def expand(study: Study) -> list[Case]:
    """Every case of ``study``, scenes outermost, then bodies, loads, positions."""
    return [
        case_at(study, i, j, load, k)
        for i, sc in enumerate(study.scenes)
        for j in range(len(study.bodies))
        for load in study.loads_of(sc.scene)
        for k in range(len(study.positions))
    ]


def kept_tips(case: Case) -> np.ndarray:
    """Indices (scene order) of the tips whose shifted position lies in the body's footprint."""
    tips = np.array([[a.x, a.y] for a in case.scene.scene.asperities], dtype=float) + np.asarray(case.shift)
    return np.flatnonzero(case.body.footprint.contains(tips))


def case_scene(case: Case, study: Study) -> Any:
    """The scene the case solves (validated by the scene's own checks).

    Raises
    ------
    SceneError
        No tip under the footprint, or a load the scene rejects (a penetration below every
        kept tip's recess).
    """
    from ..scene import SceneError

    scene = case.scene.scene
    keep = kept_tips(case)
    if len(keep) == 0:
        raise SceneError(
            f"no tip lies in the footprint of {case.body.name} at shift ({case.shift[0]:g}, {case.shift[1]:g}) mm"
        )
    sx, sy = case.shift
    asperities = tuple(
        dataclasses.replace(scene.asperities[k], x=scene.asperities[k].x + sx, y=scene.asperities[k].y + sy)
        for k in keep
    )
    kind, value = case.load
    if kind == "total":
        tilt = scene.tilt if study.tilt is None else study.tilt
        load = dict(total_load=value, penetration=None, tilt=tilt, pivot=scene.pivot if tilt else (0.0, 0.0))
    else:  # penetration control has no joint
        load = dict(penetration=value, total_load=None, tilt=False, pivot=(0.0, 0.0))
    h = study.solver.get("h", scene.h)
    built = dataclasses.replace(
        scene, asperities=asperities, influence=dict(case.body.influence), load_cases=(), h=h, **load
    )
    light = lightest_load(case, study)
    if light is None or light == case.load:
        return built
    return dataclasses.replace(built, h=_default_h_at(dataclasses.replace(case, load=light), study))


#: What chose a case's cell size (the cases table's ``h_source``).
H_SOURCES = ("solver.h", "scene", "lightest load")


def _default_h_at(case: Case, study: Study) -> float | None:
    """The default cell size of ``case``'s scene (None, the case's own default, when that
    scene cannot be built or sized: the case then fails or runs and says why)."""
    from ..scene import SceneError, default_h

    try:
        return default_h(case_scene(case, study))
    except SceneError:
        return None
