"""The two-scale solve takes in the tips a finite body's bulge lifts (:mod:`twoscale.bulge`).

The micro step gives a patch only to a tip its approach reaches (``d - z_k > 0``). Beside
the contacts of a bonded, nearly incompressible block the surface rises, and a tip a little
above the approach touches there. On a body whose surface may rise two steps take such tips
in (the patches they are given are sized by :attr:`MicroProblem.lift
<twoscale.micro.problem.MicroProblem.lift>`):

1. :func:`with_macro_lift`: the macro step's local approach of each tip holds the surface's
   rise there (the point compliance is negative where it rises); a tip above the approach
   that the macro step puts in contact is given a patch sized from its local approach;
2. :func:`settle`: the micro step's answer is checked (:func:`twoscale.bulge.lifted_among`:
   each unreached tip's apex against the solved pressure's displacement); a tip it finds is
   given a patch sized from twice its apex's overlap with the solved surface, and the micro
   step runs again from the answer's pressure, up to :data:`twoscale.bulge.SETTLE_ROUNDS`
   times. What is still lifted then is recorded (``details.bulge``,
   :class:`~twoscale.details.BulgeDetails`) and named by a
   :class:`~twoscale.errors.BulgeWarning` (:func:`twoscale.bulge.warn_lifted_tips`).

A scene where neither finds a tip is solved as it was without them, with no further round.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from .bulge import SETTLE_ROUNDS, LiftedTips, lifted_among
from .details import BulgeDetails
from .micro.problem import MicroProblem
from .micro.workset import tip_approaches
from .results import ContactResult


def rises(provider) -> bool:
    """Whether the body's surface may rise beside a contact (``surface_rises``)."""
    return bool(getattr(provider, "surface_rises", False))


def with_macro_lift(provider, asperities, problem: MicroProblem) -> MicroProblem:
    """``problem`` with a ``lift`` that gives a patch to every tip above the approach
    (geometric approach <= 0) that the macro step's local approach puts in contact, sized
    from that local approach; ``problem`` itself on a body whose surface only sinks, or
    where there is no such tip."""
    delta = problem.sizing_penetrations
    if not rises(provider) or delta is None:
        return problem
    geometric = tip_approaches(asperities, problem.theta, problem.pivot)
    taken = (geometric <= 0.0) & (np.asarray(delta, dtype=float) > 0.0)
    if not np.any(taken):
        return problem
    return dataclasses.replace(problem, lift=np.where(taken, delta - geometric, 0.0))


def _raised(lift: np.ndarray | None, lifted: LiftedTips, asperities, penetration: float) -> np.ndarray:
    """``lift`` raised so that each lifted tip's patch is sized from twice its apex's overlap
    with the solved surface (``-gap``) at the approach ``penetration`` (mm, no tilt)."""
    out = np.zeros(len(asperities)) if lift is None else np.array(lift, dtype=float)
    for k, gap in zip(lifted.tips.tolist(), lifted.gaps.tolist()):
        geometric = penetration - float(asperities[k].z)
        out[k] = max(out[k], -2.0 * gap - geometric)
    return out


def settle(
    first: ContactResult,
    asperities,
    provider,
    lift: np.ndarray | None,
    again: Callable[[np.ndarray, ContactResult], ContactResult],
) -> ContactResult:
    """The two-scale answer ``first`` (solved with the patches' ``lift``, mm or None) with
    the tips its surface lifts taken in: while :func:`twoscale.bulge.lifted_among` finds
    some, at most ``SETTLE_ROUNDS`` times, ``again(lift, previous)`` solves the micro step
    again with their patches; ``details.bulge`` says what was done and what is left.
    Call it on a body whose surface may rise (:func:`rises`), without a free tilt."""
    result, rounds = first, 0
    lifted = lifted_among(asperities, provider, result)
    while lifted is not None and rounds < SETTLE_ROUNDS:
        lift = _raised(lift, lifted, asperities, float(result.penetration))
        result = again(lift, result)
        rounds += 1
        lifted = lifted_among(asperities, provider, result)
    taken = () if lift is None else np.flatnonzero(lift > 0.0)
    left = BulgeDetails() if lifted is None else BulgeDetails(left=lifted.tips, left_gaps=lifted.gaps)
    bulge = dataclasses.replace(left, rounds=rounds, taken=taken)
    return dataclasses.replace(result, details=dataclasses.replace(result.details, bulge=bulge))


__all__ = ["rises", "settle", "with_macro_lift"]
