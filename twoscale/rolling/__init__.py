"""A road rolling under the body: a static contact at every position of a track, with the
signals tyre/road-noise engineers read (force, approach, contact area, drag; the stones'
forces).

* :class:`RollingSpec` (:mod:`.spec`): the ``[rolling]`` table (start, end, step, speed,
  the tyre's radius, the footprint);
* :func:`roll` (:mod:`.run`): every position, warm-started from the previous one,
  returning a :class:`RollingResult` (:mod:`.result`);
* :mod:`.road`: the strip segmented once and its stones shifted per position;
  :mod:`.track`: what the positions share and the checks before a run;
* :func:`road_strip` (:mod:`.strip`): a seeded chip-seal strip for examples and benchmarks.
"""

from __future__ import annotations

from .result import RollingResult, StoneSignals
from .run import RollingOptions, roll, solve_position
from .spec import RollingSpec, rolling_from_table
from .strip import road_strip

__all__ = [
    "RollingOptions",
    "RollingResult",
    "RollingSpec",
    "StoneSignals",
    "road_strip",
    "roll",
    "rolling_from_table",
    "solve_position",
]
