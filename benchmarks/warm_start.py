"""Warm starts along a track against cold starts, in one process.

Along the example study's track (``examples/study.toml``: S2, half-space and block, 200 and
300 N, 0/5/10 mm) and the benchmark study's (``study.py``: 4 loads, 0-8 mm in 2 mm steps),
each case after a track's first is solved twice with the same provider: cold (the default
start) and warm. The order alternates from case to case, so neither start always meets a
warmer cache. Two warm starts are measured:

* ``macro``: ``start=`` the neighbour's result (the library's warm start: the macro Newton
  iteration starts from the neighbour's forces, approach and tilt, mapped by tip identity);
* ``micro`` (an experiment, not a library option): the micro step's first pressure on each
  patch is the neighbour's pressure moved with the tips and scaled to the new macro force,
  in place of the paper's eq. 7 (substituted for this run only).

Reported per track: macro Newton steps, macro seconds, micro sweeps, micro seconds, summed
over the warm-startable cases, cold against warm.

Usage::

    cd benchmarks && python warm_start.py
"""

from __future__ import annotations

import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import _common  # noqa: F401  (single-threaded processes)
import numpy as np  # noqa: E402  (after _common: OpenBLAS reads its thread count when loaded)
from study import ROOT, STUDY

sys.path.insert(0, str(ROOT))


@contextmanager
def micro_start(state: dict):
    """Substitute the micro step's eq. 7 start by ``state["previous"]`` moved by
    ``state["shift"]`` (mm) and scaled to each tip's macro force, while inside."""
    import twoscale.micro.setup as ms

    real = ms._initial

    def warm(provider, asperities, patches, blocks, forces, z_blocks, h, rtol=ms.P0_RTOL):
        out = real(provider, asperities, patches, blocks, forces, z_blocks, h, rtol=rtol)
        if state.get("previous") is None:
            return out
        table = _cells(state["previous"], h)
        dx, dy = state["shift"]
        moved = []
        for pt, p7 in zip(patches, out):
            g = pt.grid
            i, j = np.meshgrid(
                np.rint((g.x0 - dx) / h + np.arange(g.nx)).astype(int),
                np.rint((g.y0 - dy) / h + np.arange(g.ny)).astype(int),
            )
            v = np.array([table.get(c, 0.0) for c in zip(i.ravel(), j.ravel())]).reshape(g.shape)[pt.owned]
            s, P = h * h * v.sum(), float(forces[pt.asperity])
            moved.append(v * (P / s) if s > 0 and P > 0 else p7)
        return moved

    ms._initial = warm
    try:
        yield
    finally:
        ms._initial = real


def _cells(result, h: float) -> dict:
    """Pressure of ``result`` by lattice cell ``(i, j)`` (centres at ``(i h, j h)``)."""
    table: dict = {}
    for f in result.fields:
        g = f.grid
        i, j = np.meshgrid(
            np.rint(g.x0 / h + np.arange(g.nx)).astype(int), np.rint(g.y0 / h + np.arange(g.ny)).astype(int)
        )
        for c, v in zip(zip(i.ravel(), j.ravel()), f.pressure.ravel()):
            if v > 0:
                table[c] = table.get(c, 0.0) + float(v)
    return table


def track(study) -> dict:
    """Cold against warm (macro start, micro start) over ``study``'s warm-startable cases."""
    import twoscale
    from twoscale.macro import MacroStart
    from twoscale.studies.cases import case_scene, expand, kept_tips
    from twoscale.studies.providers import ProviderCache

    providers, state = ProviderCache(), {}
    sums = {k: np.zeros(4) for k in ("cold", "macro", "micro")}
    previous = None
    with micro_start(state):
        for n, case in enumerate(expand(study)):
            scene, tips = case_scene(case, study), kept_tips(case)
            provider = providers.get(scene)
            if previous is None or previous[0] != case.ref[:3]:
                state["previous"] = None
                previous = (case.ref[:3], tips, twoscale.solve(scene, provider=provider), case.shift)
                continue
            where = {int(t): i for i, t in enumerate(previous[1])}
            start = MacroStart.from_result(previous[2], np.array([where.get(int(t), -1) for t in tips]))
            shift = (case.shift[0] - previous[3][0], case.shift[1] - previous[3][1])
            runs = {"cold": (None, None), "macro": (start, None), "micro": (None, previous[2])}
            names = list(runs) if n % 2 else list(runs)[::-1]
            results = {}
            for name in names:
                state["previous"], state["shift"] = runs[name][1], shift
                results[name] = r = twoscale.solve(scene, provider=provider, start=runs[name][0])
                assert r.converged, case.label
                sums[name] += [r.iterations["macro"], r.timings_s["macro"], r.iterations["micro"], r.timings_s["micro"]]
            state["previous"] = None
            previous = (case.ref[:3], tips, results["cold"], case.shift)
    return {k: dict(zip(("macro_steps", "macro_s", "micro_sweeps", "micro_s"), v.tolist())) for k, v in sums.items()}


def main() -> int:
    from twoscale.studies.spec import read_study

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.toml"
        path.write_text(STUDY.format(scene=(ROOT / "examples" / "S2.toml").as_posix()), encoding="utf-8")
        studies = {
            "example track (examples/study.toml)": read_study(ROOT / "examples" / "study.toml"),
            "benchmark track (study.py)": read_study(path),
        }
        t0 = time.perf_counter()
        for name, study in studies.items():
            out = track(study)
            print(name)
            for k, v in out.items():
                print(
                    f"  {k:6s} macro steps {v['macro_steps']:4.0f}  macro {v['macro_s']:6.3f} s  "
                    f"micro sweeps {v['micro_sweeps']:4.0f}  micro {v['micro_s']:6.2f} s"
                )
        print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
