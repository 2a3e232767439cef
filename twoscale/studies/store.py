"""Per-case result folders, written atomically under the case's key.

``OUT/cases/<key>/`` holds ``case.json`` (inputs, status, reason, numbers, per-tip
figures, program version, units, the warnings the case raised) and ``sensor.npy`` (the sensor map, MPa; absent for a
failed case). A folder is written under a hidden temporary name in the same directory
and renamed to its key when complete, so a folder named by a key is always whole: an
interrupted write leaves only a ``.<key>.tmp-*`` folder, removed by the next run
(:meth:`CaseStore.clean`). A case is finished when its folder exists with status
"converged" or "not-converged"; failed cases are solved again by a rerun.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from .._version import __version__
from ..io.atomic import current_umask
from ..io.result_json import UNITS
from .solve import CaseRecord

CASE_NAME = "case.json"
SENSOR_NAME = "sensor.npy"
#: Statuses that count as finished (not solved again on a rerun).
FINISHED = ("converged", "not-converged")


def record_to_dict(record: CaseRecord, inputs: dict) -> dict:
    """The JSON content of ``case.json``."""
    out = {
        "key": record.key,
        "label": record.label,
        "status": record.status,
        "reason": record.reason,
        "seconds": _seconds(record.seconds),
        "cpu_seconds": _seconds(record.cpu_seconds),
        "version": __version__,
        "units": dict(UNITS),
        "inputs": inputs,
        "tips": [int(k) for k in record.tips],
        "warnings": [dict(w) for w in record.warnings],  # category, one-line message, count
    }
    o = record.outcome
    if o is not None:
        out["result"] = {
            "converged": o.converged,
            "message": o.message,
            "total_load": o.total_load,
            "penetration": o.penetration,
            "tilt": None if o.tilt is None else list(o.tilt),
            "h": o.h,
            "strategy": o.strategy,
            "iterations": o.iterations,
            "timings_s": o.timings_s,
            "forces": o.forces.tolist(),
            "contact_areas": o.contact_areas.tolist(),
            "max_pressures": o.max_pressures.tolist(),
        }
    return out


def _seconds(v: float) -> float | None:
    return float(v) if np.isfinite(v) else None


class CaseStore:
    """The case folders of a study's output directory ``root`` (``root/cases``)."""

    def __init__(self, root: str | os.PathLike):
        self.root = Path(root)
        self.folder = self.root / "cases"

    def path(self, key: str) -> Path:
        return self.folder / key

    def status(self, key: str) -> str | None:
        """The recorded status of ``key``, or None when it has no (readable) folder."""
        data = self.read(key)
        return None if data is None else data.get("status")

    def finished(self, key: str) -> bool:
        return self.status(key) in FINISHED

    def read(self, key: str) -> dict | None:
        """``case.json`` of ``key`` as a dict, or None."""
        try:
            return json.loads((self.path(key) / CASE_NAME).read_text(encoding="utf-8"))
        except (FileNotFoundError, NotADirectoryError, json.JSONDecodeError):
            return None

    def sensor_map(self, key: str) -> np.ndarray | None:
        path = self.path(key) / SENSOR_NAME
        return np.load(path, allow_pickle=False) if path.is_file() else None

    def write(self, record: CaseRecord, inputs: dict) -> Path:
        """Write the record's folder atomically (a previous folder of the key is replaced)."""
        files = {}
        if record.outcome is not None:
            buffer = io.BytesIO()
            np.save(buffer, record.outcome.sensor_map, allow_pickle=False)
            files[SENSOR_NAME] = buffer.getvalue()
        return self.write_folder(record.key, record_to_dict(record, inputs), files)

    def write_folder(self, key: str, content: dict, files: dict) -> Path:
        """Write ``key``'s folder atomically: ``case.json`` holding ``content`` and each of
        ``files`` (``{name: bytes}``); a previous folder of the key is replaced."""
        self.folder.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{key}.tmp-", dir=self.folder))
        try:
            text = json.dumps(content, indent=1, allow_nan=True)
            (tmp / CASE_NAME).write_text(text + "\n", encoding="utf-8")
            for name, data in files.items():
                (tmp / name).write_bytes(data)
            os.chmod(tmp, 0o777 & ~current_umask())
            final = self.path(key)
            if final.exists():  # a failed case solved again: the old folder goes
                old = Path(tempfile.mkdtemp(prefix=f".{key}.old-", dir=self.folder))
                os.replace(final, old / "x")
                shutil.rmtree(old, ignore_errors=True)
            os.rename(tmp, final)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        return final

    def clean(self) -> int:
        """Remove temporary folders left by interrupted writes (and the temporary files of
        the tables, :func:`twoscale.io.atomic.atomic_output`'s ``.NAME.*.tmp``, left by a run
        killed while writing them); returns how many."""
        n = 0
        if self.root.is_dir():
            for p in self.root.glob(".*.tmp"):
                if p.is_file():
                    with contextlib.suppress(OSError):
                        p.unlink()
                        n += 1
        if self.folder.is_dir():
            for p in self.folder.iterdir():
                if p.name.startswith(".") and (".tmp-" in p.name or ".old-" in p.name):
                    with contextlib.suppress(OSError):
                        shutil.rmtree(p)
                        n += 1
        return n
