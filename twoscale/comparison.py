"""Comparing solves: per-asperity tables and the paper's indicators e_M and e_m between them.

A :class:`Run` is one solve of one load case on one body; :func:`indicators` gives e_M
(tip forces) and e_m (pressure averaged on the sensor cells), in percent, between every
pair of bodies at each load, and against measured data (:class:`Measured`);
:func:`folder_indicators` does the same for two output folders of ``twoscale solve``.
``twoscale compare`` and ``twoscale indicators`` are thin commands over these.

Numbering: rows written for people (:func:`per_asperity_rows`) number asperities from 1,
as the scene file lists them; arrays are 0-based.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from .scene import Scene
from .sensor import Sensor, centred_tips, e_M, e_m, pivot_from_forces

#: Columns of :func:`per_asperity_rows` (``twoscale compare``'s forces.csv): the load as
#: numbers, ``load_N`` (the given total load) or ``penetration_mm`` (the given approach), the
#: other one empty.
ROW_FIELDS = (
    "load_N",
    "penetration_mm",
    "body",
    "asperity",
    "force_N",
    "contact_area_mm2",
    "max_pressure_MPa",
    "macro_force_N",
)
#: Columns of :func:`tip_changes` (``twoscale compare``'s changes.csv).
CHANGE_FIELDS = (
    "load_N",
    "penetration_mm",
    "reference",
    "body",
    "asperity",
    "reference_force_N",
    "force_N",
    "change_N",
    "change_percent",
)
#: Tips whose reference force is below this fraction of the largest are not ranked among the
#: largest changes (a tip that barely touches changes by any percentage).
RANKED_FORCE_FRACTION = 0.01


@dataclasses.dataclass(frozen=True)
class Run:
    """One solve: the load label (``"50N"`` or ``"d0.5mm"``), the body, the scene solved,
    its result (ContactResult), the wall time, s, and the warnings the solve raised
    (:meth:`twoscale.io.warning_log.WarningLog.entries`, for its ``result.json``)."""

    load: str
    body: str
    scene: Scene
    result: object
    seconds: float
    warnings: tuple = ()


@dataclasses.dataclass(frozen=True)
class Measured:
    """Measured data for one load case: tip forces (N, scene order) and/or a sensor map (MPa)."""

    forces: np.ndarray | None
    sensor_map: np.ndarray | None
    forces_from_map: bool = False


def load_label(scene: Scene) -> str:
    """``"50N"`` under load control, ``"d0.5mm"`` under penetration control (file names)."""
    if scene.total_load is not None:
        return f"{scene.total_load:g}N"
    return f"d{scene.penetration:g}mm"


def load_title(label: str) -> str:
    """Readable form of a load label: "50N" -> "total load 50 N", "d0.5mm" -> "approach 0.5 mm"."""
    return f"approach {label[1:-2]} mm" if label.startswith("d") else f"total load {label[:-1]} N"


def sensor_text(sensor: Sensor) -> str:
    """``"44 x 44 sensor cells of 1.9 mm"`` (and where it is centred when not at the origin)."""
    text = f"{sensor.nx} x {sensor.ny} sensor cells of {sensor.cell:g} mm"
    cx, cy = sensor.centre
    return text if (cx, cy) == (0.0, 0.0) else f"{text} centred at ({cx:g}, {cy:g}) mm"


def centre_pivot(scene: Scene, forces: np.ndarray) -> tuple[Scene, str]:
    """The scene with its tips shifted by (-x0, -y0) so the joint sits at the centre of
    ``forces`` (paper eq. 13), and a note saying by how much."""
    x0, y0 = pivot_from_forces(scene.tips, forces, total=scene.total_load)
    tips = centred_tips(scene.tips, forces, total=scene.total_load)
    asps = tuple(dataclasses.replace(a, x=float(t[0]), y=float(t[1])) for a, t in zip(scene.asperities, tips))
    note = f"tips shifted by ({-x0:.4g}, {-y0:.4g}) mm so the joint sits at the measured force centre (paper eq. 13)"
    return dataclasses.replace(scene, asperities=asps), note


def load_values(scene: Scene) -> dict:
    """The load of a run as numbers: ``{"load_N": W, "penetration_mm": None}`` or the reverse."""
    return {"load_N": scene.total_load, "penetration_mm": scene.penetration}


def per_asperity_rows(runs, measured: Measured | None = None) -> list[dict]:
    """One dict per load, body and asperity (:data:`ROW_FIELDS`; asperities numbered from 1);
    measured forces as body "measured"; None where a value does not apply (``macro_force_N``
    of a method without a macro step)."""
    rows = []
    if measured is not None and measured.forces is not None:
        rows += [
            {
                **load_values(runs[0].scene),
                "body": "measured",
                "asperity": k + 1,
                "force_N": float(f),
                "contact_area_mm2": None,
                "max_pressure_MPa": None,
                "macro_force_N": None,
            }
            for k, f in enumerate(measured.forces)
        ]
    for run in runs:
        s = run.result.asperities
        macro = run.result.macro_forces
        for k in range(len(s.forces)):
            rows.append(
                {
                    **load_values(run.scene),
                    "body": run.body,
                    "asperity": k + 1,
                    "force_N": float(s.forces[k]),
                    "contact_area_mm2": float(s.contact_areas[k]),
                    "max_pressure_MPa": float(s.max_pressures[k]),
                    "macro_force_N": None if macro is None else float(macro[k]),
                }
            )
    return rows


def tip_changes(runs) -> list[dict]:
    """Per load, each body's tip forces against the first body's (the reference: the
    half-space in ``twoscale compare``): one dict per load, other body and tip
    (:data:`CHANGE_FIELDS`), ``change_percent`` in percent of the tip's own reference force
    (None where the reference tip carries nothing)."""
    rows = []
    for load in dict.fromkeys(r.load for r in runs):
        group = [r for r in runs if r.load == load]
        ref = group[0]
        F_ref = np.asarray(ref.result.asperities.forces, dtype=float)
        for run in group[1:]:
            F = np.asarray(run.result.asperities.forces, dtype=float)
            for k in range(F.size):
                rows.append(
                    {
                        **load_values(run.scene),
                        "reference": ref.body,
                        "body": run.body,
                        "asperity": k + 1,
                        "reference_force_N": float(F_ref[k]),
                        "force_N": float(F[k]),
                        "change_N": float(F[k] - F_ref[k]),
                        "change_percent": 100.0 * float(F[k] - F_ref[k]) / F_ref[k] if F_ref[k] > 0 else None,
                    }
                )
    return rows


def largest_changes(rows: list[dict], n: int = 3) -> list[dict]:
    """The ``n`` rows of one load and body of :func:`tip_changes` with the largest change in
    percent, among the tips whose reference force is at least :data:`RANKED_FORCE_FRACTION`
    of the largest."""
    top = max((r["reference_force_N"] for r in rows), default=0.0)
    ranked = [
        r for r in rows if r["change_percent"] is not None and r["reference_force_N"] >= RANKED_FORCE_FRACTION * top
    ]
    return sorted(ranked, key=lambda r: -abs(r["change_percent"]))[:n]


def e_m_or_none(p, p_ref):
    """e_m (percent), or None when the reference map is zero on every sensor cell."""
    return e_m(p, p_ref) if np.any(p_ref != 0) else None


def indicators(runs, sensor: Sensor | None = None, measured: Measured | None = None) -> dict:
    """e_M and e_m (percent) of every body against every other, per load.

    ``out[load][reference][other] = {"e_M": ..., "e_m": ...}``, with the reference body's
    forces (sensor map) in the denominator; ``sensor`` defaults to the paper's. With
    measured data, the reference ``"measured"`` is added (``None`` for an indicator whose
    data were not given). e_m is ``None`` when the reference map is zero on every sensor
    cell (a sensor placed away from the contact; :func:`sensor_notes` says so).
    """
    sensor = Sensor() if sensor is None else sensor
    out: dict = {}
    maps = {(r.load, r.body): sensor.average(r.result) for r in runs}
    if measured is not None:
        for r in runs:
            out.setdefault(r.load, {}).setdefault("measured", {})[r.body] = {
                "e_M": None if measured.forces is None else e_M(r.result.asperities.forces, measured.forces),
                "e_m": None if measured.sensor_map is None else e_m_or_none(maps[r.load, r.body], measured.sensor_map),
            }
    for ref in runs:
        for other in runs:
            if other.load != ref.load or other.body == ref.body:
                continue
            out.setdefault(ref.load, {}).setdefault(ref.body, {})[other.body] = {
                "e_M": e_M(other.result.asperities.forces, ref.result.asperities.forces),
                "e_m": e_m_or_none(maps[other.load, other.body], maps[ref.load, ref.body]),
            }
    return out


def sensor_notes(runs, sensor: Sensor, *, rtol: float = 1e-3) -> list[str]:
    """One note per solve whose load the sensor does not fully carry (part of the contact
    lies outside it, so e_m compares only what the sensor sees)."""
    notes = []
    for r in runs:
        seen = sensor.force(sensor.average(r.result))
        if seen < (1.0 - rtol) * r.result.total_load:
            notes.append(
                f"the sensor ({sensor_text(sensor)}) carries {seen:.4g} N of the "
                f"{r.result.total_load:.4g} N of {r.body} at {load_title(r.load)}"
            )
    return notes


def folder_indicators(run: str | os.PathLike, reference: str | os.PathLike, sensor: Sensor) -> dict:
    """``{"e_M": percent, "e_m": percent or None}`` between two output folders of
    ``twoscale solve --out`` (their result.json and field files), ``reference`` in the
    denominator.

    Raises
    ------
    ValueError
        A missing or foreign file, or runs with different numbers of asperities.
    """
    from .io.result_json import read_forces_and_tips

    run, reference = Path(run), Path(reference)
    (P, tips), (P_ref, tips_ref) = read_forces_and_tips(run), read_forces_and_tips(reference)
    if P.shape != P_ref.shape:
        raise ValueError(
            f"{run} has {P.size} asperities and {reference} has {P_ref.size}: e_M compares the same asperities"
        )
    _warn_if_tips_differ(run, reference, tips, tips_ref)
    p, p_ref = _folder_sensor_map(run, sensor), _folder_sensor_map(reference, sensor)
    return {"e_M": e_M(P, P_ref), "e_m": e_m_or_none(p, p_ref)}


def _warn_if_tips_differ(run: Path, reference: Path, a: np.ndarray, b: np.ndarray, tol: float = 1e-6) -> None:
    """A warning when the two runs' tips ``a``, ``b`` (N, 2) mm are not at the same places
    (two different scenes give an e_M that compares nothing)."""
    import warnings

    if a.shape == b.shape and a.size and np.all(np.isfinite(a)) and np.all(np.isfinite(b)):
        k = np.flatnonzero(np.hypot(*(a - b).T) > tol)
        if k.size:
            warnings.warn(
                f"{run} and {reference} have asperities at different places (asperity {k[0] + 1}: "
                f"({a[k[0], 0]:g}, {a[k[0], 1]:g}) against ({b[k[0], 0]:g}, {b[k[0], 1]:g}) mm): "
                "the indicators compare different scenes",
                stacklevel=3,
            )


def _folder_sensor_map(folder: Path, sensor: Sensor) -> np.ndarray:
    from .io.solve_outputs import FIELDS_NAME
    from .io.vtk import read_vtk

    path = folder / FIELDS_NAME
    if not path.is_file():
        raise ValueError(f"{path} does not exist (twoscale solve --out writes it)")
    return sensor.average(read_vtk(path))


__all__ = [
    "ROW_FIELDS",
    "CHANGE_FIELDS",
    "Run",
    "Measured",
    "per_asperity_rows",
    "tip_changes",
    "largest_changes",
    "load_values",
    "indicators",
    "sensor_notes",
    "folder_indicators",
    "centre_pivot",
    "load_label",
    "load_title",
    "sensor_text",
]
