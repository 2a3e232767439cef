"""The warnings a run raised, kept for its output files (the ``warnings`` list of
``result.json``, a history's ``result.json`` and ``rolling.json``).

:class:`WarningLog` is a context manager around a run. Every warning raised inside it is
counted under its category's name and its message on one line, in the order first raised;
a repeat (the same category and message, e.g. at every step of a history) adds to the
count. Each warning is still shown, or not, exactly as without the log: the filters and the
``warnings.showwarning`` in force when the log was entered decide, with one registry for the
log's lifetime, so a warning the ``"default"`` action prints once is printed once, an
``"error"`` filter still raises and an ``"ignore"`` filter still hides it (the file records
it all the same: it says what caveats the answer came with).

The solver knows nothing of the log: warnings stay the library's channel for caveats, and
the files record what that channel carried during the run, whichever module raised it.
"""

from __future__ import annotations

import sys
import warnings

__all__ = ["WarningLog", "one_line", "entries_of"]


def one_line(message) -> str:
    """A warning's message on one line (runs of white space, new lines too, as one space)."""
    return " ".join(str(message).split())


def entries_of(caught) -> list[dict]:
    """The entries (:meth:`WarningLog.entries`) of the list ``warnings.catch_warnings(record=True)``
    gives, for a caller that records warnings its own way."""
    counts: dict[tuple[str, str], int] = {}
    for w in caught:
        _add(counts, (w.category.__name__, one_line(w.message)))
    return _entries(counts)


def _add(counts: dict, key: tuple[str, str]) -> None:
    counts[key] = counts.get(key, 0) + 1


def _entries(counts: dict) -> list[dict]:
    return [{"category": c, "message": m, "count": n} for (c, m), n in counts.items()]


class WarningLog:
    """Count the warnings raised inside ``with WarningLog() as log:`` (module docstring);
    :meth:`entries` gives them as the files record them."""

    def __init__(self) -> None:
        # (category, message) -> times raised, in the order first raised: one entry per
        # distinct warning, however often it repeats
        self._counts: dict[tuple[str, str], int] = {}
        self._registry: dict = {}  # the "default" action's memory of what was shown
        self._modules: dict[str, str] = {}  # file -> module name, looked up once
        self._outer = None
        self._context = None

    def __enter__(self) -> WarningLog:
        self._outer = (warnings.filters, warnings.showwarning)  # catch_warnings copies, never edits, them
        self._context = warnings.catch_warnings()
        self._context.__enter__()
        warnings.simplefilter("always")  # every raise reaches _show, to be counted
        warnings.showwarning = self._show
        return self

    def __exit__(self, *exc) -> None:
        self._context.__exit__(*exc)
        self._context = None

    def _show(self, message, category, filename, lineno, file=None, line=None) -> None:
        """Count the warning, then let the outer filters decide whether and how it shows."""
        _add(self._counts, (category.__name__, one_line(message)))
        inner = warnings.filters, warnings.showwarning
        warnings.filters, warnings.showwarning = self._outer
        try:
            warnings.warn_explicit(
                message, category, filename, lineno, module=self._module(filename), registry=self._registry
            )
        finally:
            warnings.filters, warnings.showwarning = inner

    def _module(self, filename: str) -> str:
        if filename not in self._modules:
            self._modules[filename] = _module_name(filename)
        return self._modules[filename]

    def mark(self) -> dict:
        """The counts so far: :meth:`entries` ``(since=mark)`` gives what was raised after it
        (one of several solves under one log)."""
        return dict(self._counts)

    def entries(self, since: dict | None = None) -> list[dict]:
        """``[{"category": "TiltWarning", "message": "...", "count": 1}, ...]`` in the order
        first raised; empty when nothing was raised. ``since``: a :meth:`mark`, to count only
        the raises after it."""
        before = since or {}
        return _entries({k: n - before.get(k, 0) for k, n in self._counts.items() if n > before.get(k, 0)})


def _module_name(filename: str) -> str:
    """The name of the loaded module whose file is ``filename`` (what the filters match a
    warning's module against), else the file's name without ``.py``, as Python names a
    warning's module when it is not given (``"<string>"`` for ``python -c``)."""
    for name, module in list(sys.modules.items()):
        if getattr(module, "__file__", None) == filename:
            return name
    if not filename:
        return "<unknown>"
    return filename[:-3] if filename.endswith(".py") else filename
