"""A progress bar over a study's cases: tqdm when it is installed, else the project's own
plain bar (:class:`twoscale.progress.Progress`)."""
from __future__ import annotations

import sys


class CaseBar:
    """Progress over ``total`` cases of which ``done`` are already finished.

    Parameters
    ----------
    total : int
        Cases in the study.
    done : int, default 0
        Cases finished before this run (a resumed study starts there).
    quiet : bool, default False
        Draw nothing.
    """

    def __init__(self, total: int, *, done: int = 0, quiet: bool = False):
        try:
            from tqdm import tqdm
        except ImportError:
            tqdm = None
        if tqdm is not None:
            self._bar = tqdm(total=total, initial=done, unit="case", desc="study", disable=quiet,
                             file=sys.stderr, dynamic_ncols=True)
            self._plain = None
        else:
            from ..progress import Progress

            self._plain = Progress(total, label="study", quiet=quiet)
            self._plain.update(done)
            self._bar = None

    def update(self, note: str = "") -> None:
        """One more case finished; ``note`` says which."""
        if self._bar is not None:
            self._bar.set_postfix_str(note, refresh=False)
            self._bar.update(1)
        else:
            self._plain.update(note=note)

    def close(self) -> None:
        (self._bar or self._plain).close()

    def __enter__(self) -> "CaseBar":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
