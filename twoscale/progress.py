"""A tiny progress bar on stderr for work that lasts more than a couple of seconds.

Silent when ``quiet`` is set, when the stream is not a terminal, or while the work is
younger than ``delay`` seconds (so quick runs print nothing). No dependency.

Example
-------
>>> with Progress(total=3, label="loads", quiet=True) as bar:
...     for _ in range(3):
...         bar.update()
"""
from __future__ import annotations

import sys
import time
from typing import Iterable, Iterator, TextIO, TypeVar

T = TypeVar("T")


class Progress:
    """Progress of ``total`` steps, drawn as ``label [#####     ] 3/7  4.2 s``.

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
    width : int, default 30
        Bar width, characters.
    clock : callable, default ``time.monotonic``
        Time source in seconds (tests inject one).
    """

    def __init__(self, total: int, *, label: str = "", quiet: bool = False,
                 stream: TextIO | None = None, delay: float = 2.0, width: int = 30,
                 clock=time.monotonic) -> None:
        if total < 0:
            raise ValueError(f"progress total must be >= 0, got {total!r}")
        self.total = int(total)
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        isatty = getattr(self.stream, "isatty", None)
        self.enabled = (not quiet) and bool(isatty and isatty())
        self.delay = float(delay)
        self.width = int(width)
        self._clock = clock
        self._start = clock()
        self.done = 0
        self._drawn = False

    def update(self, n: int = 1, *, note: str = "") -> None:
        """Advance by ``n`` steps and redraw if drawing is due."""
        self.done = min(self.total, self.done + n) if self.total else self.done + n
        self._draw(note)

    def _draw(self, note: str = "") -> None:
        if not self.enabled:
            return
        elapsed = self._clock() - self._start
        if elapsed < self.delay:
            return
        frac = self.done / self.total if self.total else 0.0
        fill = int(round(frac * self.width))
        bar = "#" * fill + " " * (self.width - fill)
        text = f"\r{self.label} [{bar}] {self.done}/{self.total}  {elapsed:.1f} s"
        if note:
            text += f"  {note}"
        self.stream.write(text + "\x1b[K")
        self.stream.flush()
        self._drawn = True

    def close(self) -> None:
        """End the line if anything was drawn."""
        if self._drawn:
            self._draw()
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def track(items: Iterable[T], *, total: int | None = None, label: str = "", quiet: bool = False,
          stream: TextIO | None = None, delay: float = 2.0) -> Iterator[T]:
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
    ``solving: micro step, two-level: sweep 5, residual 1.2e-04  12.3 s``.

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
    clock : callable, default ``time.monotonic``
    """

    def __init__(self, *, label: str = "solving", quiet: bool = False, stream: TextIO | None = None,
                 delay: float = 3.0, interval: float = 0.5, clock=time.monotonic) -> None:
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        isatty = getattr(self.stream, "isatty", None)
        self.enabled = not quiet and bool(isatty and isatty())
        self.delay, self.interval, self.clock = delay, interval, clock
        self.start = clock()
        self._last = -float("inf")
        self._width = 0

    def __call__(self, text: str) -> None:
        if not self.enabled:
            return
        now = self.clock()
        if now - self.start < self.delay or now - self._last < self.interval:
            return
        self._last = now
        line = f"{self.label}: {text}  {now - self.start:.1f} s"
        self.stream.write("\r" + line.ljust(self._width))
        self.stream.flush()
        self._width = len(line)

    def close(self) -> None:
        if self.enabled and self._width:
            self.stream.write("\r" + " " * self._width + "\r")
            self.stream.flush()
            self._width = 0

    def __enter__(self) -> "StatusLine":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
