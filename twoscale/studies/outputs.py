"""Everything a study writes beside its case folders, in one call: the tidy tables,
summary.json and the figures (see :mod:`twoscale.studies.tables` and
:mod:`twoscale.studies.figures`)."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

from .._version import __version__
from .cases import expand
from .execute import StudyRun
from .keys import case_key
from .spec import Study
from .store import CaseStore
from .tables import write_tables


def write_outputs(out: str | Path, study: Study, run: StudyRun | None = None, *, figures: bool = True) -> dict:
    """Write the tables, summary.json and (``figures``) the figures of every case of
    ``study`` finished in ``out`` so far; returns the summary."""
    out = Path(out)
    cases = expand(study)
    keys = list(run.keys) if run is not None else [case_key(c, study) for c in cases]
    record = {} if run is None else {k: v for k, v in asdict(run).items() if k != "keys"}
    case_rows, tip_rows, ind, summary = write_tables(out, study, cases, keys, CaseStore(out), record)
    if figures:
        from .figures import write_figures

        write_figures(
            out,
            case_rows,
            tip_rows,
            ind,
            track_positions=len(study.positions) > 1,
            meta={"study": study.name, "version": __version__},
            bodies={b.name: b.influence for b in study.bodies},
        )
    return summary
