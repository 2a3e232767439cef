"""The solvers' options as frozen typed objects, validated once.

:class:`SolverOptions` groups them by what they steer: :class:`MacroOptions` (the macro
step's Newton iteration), :class:`MicroOptions` (the micro step: tolerance, iteration,
coupling, patches), :class:`ReferenceOptions` (the full-grid reference) and
:class:`ResolutionOptions` (cell size and memory). Every field has a documented default;
a bad value is an error naming the option when the object is made, and
:meth:`SolverOptions.from_keywords` maps the flat keywords ``twoscale.solve`` takes
(``tol=``, ``iteration=``, ...) to the groups, refusing an unknown or misspelt one by name
with the closest known names. :func:`list_options` lists them all (the docs' table of
options, ``docs/options.md``, is generated from it by :func:`options_markdown`).
"""

from __future__ import annotations

import dataclasses
import difflib
import math
from dataclasses import dataclass, field
from typing import Any, Mapping

#: Iterations of the micro step the caller may fix ("auto": the policy picks).
MICRO_ITERATIONS = ("auto", "union-cg", "block-gs", "two-level")


def _positive(name: str, v: Any, *, integer: bool = False, allow_none: bool = False) -> None:
    if v is None and allow_none:
        return
    if integer:
        if isinstance(v, bool) or not isinstance(v, int) or v < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
        return
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
        raise ValueError(f"{name} must be a finite number > 0, got {v!r}")


def _fraction(name: str, v: Any, *, allow_none: bool = True) -> None:
    if v is None and allow_none:
        return
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 < v < 1.0:
        raise ValueError(f"{name} must be a number in (0, 1){' or None' if allow_none else ''}, got {v!r}")


@dataclass(frozen=True)
class MacroOptions:
    """The macro step (tip forces with interaction, Newton on the tip forces).

    Attributes
    ----------
    tol : float, default 1e-10
        Relative residual at which the Newton iteration stops.
    max_iter : int, default 100
        Newton iterations allowed.
    dense_max : int, default 2000
        Up to this many tips the interaction is a factorised dense matrix; above, the
        provider's point operator with conjugate gradients (matrix-free: on 2,000-2,900
        tips the dense step's factorisations took seconds more, with forces the same to
        1e-8).
    operator_rtol : float, default 1e-6
        Accuracy of that point operator, relative to the largest displacement.
    """

    tol: float = 1e-10
    max_iter: int = 100
    dense_max: int = 2000
    operator_rtol: float = 1e-6

    def __post_init__(self) -> None:
        _positive("macro.tol", self.tol)
        _positive("macro.max_iter", self.max_iter, integer=True)
        _positive("macro.dense_max", self.dense_max, integer=True)
        _fraction("macro.operator_rtol", self.operator_rtol, allow_none=False)


@dataclass(frozen=True)
class MicroOptions:
    """The micro step (pressure on patches around the tips).

    Attributes
    ----------
    tol : float, default 1e-6
        Relative change of the pressure between sweeps at which the block iterations stop
        (the union CG stops at 1 % of it, as a KKT residual).
    max_sweeps : int, default 100
        Sweeps (or rounds) allowed, all attempts together.
    iteration : {"auto", "union-cg", "block-gs", "two-level"}, default "auto"
        "auto": the policy picks from the patches by a cost estimate and says why.
    far_tol : float or None, default None
        None: patches coupled exactly; a number in (0, 1): pairs farther apart than
        ``(r_k + r_l) / sqrt(far_tol)`` act through nine point forces per patch that carry
        its load's resultant and first and second moments (two-level).
    margin : float, default 1.3
        Patch half-width over the Hertz-like contact radius of the macro force.
    dense_max_cells : int, default 400
        Local blocks up to this many cells are solved densely (Cholesky), larger by CG
        (0: every block by CG).
    separated_rtol : float or None, default 1e-8
        Patches far apart for their size act through the provider's low-rank separated
        operator to this accuracy; None: FFT products only.
    merge : bool, default True
        Close patches are solved as one block.
    p0 : bool, default False
        Also compute the paper's eq. 7 pressures for the report where the chosen
        iteration does not start from them.
    """

    tol: float = 1e-6
    max_sweeps: int = 100
    iteration: str = "auto"
    far_tol: float | None = None
    margin: float = 1.3
    dense_max_cells: int = 400
    separated_rtol: float | None = 1e-8
    merge: bool = True
    p0: bool = False

    def __post_init__(self) -> None:
        _positive("micro.tol", self.tol)
        _positive("micro.max_sweeps", self.max_sweeps, integer=True)
        if self.iteration not in MICRO_ITERATIONS:
            raise ValueError(f"micro.iteration must be one of {MICRO_ITERATIONS}, got {self.iteration!r}")
        _fraction("micro.far_tol", self.far_tol)
        if self.iteration == "union-cg" and self.far_tol is not None:
            raise ValueError("micro.far_tol applies to the block iterations, not to iteration='union-cg'")
        _positive("micro.margin", self.margin)
        if not self.margin >= 1.0:
            raise ValueError(
                f"micro.margin must be >= 1 (patch half-width over the contact radius), got {self.margin!r}"
            )
        if (
            isinstance(self.dense_max_cells, bool)
            or not isinstance(self.dense_max_cells, int)
            or self.dense_max_cells < 0
        ):
            raise ValueError(f"micro.dense_max_cells must be an integer >= 0, got {self.dense_max_cells!r}")
        _fraction("micro.separated_rtol", self.separated_rtol)
        for name in ("merge", "p0"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"micro.{name} must be true or false, got {getattr(self, name)!r}")


@dataclass(frozen=True)
class ReferenceOptions:
    """The full-grid reference solver.

    Attributes
    ----------
    tol : float or None, default None
        Stopping tolerance; None: the solver's own (CG 1e-8 KKT residual, dense 1e-10).
    max_iter : int or None, default None
        Iterations allowed; None: the solver's own (CG 20,000, dense 200).
    max_enlargements : int, default 3
        Times the grid may grow by half while pressure reaches its edge.
    """

    tol: float | None = None
    max_iter: int | None = None
    max_enlargements: int = 3

    def __post_init__(self) -> None:
        _positive("reference.tol", self.tol, allow_none=True)
        _positive("reference.max_iter", self.max_iter, integer=True, allow_none=True)
        if (
            isinstance(self.max_enlargements, bool)
            or not isinstance(self.max_enlargements, int)
            or self.max_enlargements < 0
        ):
            raise ValueError(f"reference.max_enlargements must be an integer >= 0, got {self.max_enlargements!r}")

    def keywords(self) -> dict:
        """The keywords the reference solvers take (only those set)."""
        out: dict = {"max_enlargements": self.max_enlargements}
        out.update({k: v for k, v in (("tol", self.tol), ("max_iter", self.max_iter)) if v is not None})
        return out


@dataclass(frozen=True)
class ResolutionOptions:
    """Cell size and memory.

    Attributes
    ----------
    h : float or None, default None
        Cell size, mm; None: the scene's, else the default rule (about 32 cells across the
        smallest loaded contact, coarsened to keep the patches within 1.5 M cells).
    memory_limit : float or None, default None
        Bytes a solve may use, checked before anything large is allocated; None: 80 % of
        the memory available at the solve; ``inf``: no check.
    """

    h: float | None = None
    memory_limit: float | None = None

    def __post_init__(self) -> None:
        _positive("resolution.h", self.h, allow_none=True)
        if self.memory_limit is not None and (
            isinstance(self.memory_limit, bool)
            or not isinstance(self.memory_limit, (int, float))
            or not self.memory_limit > 0
        ):
            raise ValueError(
                f"resolution.memory_limit must be a number of bytes > 0 (or inf), got {self.memory_limit!r}"
            )


#: The option groups, by the name a mapping uses.
GROUPS = {"macro": MacroOptions, "micro": MicroOptions, "reference": ReferenceOptions, "resolution": ResolutionOptions}
#: Flat keywords (``twoscale.solve``'s) -> (group, field).
KEYWORDS = {
    "tol": ("micro", "tol"),
    "max_sweeps": ("micro", "max_sweeps"),
    "iteration": ("micro", "iteration"),
    "far_tol": ("micro", "far_tol"),
    "margin": ("micro", "margin"),
    "dense_max_cells": ("micro", "dense_max_cells"),
    "separated_rtol": ("micro", "separated_rtol"),
    "merge": ("micro", "merge"),
    "p0": ("micro", "p0"),
    "macro_tol": ("macro", "tol"),
    "macro_max_iter": ("macro", "max_iter"),
    "macro_dense_max": ("macro", "dense_max"),
    "macro_operator_rtol": ("macro", "operator_rtol"),
    "h": ("resolution", "h"),
    "memory_limit": ("resolution", "memory_limit"),
}


@dataclass(frozen=True)
class SolverOptions:
    """Every option of a solve, by group (each with documented defaults)."""

    macro: MacroOptions = field(default_factory=MacroOptions)
    micro: MicroOptions = field(default_factory=MicroOptions)
    reference: ReferenceOptions = field(default_factory=ReferenceOptions)
    resolution: ResolutionOptions = field(default_factory=ResolutionOptions)

    def __post_init__(self) -> None:
        for name, kind in GROUPS.items():
            if not isinstance(getattr(self, name), kind):
                raise ValueError(f"options.{name} must be a {kind.__name__}, got {type(getattr(self, name)).__name__}")

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any]) -> "SolverOptions":
        """Options from ``{"micro": {"tol": 1e-7}, "macro": {...}, ...}`` (e.g. a TOML
        table); an unknown group or option is an error naming it."""
        groups = {}
        for name, values in data.items():
            if name not in GROUPS:
                raise ValueError(f"unknown option group {name!r}{_close(name, GROUPS)}")
            if not isinstance(values, Mapping):
                raise ValueError(f"options.{name} must be a table of options, got {values!r}")
            known = {f.name for f in dataclasses.fields(GROUPS[name])}
            for key in values:
                if key not in known:
                    raise ValueError(f"unknown option {name}.{key}{_close(key, known)}")
            groups[name] = GROUPS[name](**values)
        return cls(**groups)

    @classmethod
    def from_keywords(cls, base: "SolverOptions | None" = None, **keywords: Any) -> "SolverOptions":
        """``base`` (default: the defaults) with ``twoscale.solve``'s flat keywords applied
        (``tol``, ``iteration``, ``macro_tol``, ...; :data:`KEYWORDS`)."""
        base = cls() if base is None else base
        changes: dict = {}
        for key, value in keywords.items():
            if key not in KEYWORDS:
                raise ValueError(f"unknown option {key!r}{_close(key, KEYWORDS)}")
            group, name = KEYWORDS[key]
            changes.setdefault(group, {})[name] = value
        return dataclasses.replace(base, **{g: dataclasses.replace(getattr(base, g), **v) for g, v in changes.items()})

    def twoscale_keywords(self) -> dict:
        """The keywords of :func:`twoscale.driver.solve_twoscale` these options give (the
        macro and micro options under their flat names, :data:`KEYWORDS`)."""
        return {
            key: getattr(getattr(self, group), name)
            for key, (group, name) in KEYWORDS.items()
            if group in ("macro", "micro")
        }


def settings_from(kind: type, keywords: Mapping[str, Any], what: str) -> Any:
    """``kind(**keywords)`` for a frozen dataclass of settings, an unknown keyword refused
    by name with the closest fields (``what`` names the function in the message)."""
    known = {f.name for f in dataclasses.fields(kind)}
    for key in keywords:
        if key not in known:
            raise ValueError(f"unknown keyword {key!r} for {what}{_close(key, known)}")
    return kind(**keywords)


def _close(name: str, known) -> str:
    match = difflib.get_close_matches(name, sorted(known), n=3)
    return f" (did you mean {', '.join(repr(m) for m in match)}?)" if match else f" (known: {', '.join(sorted(known))})"


@dataclass(frozen=True)
class OptionInfo:
    """One option: its group, name, default and the sentence documenting it."""

    group: str
    name: str
    default: Any
    doc: str


def list_options() -> tuple[OptionInfo, ...]:
    """Every option of :class:`SolverOptions`, with its default and documentation (read
    from the groups' docstrings)."""
    out = []
    for group, kind in GROUPS.items():
        docs = _attribute_docs(kind.__doc__ or "")
        for f in dataclasses.fields(kind):
            default = f.default if f.default is not dataclasses.MISSING else None
            out.append(OptionInfo(group, f.name, default, docs.get(f.name, "")))
    return tuple(out)


def _attribute_docs(doc: str) -> dict:
    """``{name: first sentence}`` from a numpydoc ``Attributes`` section."""
    out: dict = {}
    lines = doc.splitlines()
    name = None
    for line in lines:
        text = line.strip()
        indent = len(line) - len(line.lstrip())
        if indent == 4 and " : " in text:
            name = text.split(" : ")[0]
            out[name] = ""
        elif name is not None and indent >= 8 and text:
            out[name] = (out[name] + " " + text).strip()
    return out


def options_markdown() -> str:
    """The table of options in the docs (``docs/options.md``), generated from :func:`list_options`."""
    rows = [
        "# Options",
        "",
        "Every option of a solve, by group (`twoscale.SolverOptions`; this page is generated by "
        "`twoscale.options.options_markdown()` from the option objects themselves). In Python: "
        "`twoscale.ContactSolver(body, SolverOptions(micro=MicroOptions(tol=1e-7)))`, or "
        '`SolverOptions.from_mapping({"micro": {"tol": 1e-7}})`; `twoscale.solve` takes the '
        "flat keywords of the last column.",
        "",
        "| option | default | flat keyword | meaning |",
        "|---|---|---|---|",
    ]
    flat = {v: k for k, v in KEYWORDS.items()}
    for o in list_options():
        key = flat.get((o.group, o.name), "")
        rows.append(f"| `{o.group}.{o.name}` | `{o.default!r}` | {f'`{key}`' if key else ''} | {o.doc} |")
    return "\n".join(rows) + "\n"
