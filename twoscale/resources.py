"""Memory a solve will need, estimated from the scene before anything large is allocated.

:func:`estimate_memory` counts the cells a solver will carry from the scene alone (no
grid array is built) and turns them into bytes with per-cell costs measured on this code
(peak resident memory of the sweep's solves in fresh processes,
:mod:`twoscale.memory_costs`). :func:`check_memory` compares an estimate with a limit, by
default 80 % of the memory the machine has available, and raises a one-line
:class:`~twoscale.scene.SceneError` naming the option to change when it is over.

What the two methods carry:

* ``"reference"``: one grid (:func:`twoscale.reference.on_scene.reference_grid`), its zero-padded FFT
  and the constrained CG's vectors; the dense solver's matrix where the scene is small enough for it.
* ``"twoscale"``: one patch per asperity that can touch, of half-width ``margin a_k + 2 h``
  (``a_k`` the contact radius at the expected approach, under penetration control lowered
  by the neighbours' mean push, :mod:`twoscale.mean_field`), each with its FFT operator; the
  operators of the pairs of patches coupled exactly (the near pairs where the far field may
  be taken; at most the coupling's cache budget); where the far field may be taken, the
  weights it keeps per owned cell on patches under ``SEPARABLE_CELLS`` owned cells
  (:func:`twoscale.memory_parts.far_weight_bytes`; none per cell on the larger) and its
  point operator among the patches; the dense macro matrix; and, where the policy
  surely solves on the patches' bounding box as one grid (``union-cg`` chosen on every
  patch size :mod:`twoscale.memory_choice` tries), that box with its coarse correction
  where its loaded squares are few and sparse enough for it to be built, no block
  operators, and (where the macro step cannot stall) the patches as windows of the box, a
  few kB each. Where the policy may take the union CG or a block iteration, the block
  iteration is counted, and the union CG (the box beyond a block attempt before it,
  :mod:`twoscale.memory_parts`) is what the estimate says it would need
  (:attr:`MemoryEstimate.union_bytes`): it is checked when the policy takes it, against
  the memory available then (:func:`twoscale.memory_now.box_check`; else the block
  iteration the policy takes without it, or a one-line refusal). So is the union CG that
  only follows a far-field attempt which did not converge
  (:func:`twoscale.memory_now.union_box_fits`; else block Gauss-Seidel with the same far
  field), not counted. Under penetration control a tip the neighbours' push lifts out of
  contact still holds a patch at its reach (:func:`twoscale.memory_parts.twoscale_parts`).
  With more than a thousand tips the macro step may stall and leave patches sized by the
  indenters' reach (:mod:`twoscale.memory_stall`): that route's block iterations are
  counted too, and the larger taken; the union CG on their box where they overlap beyond
  it is checked when the policy takes it, as above. An iteration asked for runs alone and
  is counted alone.
* a body that builds something on its first answers adds it (the finite block's
  factorisation where its on-disk cache lacks a field the tips' region needs).

Measured peaks against the estimate: docs/records/sweep.md (seeds 6-9's scenes). Not
counted: the reference grid's enlargements when pressure reaches its edge (x 2.25 each),
and a union CG the policy takes on patches that cover their box beyond what the band of
:mod:`twoscale.memory_choice` predicts.

Units: bytes, mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .memory_costs import BASE_BYTES, DEFAULT_FRACTION, ADVICE_SHARE
from .full_grid import FULL_GRID_DENSE_CELLS
from .mean_field import tip_arrays
from .memory_now import available_memory
from .memory_parts import grid_parts, twoscale_parts
from .micro.full_grid_rule import FULL_GRID_MAX_TIPS, full_grid_max_cells, full_grid_route as policy_full_grid_route
from .pivot import pivot_route
from .scene import SCENE_METHODS, Scene, SceneError, expected_approaches, expected_contact_radii, round_up


@dataclass(frozen=True)
class MemoryEstimate:
    """Peak memory a solve is expected to need.

    Attributes
    ----------
    bytes : float
        Estimated peak resident memory of what surely runs, bytes (a prediction: of seeds
        6-9's 715 recorded sweep scenes, 654 peaked within 0.67-1.5 times it, or of
        :attr:`union_bytes` where the union CG ran; docs/records/sweep.md).
    cells : int
        Cells the solver will carry: the reference grid, or the patches (the union box
        when the micro step is expected to solve on it and it is larger).
    dominant : str
        The part that dominates the estimate.
    method : str
        ``"twoscale"`` or ``"reference"``.
    h : float
        Cell size, mm.
    parts : tuple of (str, float)
        The estimate's parts, bytes.
    union_parts : tuple of (str, float)
        The parts if the policy takes the union CG over the patches' box where it may take a
        block iteration too and the estimate counts that (empty where the union CG is
        counted in ``bytes``, or needs no more): checked against the memory available
        when the policy chooses it, not before the solve
        (:func:`twoscale.memory_now.box_check`).
    """

    bytes: float
    cells: int
    dominant: str
    method: str
    h: float
    parts: tuple = ()
    union_parts: tuple = ()

    @property
    def union_bytes(self) -> float:
        """Peak if the policy takes the union CG (:attr:`union_parts`), bytes; ``bytes``
        where that is not more."""
        return max(self.bytes, float(sum(v for _, v in self.union_parts)))

    @property
    def text(self) -> str:
        """One line: the total in GB, the cells and what dominates, and what the union CG
        would need where the policy may take it and it is not counted."""
        line = (
            f"about {self.bytes / 1e9:.3g} GB for {self.cells:,} cells at h = {self.h:g} mm "
            f"({self.method}; mostly {self.dominant})"
        )
        if self.union_bytes > self.bytes:
            line += f"; up to {self.union_bytes / 1e9:.3g} GB if the policy takes the union CG over the patches' box"
        return line

    def __str__(self) -> str:
        return self.text


# ---------------------------------------------------------------- the estimate
def estimate_memory(
    scene: Scene, h: float, method: str = "twoscale", *, iteration: str = "auto", provider=None
) -> MemoryEstimate:
    """Peak memory of solving ``scene`` at cell size ``h`` with ``method``.

    Parameters
    ----------
    scene : Scene
    h : float
        Cell size, mm (> 0).
    method : {"twoscale", "reference"}, default "twoscale"
    iteration : str, default "auto"
        The two-scale micro iteration asked for (``solve_twoscale``'s ``iteration``):
        ``"union-cg"`` counts the box of the patches and no block operators;
        ``"block-gs"`` and ``"two-level"`` the block operators and no box (an iteration
        asked for runs alone); ``"auto"`` what the policy may run
        (:func:`twoscale.memory_choice.possible_routes`): the block operators, the box, or
        the larger of both, and on a height map's stones the box too.
    provider : InfluenceProvider, optional
        The body the solve will use, asked what its first answers build
        (:func:`body_build_bytes`); None: the scene's, built here.

    Returns
    -------
    MemoryEstimate
        Bytes, cells and what dominates, from the scene alone (no grid array built).
    """
    if method not in SCENE_METHODS:
        raise ValueError(f"method must be one of {SCENE_METHODS}, got {method!r}")
    if not (isinstance(h, (int, float)) and math.isfinite(h) and h > 0):
        raise ValueError(f"h must be a finite number > 0 (mm), got {h!r}")
    parts = {"interpreter and libraries": BASE_BYTES}
    if_union: dict = {}  # the parts if the policy takes the union CG, where not counted
    try:
        if method == "reference" or (iteration == "auto" and full_grid_route(scene, h) is not None):
            from .reference.on_scene import reference_grid

            grid = reference_grid(scene, h)
            cells = int(grid.size)
            # the default's full grid keeps the reference's dense solver only on the smallest grids
            dense = method == "reference" or cells <= FULL_GRID_DENSE_CELLS
            parts.update(grid_parts(scene, grid, "reference grid", dense=dense))
        else:
            cells, extra, if_union = twoscale_parts(scene, h, iteration=iteration)
            parts.update(extra)
    except OverflowError:  # cells past any float (h = 1e-320 mm): no count to report
        raise SceneError(
            f"cell size h = {h!r} mm is too small: the scene's cells cannot even be counted (over 1e308 of them)"
        ) from None
    body = {}
    if (build := body_build_bytes(scene, provider)) > 0:
        body["finite-block factorisation (a field not in its cache)"] = build
    parts |= body
    union = {"interpreter and libraries": BASE_BYTES} | if_union | body if if_union else {}
    total = float(sum(parts.values()))
    dominant = max(
        (k for k in parts if k != "interpreter and libraries"), key=parts.get, default="interpreter and libraries"
    )
    return MemoryEstimate(total, cells, dominant, method, float(h), _items(parts), _items(union))


def _items(parts: dict) -> tuple:
    return tuple((k, float(v)) for k, v in parts.items())


def body_build_bytes(scene: Scene, provider=None) -> float:
    """What the scene's body will build on its first answers, bytes
    (:meth:`~twoscale.influence.base.InfluenceProvider.build_bytes`: the finite block's
    factorisation where its on-disk cache lacks a field the tips' region needs, 0 where it
    holds them all, as after a first solve of the same block; always 0 on the half-space).
    The region: the tips' box widened by their largest reach at the expected approach, which
    every grid a solve builds stays within. ``provider``: the body the solve will use; None:
    the scene's, built here once per scene (the answer kept with it)."""
    if provider is None and scene.influence["kind"] == "halfspace":
        return 0.0
    kept = None if provider is not None else scene.__dict__.get("_build_bytes")
    if kept is None:
        delta = expected_approaches(scene)
        reach = max((a.reach(float(d)) for a, d in zip(scene.asperities, delta)), default=0.0)
        x, y = scene.tips[:, 0], scene.tips[:, 1]
        rect = (float(x.min()) - reach, float(x.max()) + reach, float(y.min()) - reach, float(y.max()) + reach)
        try:
            build = getattr(provider or scene.provider(progress=False), "build_bytes", None)
            kept = 0.0 if build is None else float(build(rect))  # a body of the caller's may not say
        except (SceneError, ValueError):  # a body the solve will refuse: nothing is built
            kept = 0.0
        if provider is None:
            scene.__dict__["_build_bytes"] = kept  # not a field: equality, hash and repr ignore it
    return kept


def full_grid_route(scene: Scene, h: float, body: str | None = None) -> str | None:
    """Why a default solve of ``scene`` at ``h`` on a ``body`` (a provider's ``kind``, default the
    scene's) runs as its full grid's one CG (:func:`twoscale.micro.full_grid_rule.full_grid_route`;
    a tilt about a pivot off the tips: :func:`twoscale.pivot.pivot_route`), or None."""
    if (route := pivot_route(scene)) is not None or scene.surface is not None:
        return route
    from .reference.on_scene import reference_grid

    pressed = scene.penetration is not None and (body or scene.influence["kind"]) == "halfspace"
    n = len(scene.asperities)
    tips = 0 if scene.tilt else n
    if n <= FULL_GRID_MAX_TIPS:
        return policy_full_grid_route(int(reference_grid(scene, h).size), tips, pressed)
    x, y = tip_arrays(scene).tips.T
    if (np.ptp(x) / h + 1.0) * (np.ptp(y) / h + 1.0) > full_grid_max_cells(tips):
        return None  # the tips' own box already has more cells a tip
    return policy_full_grid_route(int(reference_grid(scene, h).size), tips, pressed)


# ---------------------------------------------------------------- the check
def check_solve_memory(
    scene: Scene,
    h: float,
    method: str = "twoscale",
    *,
    iteration: str = "auto",
    limit_bytes: float | None = None,
    option: str = "--h",
    h_given: bool = False,
    provider=None,
) -> None:
    """:func:`check_memory` for solving ``scene`` at ``h``: the refusal names where h came
    from (``option``, the scene's ``grid.h``, or the default rule) and suggests an h whose
    estimate was checked to fit; ``provider``: the body the solve will use (None: the scene's)."""
    if h_given:
        source = f"given as {option}"
    elif scene.h is not None:
        source = "the scene's grid.h"
    else:
        source = "the default, chosen from the scene"
    family = "twoscale" if method == "twoscale" else "reference"

    def refit(hh: float) -> MemoryEstimate:
        return estimate_memory(scene, hh, family, iteration=iteration, provider=provider)

    try:
        check_memory(refit(h), limit_bytes, option=option, source=source, refit=refit)
    except SceneError as exc:  # say what makes the grid large: the load asked for
        raise SceneError(f"{exc}; {_largest_contact(scene)}") from None


def _largest_contact(scene: Scene) -> str:
    """The largest expected contact and what makes it, in words: the approach, or the load
    and the modulus (under load control a contact grows as ``(F R / E)^(1/3)``)."""
    a = expected_contact_radii(scene)
    k = int(np.argmax(a))
    load = (
        f"load.penetration = {scene.penetration:g} mm"
        if scene.penetration is not None
        else f"load.total = {scene.total_load:g} N and material.E = {scene.material.E:g} MPa"
    )
    return f"the largest expected contact, asperity {k + 1}'s, is about {2 * a[k]:.3g} mm across at {load}"


def default_limit() -> float:
    """The default limit: :data:`DEFAULT_FRACTION` (80 %) of :func:`available_memory`, bytes."""
    return DEFAULT_FRACTION * available_memory()


def check_memory(
    estimate: MemoryEstimate,
    limit_bytes: float | None = None,
    *,
    option: str = "--h",
    source: str | None = None,
    refit=None,
) -> None:
    """Raise :class:`SceneError` when ``estimate`` exceeds the limit.

    Parameters
    ----------
    estimate : MemoryEstimate
    limit_bytes : float or None
        Limit, bytes; None: 80 % of the memory available now (:func:`default_limit`);
        ``math.inf``: no limit.
    option : str, default "--h"
        The option the message tells the user to change (``"grid.h"`` in a scene file).
    source : str, optional
        Where the cell size came from, in words (e.g. ``"the default, chosen from the
        scene"``), named in the message.
    refit : callable, optional
        ``refit(h) -> MemoryEstimate`` for the same solve at another cell size: the
        suggested h is then one whose estimate was checked to fit (else it is scaled as
        ``1 / h^2``, which the patches' margins and fixed costs make optimistic).

    Raises
    ------
    SceneError
        One line: the estimate in GB, the limit in GB, where h came from, and the option
        to change with a value at which the estimate fits.
    ValueError
        When ``limit_bytes`` is not > 0.
    """
    limit = default_limit() if limit_bytes is None else float(limit_bytes)
    if not limit > 0:  # also NaN
        raise ValueError(f"memory limit must be > 0 bytes (or inf), got {limit_bytes!r}")
    if estimate.bytes <= limit:
        return
    gb = f"{estimate.bytes / 1e9:.2g}" if estimate.bytes < 1e11 else f"{estimate.bytes / 1e9:,.0f}"
    if estimate.union_bytes > estimate.bytes:  # what the union CG would need, checked when taken
        gb += f" (up to {estimate.union_bytes / 1e9:.2g} GB if the policy takes the union CG)"
    which = "80 % of the memory available now" if limit_bytes is None else "given"
    where = f"h = {estimate.h:g} mm ({source})" if source else f"{option} = {estimate.h:g} mm"
    raise SceneError(
        f"the solve at {where} needs about {gb} GB of memory ({estimate.cells:,} "
        f"cells, mostly {estimate.dominant}), over the limit of {limit / 1e9:.3g} GB ({which}); "
        f"{_advice(estimate, limit, option, refit)}"
    )


def _advice(estimate: MemoryEstimate, limit: float, option: str, refit=None) -> str:
    """What to change: a cell size at which the estimate fits (checked with ``refit``)."""
    room = limit - BASE_BYTES
    if room <= 0:
        return f"the machine has too little memory available for any {option}"
    h = estimate.h * math.sqrt(max(estimate.bytes - BASE_BYTES, 0.0) / room)
    h = round_up(h * 1.05, digits=2)  # 5 % slack: the estimate is not exactly 1/h^2
    if refit is not None:
        for _ in range(40):  # cells fall at least as 1 / h: 40 steps of 10 % cover 45x
            if refit(h).bytes <= ADVICE_SHARE * limit:  # room to spare, not the limit's edge
                break
            h = round_up(h * 1.1, digits=2)
        else:
            return f"no {option} up to {h:g} mm fits"
    sep = " " if option.startswith("-") else " = "
    return f"try {option}{sep}{h:g} mm or larger"
