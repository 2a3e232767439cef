"""The files of a rolling run (:class:`~twoscale.rolling.RollingResult`).

* ``signals.csv``: a row per position, columns exactly ``time_s, shift_mm, total_load_N,
  penetration_mm, contact_area_mm2, drag_N``; header on the first line, no comment lines
  (what the columns mean, the version and the scene: ``signals.csv-metadata.json``);
* ``asperity_signals.csv`` (and ``.parquet`` when pyarrow is there): a row per stone in
  contact per position, columns exactly ``time_s, shift_mm, asperity, force_N,
  contact_area_mm2``, stones numbered from 1 as in the segmentation (the scene's
  asperity order for tips);
* ``rolling.json``: the scene, the body, the material, the speed, the steps, the
  convergence of every position (converged, iterations: the CG's on the window path, the
  micro step's sweeps on the two-scale path, as ``method`` says; stones, message; its
  wall-clock ``seconds`` and ``cpu_seconds``), the timings;
  the step against the road's samples and the Prony branches (``step_check``,
  :mod:`twoscale.rolling.stepcheck`) and a viscoelastic run's energy balance
  (``energy_balance``, with its meaning); ``warnings``: what the run warned of (as in
  ``result.json``: category, one-line message, count);
* ``fields.pvd`` (+ ``fields/s_NNNN.vti``): the pressure at each position on one grid of the
  body (written as the run goes, :class:`FrameWriter`): a series ParaView animates, its
  time the position's time;
* ``bands.csv`` (``band_Hz, level_dB``: third-octave levels of the total force under
  penetration control, of the approach re 1 um under load control), ``texture.json`` (the
  strip's MPD and texture spectrum), ``signals.png``, ``bands.png``, ``space_time.png``:
  :func:`write_signal_products`, through :mod:`twoscale.rolling.bands`,
  :mod:`twoscale.rolling.texture` and :mod:`twoscale.plot.rolling` where the package has them.

``drag_N`` is the force the road exerts on the body along +x (the road moves along +x
under it): the sum over the contact of the pressure times the road's x-slope, times the
cell area; positive when the road drags the body along (the resistance to rolling).
"""

from __future__ import annotations

import json
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from .._version import __version__
from .atomic import atomic_output
from .tables import write_table

SIGNALS_NAME = "signals"
ASPERITY_SIGNALS_NAME = "asperity_signals"
ROLLING_JSON_NAME = "rolling.json"
FIELDS_NAME = "fields.pvd"
SIGNAL_COLUMNS = ("time_s", "shift_mm", "total_load_N", "penetration_mm", "contact_area_mm2", "drag_N")
ASPERITY_SIGNAL_COLUMNS = ("time_s", "shift_mm", "asperity", "force_N", "contact_area_mm2")
DESCRIPTIONS = {
    "time_s": "time of the position from the first, s (distance / speed)",
    "shift_mm": "shift of the road along +x relative to the body, mm (a road point at x is at body x + shift)",
    "total_load_N": "total normal force, N",
    "penetration_mm": "rigid approach of the body below the road's highest point, mm",
    "contact_area_mm2": "real contact area, mm2",
    "drag_N": "force the road exerts on the body along +x, N (sum of pressure x road x-slope x cell area)",
    "asperity": "stone number, from 1 (segmentation order; scene order for tips)",
    "force_N": "force of the stone, N",
}
UNITS = {"length": "mm", "force": "N", "pressure": "MPa", "time": "s", "speed": "km/h", "area": "mm^2"}


def signal_rows(result) -> list[dict]:
    """The rows of ``signals.csv``."""
    return [
        dict(zip(SIGNAL_COLUMNS, (float(t), float(s), float(w), float(d), float(a), float(g))))
        for t, s, w, d, a, g in zip(
            result.times, result.shifts, result.total_load, result.penetration, result.contact_area, result.drag
        )
    ]


def asperity_rows(result) -> list[dict]:
    """The rows of ``asperity_signals.csv`` (positions in order, stones by number)."""
    a = result.asperities
    order = np.lexsort((a.stone, a.position))
    return [
        {
            "time_s": float(result.times[a.position[k]]),
            "shift_mm": float(result.shifts[a.position[k]]),
            "asperity": int(a.stone[k]),
            "force_N": float(a.force[k]),
            "contact_area_mm2": float(a.contact_area[k]),
        }
        for k in order
    ]


def rolling_to_dict(result, scene, *, warnings=()) -> dict:
    """The content of ``rolling.json``; ``warnings``: :meth:`twoscale.io.warning_log.WarningLog.entries`."""
    from .scene_file import scene_to_dict

    spec = result.spec
    return {
        "program": "twoscale",
        "version": __version__,
        "units": UNITS,
        "scene": scene_to_dict(scene),
        "body": result.body,
        "material": {
            "E": scene.material.E,
            "nu": scene.material.nu,
            "E_star": scene.material.E_star,
            "prony": [list(b) for b in scene.material.prony],
        },
        "speed_kmh": spec.speed,
        "speed_mm_s": spec.speed_mm_s,
        "control": result.control,
        "held": scene.penetration if result.control == "penetration" else scene.total_load,
        "method": result.method,
        "h_mm": result.h,
        "steps": {
            "start_mm": spec.start,
            "end_mm": spec.end,
            "step_mm": spec.step,
            "positions": len(result.shifts),
            "first_shift_mm": float(result.shifts[0]),
            "last_shift_mm": float(result.shifts[-1]),
            "duration_s": float(result.times[-1]),
        },
        "converged": result.all_converged,
        "mean_drag_N": result.mean_drag,
        "positions": [
            {
                "shift_mm": float(s),
                "converged": bool(c),
                "iterations": int(i),
                "stones": int(n),
                "seconds": float(t),
                "cpu_seconds": float(u),
                "message": m,
            }
            for s, c, i, n, t, u, m in zip(
                result.shifts,
                result.converged,
                result.iterations,
                result.stones,
                result.seconds,
                result.cpu_seconds,
                result.messages,
            )
        ],
        "timings_s": {k: float(v) for k, v in result.timings_s.items()},
        **_energy(result),
        "warnings": [dict(w) for w in warnings],
    }


#: What ``rolling.json``'s ``energy_balance`` means (written beside the numbers).
ENERGY_MEANING = (
    "N mm from the first position on: the road's work on the rubber (drag_work: the drag over the shifts; "
    "vertical_work: the load over the approach's change, 0 under penetration control) against the energy the "
    "Prony branches stored (stored_change) and dissipated (dissipated); mismatch = work / energy - 1. The "
    "stepping meets it to second order in the step: more than a few percent says the step is too coarse for "
    "the texture or the branches (step_check); a small mismatch does not prove the friction converged (the "
    "mean drag moves at first order in the step: compare a run at twice the step)"
)


#: What ``rolling.json``'s ``step_error`` (``twoscale solve --step-error``) means.
STEP_ERROR_MEANING = (
    "N: the mean drag (hysteresis friction) over the distance both runs cover, at the step and at twice the step "
    "(same samples, same first shift); with the friction first order in the step (measured), their difference "
    "estimates the error of the run at the step, and the extrapolated friction adds it"
)


def _energy(result) -> dict:
    """A viscoelastic run's energy per position and its balance with the drag's work."""
    out: dict = {}
    if result.step_check is not None:
        out["step_check"] = result.step_check.to_dict()
    if result.step_error is not None:
        out["step_error"] = {**result.step_error, "meaning": STEP_ERROR_MEANING}
    balance = result.energy_balance()
    if balance is None:
        return out
    out["energy_Nmm"] = {"dissipated": result.dissipated.tolist(), "stored": result.stored.tolist()}
    out["energy_balance"] = {**balance, "meaning": ENERGY_MEANING}
    return out


def write_rolling_json(result, scene, path, *, warnings=()) -> Path:
    path = Path(path)
    content = rolling_to_dict(result, scene, warnings=warnings)
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(content, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    return path


def write_rolling_tables(result, scene, out_dir, *, warnings=()) -> list[Path]:
    """``signals.csv``, ``asperity_signals.csv`` (+ Parquet) and ``rolling.json`` (``warnings``: the run's)."""
    out = Path(out_dir)
    record = {"units": UNITS, "speed_kmh": result.spec.speed, "control": result.control, "body": result.body}
    written = write_table(
        out,
        SIGNALS_NAME,
        signal_rows(result),
        SIGNAL_COLUMNS,
        title="rolling signals, a row per position",
        record=record,
        descriptions=DESCRIPTIONS,
    )
    written += write_table(
        out,
        ASPERITY_SIGNALS_NAME,
        asperity_rows(result),
        ASPERITY_SIGNAL_COLUMNS,
        title="forces of the stones in contact, a row per stone and position",
        record=record,
        descriptions=DESCRIPTIONS,
        parquet=0,
    )
    written.append(write_rolling_json(result, scene, out / ROLLING_JSON_NAME, warnings=warnings))
    return written


def _have(*modules: str) -> bool:
    import importlib.util

    return all(importlib.util.find_spec(m) is not None for m in modules)


def band_signal(result) -> np.ndarray:
    """The signal whose third-octave levels a rolling run reports: the total force under
    penetration control, the approach under load control."""
    return result.total_load if result.control == "penetration" else result.penetration


def write_signal_products(result, scene, out_dir, *, figures: bool = True, name: str | None = None) -> list[Path]:
    """``bands.csv``, ``texture.json`` and the figures (module docstring; their titles name
    the scene, ``name`` its file's stem, and the body); nothing where the signal modules are
    not in the package."""
    from .scene_file import scene_to_dict

    out, written = Path(out_dir), []
    record = scene_to_dict(scene)  # the figures' titles and PNG metadata take the scene's record
    if _have("twoscale.rolling.bands"):
        from ..rolling.bands import REF_APPROACH, REF_FORCE, third_octave_levels

        force = result.control == "penetration"
        ref = REF_FORCE if force else REF_APPROACH
        cols, resolution = {"band_Hz": [], "level_dB": []}, None  # one position: no spectrum, the header only
        if len(result.shifts) >= 2:
            levels = third_octave_levels(band_signal(result), result.spec.step / result.spec.speed_mm_s, reference=ref)
            cols, resolution = levels.columns(), levels.resolution
        rows = [{"band_Hz": float(f), "level_dB": float(v)} for f, v in zip(cols["band_Hz"], cols["level_dB"])]
        what = "total force, dB re 1 N" if force else "approach, dB re 1 um"
        written += write_table(
            out,
            "bands",
            rows,
            ("band_Hz", "level_dB"),
            title=f"third-octave levels of the {what}",
            record={
                "signal": "total_load_N" if force else "penetration_mm",
                "reference": ref,
                "resolution_Hz": resolution,
                "units": UNITS,
            },
        )
        if figures and _have("twoscale.plot.rolling"):
            from ..plot.rolling import bands_figure
            from ..plot.style import Caption

            written.append(
                Path(
                    bands_figure(
                        out / "bands.png",
                        cols["band_Hz"],
                        cols["level_dB"],
                        level_label=f"level ({what})",
                        caption=Caption(scene=record, name=name),
                    )
                )
            )
    if _have("twoscale.rolling.texture") and scene.surface is not None:
        from ..rolling.texture import road_texture

        from ..errors import SceneError

        try:
            content = road_texture(scene.surface.hmap.heights, scene.surface.h).to_json_dict()
        except SceneError as exc:  # a strip too short for one MPD segment: the run stands, the texture says why
            content = {"units": {"length": "mm", "level": "dB re 1 um"}, "not_computed": str(exc)}
        path = out / "texture.json"
        with atomic_output(path) as tmp:
            tmp.write_text(json.dumps(content, indent=1, allow_nan=False) + "\n", encoding="utf-8")
        written.append(path)
    if figures and _have("twoscale.plot.rolling"):
        written += _figures(result, out, record, name)
    return written


def _figures(result, out: Path, scene, name: str | None) -> list[Path]:
    from ..plot.rolling import signals_figure, space_time_figure
    from ..plot.style import Caption

    caption = Caption(scene=scene, name=name)
    force = result.control == "penetration"
    signal = result.total_load if force else result.penetration
    paths = [
        signals_figure(
            out / "signals.png",
            result.times,
            signal,
            result.contact_area,
            signal_label="total load (N)" if force else "approach (mm)",
            drag_N=result.drag,
            caption=caption,
        )
    ]
    if result.line_x.size:
        paths.append(
            space_time_figure(out / "space_time.png", result.shifts, result.line_x, result.line_load, caption=caption)
        )
    return [Path(p) for p in paths]


class FrameWriter:
    """Writes ``fields/s_NNNN.vti`` as the positions come (pressure MPa, owner stone from 1,
    on the grid of ``window`` mm at cell ``h``) and ``fields.pvd`` at :meth:`close`."""

    def __init__(self, out_dir, grid, times, *, comment: str | None = None):
        self.path = Path(out_dir) / FIELDS_NAME
        self.folder = self.path.parent / self.path.stem
        self.folder.mkdir(parents=True, exist_ok=True)
        self.grid, self.times, self.comment = grid, np.asarray(times), comment
        self.entries: list = []

    def __call__(self, position) -> None:
        from .vti import write_image

        grid, res = self.grid, position.result
        p = res.pressure_on(grid)
        owner = np.zeros(grid.shape, dtype=np.int32)
        for f in res.fields:
            rows, cols = _overlap(f.grid, grid)
            if rows is None:
                continue
            src = f.owner[rows[1], cols[1]]
            numbers = position.selection.numbers
            mapped = np.where(src >= 0, numbers[np.maximum(src, 0)] + 1, 0)
            owner[rows[0], cols[0]] = np.where(mapped > 0, mapped, owner[rows[0], cols[0]])
        name = f"s_{position.index:04d}.vti"
        write_image(self.folder / name, grid, {"pressure_MPa": p, "asperity": owner}, comment=self.comment)
        self.entries.append((float(self.times[position.index]), f"{self.folder.name}/{name}"))

    def close(self) -> Path:
        lines = ['<?xml version="1.0"?>\n']
        if self.comment:
            lines.append(f"<!-- {self.comment} -->\n")
        lines.append('<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n<Collection>\n')
        lines += [f'<DataSet timestep="{t!r}" group="" part="0" file={quoteattr(f)}/>\n' for t, f in self.entries]
        lines.append("</Collection>\n</VTKFile>\n")
        self.path.write_text("".join(lines))
        return self.path


def _overlap(src, dst):
    """Slices of the cells ``src`` and ``dst`` (aligned grids) share: ((dst rows, src rows),
    (dst cols, src cols)), or (None, None)."""
    di, dj = src.offset_in(dst)
    i0, j0 = max(di, 0), max(dj, 0)
    i1, j1 = min(di + src.nx, dst.nx), min(dj + src.ny, dst.ny)
    if i1 <= i0 or j1 <= j0:
        return None, None
    return ((slice(j0, j1), slice(j0 - dj, j1 - dj)), (slice(i0, i1), slice(i0 - di, i1 - di)))


__all__ = [
    "SIGNAL_COLUMNS",
    "ASPERITY_SIGNAL_COLUMNS",
    "FrameWriter",
    "rolling_to_dict",
    "signal_rows",
    "asperity_rows",
    "write_rolling_json",
    "write_rolling_tables",
    "write_signal_products",
]
