"""The paper's numerical study (docs/method.md section 4; Cesbron et al. 2009, figs. 3-6).

* :mod:`.cases` — the two- and seven-sphere layouts and the reference grid on the same lattice;
* :mod:`.run` — two-scale and reference solves per case, the error indicators of fig. 6;
* :mod:`.output` — CSV files;
* :mod:`.figures` — PNG figures (the only module importing matplotlib).
"""

from .cases import PAPER_SPACINGS, PaperCase, paper_case, paper_cases, reference_surface
from .run import CaseResult, StudyResult, run_case, run_study

__all__ = [
    "PAPER_SPACINGS",
    "PaperCase",
    "paper_case",
    "paper_cases",
    "reference_surface",
    "CaseResult",
    "StudyResult",
    "run_case",
    "run_study",
]
