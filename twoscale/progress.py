"""Progress on stderr, through tqdm: a bar for counted work and a status line for a solve.

* :class:`Progress` (and :func:`track`): ``label: 40%|####      | 2/5 [00:03<00:04]  note``
  for work of a known number of steps (loads, bodies, block sources);
* :class:`StatusLine`: one line redrawn in place for a long solve whose length is not
  known, ``solving: micro step, two-level: sweep 5, residual 1.2e-04  00:12``.

Both are silent with ``quiet``, when the stream is not a terminal (a log file, a pipe,
CI), and while the work is younger than ``delay`` seconds (quick runs print nothing). In a
Jupyter notebook (an IPython kernel, whose stderr is no terminal) they are drawn with
``tqdm.auto``: a notebook progress widget when ipywidgets is installed, text otherwise.
tqdm is imported when a bar is made, so ``import twoscale`` stays light.

Example
-------
>>> with Progress(total=3, label="loads", quiet=True) as bar:
...     for _ in range(3):
...         bar.update()
"""

from __future__ import annotations

import sys
from typing import Iterable, Iterator, TextIO, TypeVar

T = TypeVar("T")


def in_notebook() -> bool:
    """True inside a Jupyter kernel (IPython's ``ZMQInteractiveShell``)."""
    ipython = sys.modules.get("IPython")
    shell = getattr(ipython, "get_ipython", lambda: None)() if ipython is not None else None
    return type(shell).__name__ == "ZMQInteractiveShell"


def _bar(stream: TextIO | None, quiet: bool, **options):
    """A tqdm bar on ``stream`` (default stderr), disabled when quiet or off a terminal; in a
    notebook (default stream) the ``tqdm.auto`` bar."""
    if stream is None and not quiet and in_notebook():
        from tqdm.auto import tqdm as auto_tqdm

        return auto_tqdm(**options)
    from tqdm import tqdm

    stream = sys.stderr if stream is None else stream
    isatty = getattr(stream, "isatty", None)
    enabled = not quiet and bool(isatty and isatty())
    return tqdm(file=stream, disable=not enabled, dynamic_ncols=True, **options)


class Progress:
    """Progress of ``total`` steps, drawn as a tqdm bar.

    Parameters
    ----------
    total : int
        Number of steps (>= 0).
    label : str, default ""
        Shown before the bar.
    quiet : bool, default False
        Never draw.
    stream : text stream, default ``sys.stderr``
        Where to draw; nothing is drawn unless ``stream.isatty()``.
    delay : float, default 2.0
        Seconds before the first drawing, s.
    """

    def __init__(
        self, total: int, *, label: str = "", quiet: bool = False, stream: TextIO | None = None, delay: float = 2.0
    ) -> None:
        if total < 0:
            raise ValueError(f"progress total must be >= 0, got {total!r}")
        self.total = int(total)
        self.done = 0
        self._bar = _bar(stream, quiet, total=self.total, desc=label or None, delay=delay, mininterval=0.5, leave=True)

    @property
    def enabled(self) -> bool:
        return not self._bar.disable

    def update(self, n: int = 1, *, note: str = "") -> None:
        """Advance by ``n`` steps; ``note`` names what was just done (shown after the bar)."""
        self.done += n
        if note:
            self._bar.set_postfix_str(note, refresh=False)
        self._bar.update(n)

    def close(self) -> None:
        """End the line (a bar drawn stays on screen)."""
        self._bar.close()

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def track(
    items: Iterable[T],
    *,
    total: int | None = None,
    label: str = "",
    quiet: bool = False,
    stream: TextIO | None = None,
    delay: float = 2.0,
) -> Iterator[T]:
    """Yield ``items`` while drawing a :class:`Progress` bar (same options)."""
    if total is None:
        items = list(items)
        total = len(items)
    with Progress(total, label=label, quiet=quiet, stream=stream, delay=delay) as bar:
        for item in items:
            yield item
            bar.update()


class StatusLine:
    """One line on stderr that says what a long solve is doing, redrawn in place:
    ``solving: micro step, two-level: sweep 5, residual 1.2e-04  00:12`` (elapsed time).

    Call it with a text (``status(text)``) whenever the work moves on; it draws only once
    the work is older than ``delay`` seconds, at most every ``interval`` seconds, and never
    when ``quiet`` or when the stream is not a terminal. :meth:`close` clears the line.

    Parameters
    ----------
    label : str, default "solving"
    quiet : bool, default False
    stream : text stream, default ``sys.stderr``
    delay : float, default 3.0
        Seconds before the first drawing.
    interval : float, default 0.5
        Seconds between two drawings.
    """

    def __init__(
        self,
        *,
        label: str = "solving",
        quiet: bool = False,
        stream: TextIO | None = None,
        delay: float = 3.0,
        interval: float = 0.5,
    ) -> None:
        self.label = label
        self._bar = _bar(
            stream,
            quiet,
            total=None,
            desc=label,
            delay=delay,
            mininterval=interval,
            leave=False,
            bar_format="{desc}  {elapsed}",
        )

    @property
    def enabled(self) -> bool:
        return not self._bar.disable

    def __call__(self, text: str) -> None:
        self._bar.set_description_str(f"{self.label}: {text}", refresh=False)
        self._bar.update(0)  # redraws when delay and interval allow

    def close(self) -> None:
        self._bar.close()

    def __enter__(self) -> "StatusLine":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
