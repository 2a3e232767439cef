"""How the solve summary names what ran: the two-scale method, a reference solver, or the
two-scale default route's full grid (a small scene solved whole, with the reason the result's
message gives), and the iteration counts in words."""

from __future__ import annotations


def method_lines(res: dict) -> list[str]:
    """The summary's ``method`` line(s) from a result.json dict: on the default route's full
    grid, the solver that ran and a ``route`` line with the reason (the two-scale method's
    macro forces and patches are then absent, as the tables show)."""
    from ..full_grid import DEFAULT_ROUTE  # with scipy: after a solve, not for --help

    if res["method"] != "twoscale":
        return [f"  method       {res['method']} ({res['solver']} solver)"]
    message = str(res.get("message") or "")
    if res["solver"] == "twoscale" or not message.startswith(DEFAULT_ROUTE):
        return ["  method       two-scale"]
    return [
        f"  method       two-scale's default route: the full grid, {res['solver']} solver",
        f"  route        {message[len(DEFAULT_ROUTE) :]}",
    ]


#: How each iteration count reads in the summary (counts of 0 are left out).
ITERATION_WORDS = {
    "macro": "macro-step Newton iterations",
    "macro_krylov": "Krylov iterations in them",
    "micro": "micro-step sweeps",
    "corrections": "approach corrections",
    "sensitivity_sweeps": "sensitivity sweeps",
    "outer": "active-set passes",
    "cg": "conjugate-gradient iterations",
    "products": "grid products",
}


def iteration_text(iterations: dict) -> str:
    """``"3 macro-step Newton iterations, 6 micro-step sweeps"``: the non-zero counts in words."""
    parts = [f"{n} {ITERATION_WORDS.get(k, k.replace('_', ' '))}" for k, n in iterations.items() if n]
    return ", ".join(parts) or "no iterations"


__all__ = ["ITERATION_WORDS", "iteration_text", "method_lines"]
