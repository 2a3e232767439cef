"""The key of a case: a hash of everything its result depends on.

Two cases with the same inputs (scene content, body, load, shift, method, solver
options, sensor) get the same key, whatever the study files they come from, so a rerun
finds the results already written; change any input (even a scene file's content under
the same name) and the key changes. Names (of the study, the scene, the body) are not
inputs. The program version is recorded with each result but is not part of the key, so
upgrading does not discard finished cases; bump :data:`KEY_VERSION` when a change makes
old results wrong.
"""

from __future__ import annotations

import hashlib
import json
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the study file's module reads scene digests from here
    from .cases import Case
    from .spec import Study

#: Bumped when a change of the solver or of the stored record makes old results invalid.
KEY_VERSION = 1


def scene_record(scene: Any) -> dict:
    """The scene's content as JSON-ready data (what the key hashes and the record stores).

    The one place that knows how a scene becomes data: scenes of another kind (e.g. a
    measured surface) plug in here."""
    from ..io.scene_file import scene_to_dict

    return scene_to_dict(scene)


def digest(data: Any) -> str:
    """Hex SHA-256 of JSON-ready ``data`` in canonical JSON (sorted keys, ``repr`` floats)."""
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def case_inputs(case: "Case", study: "Study") -> dict:
    """Everything the case's result depends on, as JSON-ready data. The scene enters by the
    digest of its content (``StudyScene.digest``), computed once per scene."""
    fp = case.body.footprint
    out = {
        "key_version": KEY_VERSION,
        "scene": case.scene.digest,
        "influence": {k: (list(v) if isinstance(v, tuple) else v) for k, v in case.body.influence.items()},
        "footprint": {"size": None if fp.size is None else list(fp.size), "centre": list(fp.centre)},
        "load": {case.load[0]: float(case.load[1]), "tilt": study.tilt if case.load[0] == "total" else False},
        "shift": [float(v) for v in case.shift],
        "method": study.method,
        "solver": dict(sorted(study.solver.items())),
        "sensor": {
            "nx": study.sensor.nx,
            "ny": study.sensor.ny,
            "cell": float(study.sensor.cell),
            "centre": list(study.sensor.centre),
        },
    }
    light = lightest_load(case, study)
    if light is not None:  # the default cell size is the lightest load's (studies.cases)
        out["h_at_load"] = {light[0]: float(light[1])}
    return out


def case_key(case: "Case", study: "Study") -> str:
    """The case's key: the :func:`digest` of its inputs."""
    return digest(case_inputs(case, study))


def h_source(case: "Case", study: "Study") -> str:
    """Which rule gives the case's cell size (:data:`H_SOURCES`, module doc)."""
    if study.solver.get("h") is not None:
        return "solver.h"
    return "scene" if case.scene.scene.h is not None else "lightest load"


def lightest_load(case: "Case", study: "Study") -> tuple | None:
    """The study's lightest load of the case's kind on its scene, whose default cell size the
    case uses; None when the study or the scene gives h."""
    if h_source(case, study) != "lightest load":
        return None
    return min((ld for ld in study.loads_of(case.scene.scene) if ld[0] == case.load[0]), key=lambda ld: ld[1])
