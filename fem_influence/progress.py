"""A tiny progress line for slow builds (stderr, shown only after a delay)."""
from __future__ import annotations

import sys
import time


class Progress:
    """Progress of ``total`` steps labelled ``label``, printed on one stderr line.

    Nothing is printed until ``delay_s`` seconds have passed, so fast (e.g. cached)
    builds stay silent.

    Parameters
    ----------
    label : str
        What is being built.
    total : int
        Number of steps (>= 0).
    enabled : bool, default True
        False silences the helper.
    delay_s : float, default 2
        Seconds before the first line is shown.
    stream : file, default sys.stderr
    """

    def __init__(self, label: str, total: int, *, enabled: bool = True, delay_s: float = 2.0, stream=None):
        self.label, self.total, self.enabled, self.delay_s = label, int(total), enabled, delay_s
        self.stream = sys.stderr if stream is None else stream
        self.done = 0
        self.t0 = time.perf_counter()
        self._shown = False

    def update(self, n: int = 1, *, stage: str = "") -> None:
        """Advance by ``n`` steps; ``stage`` names the current step."""
        self.done += n
        elapsed = time.perf_counter() - self.t0
        if self.enabled and elapsed >= self.delay_s:
            self._shown = True
            frac = self.done / self.total if self.total else 1.0
            bar = "#" * int(20 * frac)
            self.stream.write(f"\r{self.label}: [{bar:<20}] {self.done}/{self.total} {stage} {elapsed:.1f} s   ")
            self.stream.flush()

    def close(self) -> float:
        """Finish the line; returns the elapsed seconds."""
        elapsed = time.perf_counter() - self.t0
        if self._shown:
            self.stream.write(f"\r{self.label}: done in {elapsed:.1f} s{' ' * 40}\n")
            self.stream.flush()
        return elapsed
