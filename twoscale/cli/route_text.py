"""How the solve summary names what ran: the two-scale method, a reference solver, or the
two-scale default route's full grid (a small scene solved whole, with the reason the result's
message gives)."""

from __future__ import annotations

from ..full_grid import DEFAULT_ROUTE


def method_lines(res: dict) -> list[str]:
    """The summary's ``method`` line(s) from a result.json dict: on the default route's full
    grid, the solver that ran and a ``route`` line with the reason (the two-scale method's
    macro forces and patches are then absent, as the tables show)."""
    if res["method"] != "twoscale":
        return [f"  method       {res['method']} ({res['solver']} solver)"]
    message = str(res.get("message") or "")
    if res["solver"] == "twoscale" or not message.startswith(DEFAULT_ROUTE):
        return ["  method       two-scale"]
    return [
        f"  method       two-scale's default route: the full grid, {res['solver']} solver",
        f"  route        {message[len(DEFAULT_ROUTE) :]}",
    ]


__all__ = ["method_lines"]
