"""Memory estimate before a solve (twoscale.resources): the counts against the grids the
solvers build, the check's one-line message, the CLI refusing a scene the machine cannot
hold (exit 2, nothing written), and the estimate against a measured peak."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from twoscale import Material
from twoscale.cli.main import main
from twoscale.indenters import Asperity
from twoscale.io.scene_file import read_scene
from twoscale.memory_costs import FAR_OPERATOR_BYTES_PER_PATCH
from twoscale.resources import MemoryEstimate, available_memory, check_memory, default_limit, estimate_memory
from twoscale.api import solve_scene
from twoscale.scene import Scene, SceneError, default_h

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"

HERTZ = Scene(
    material=Material(E=10.0, nu=0.5),
    penetration=0.5,
    asperities=[Asperity(x=0.0, y=0.0, z=0.0, R=10.0, shape="paraboloid")],
)


def fifty_tips_toml(h: float | None = None) -> str:
    """50 spheres (R 3-6 mm, z 0-0.1 mm) on a 25 x 25 mm square under 75 N, as TOML."""
    rng = np.random.default_rng(0)
    xy = rng.uniform(0.0, 25.0, size=(50, 2))
    R = rng.uniform(3.0, 6.0, 50)
    z = rng.uniform(0.0, 0.1, 50)
    lines = ["[material]", "E = 10.0", "nu = 0.5", "[load]", "total = 75.0"]
    if h is not None:
        lines += ["[grid]", f"h = {h!r}"]
    for (x, y), zz, r in zip(xy, z, R):
        lines += ["[[asperity]]", f"x = {float(x)!r}", f"y = {float(y)!r}", f"z = {float(zz)!r}", f"R = {float(r)!r}"]
    return "\n".join(lines) + "\n"


def test_reference_counts_the_reference_grid():
    # one paraboloid at penetration d: contact can reach r = sqrt(2 R d); the reference grid
    # covers that plus 5 % and 3 h on each side, with a cell centred on the tip, so it is
    # n x n cells with n = 2 ceil(r_grid / h - 1/2) + 1
    h, R, d = 0.05, 10.0, 0.5
    est = estimate_memory(HERTZ, h, "reference")
    r_grid = 1.05 * math.sqrt(2 * R * d) + 3 * h
    n = 2 * math.ceil(r_grid / h - 0.5) + 1
    assert est.cells == n * n
    # its FFT products work on the zero-padded grid: at least (2n)^2 complex values
    grid_bytes = sum(b for name, b in est.parts if "grid" in name)
    assert grid_bytes >= (2 * n) ** 2 * 16


def test_twoscale_counts_one_patch_per_touching_tip():
    # one paraboloid: a patch of half-width 1.3 a + 2 h around the Hertz contact a = sqrt(R d)
    h = 0.05
    est = estimate_memory(HERTZ, h, "twoscale")
    a = math.sqrt(10.0 * 0.5)
    across = math.floor(2 * (1.3 * a + 2 * h) / h) + 1
    assert est.cells == across**2


def test_union_cg_asked_for_counts_the_box_of_the_patches():
    # two tips 40 mm apart on a diagonal: their box is mostly empty, counted only when asked for
    scene = Scene(
        material=Material(E=10.0, nu=0.5),
        penetration=0.5,
        asperities=[Asperity(0.0, 0.0, 0.0, 10.0), Asperity(40.0, 40.0, 0.0, 10.0)],
    )
    auto = estimate_memory(scene, 0.05, "twoscale")
    union = estimate_memory(scene, 0.05, "twoscale", iteration="union-cg")
    assert union.bytes > 2 * auto.bytes and "union box" in union.dominant


def _crowded_tips(n: int = 12) -> Scene:
    """Paraboloids 3 mm apart on a row under load: patches crowd their box (union CG and
    the far field both candidates of the policy)."""
    tips = [Asperity(3.0 * k, 0.0, 0.0, 5.0, shape="paraboloid") for k in range(n)]
    return Scene(material=Material(E=10.0, nu=0.5), total_load=2.0 * n, asperities=tips)


def test_an_iteration_asked_for_counts_only_what_it_builds(monkeypatch):
    # the union CG builds no cross-patch operator and no far field; a block iteration asked
    # for runs alone (no union CG after it): the estimate used to count the union box and
    # every block operator whatever was asked (1,000 paraboloids: 3.6 GB against 1.4 GB)
    from twoscale.micro import blocks

    built = []
    init = blocks.Coupling.__init__
    monkeypatch.setattr(blocks.Coupling, "__init__", lambda self, *a, **k: (built.append(1), init(self, *a, **k))[1])
    scene = _crowded_tips()
    h = 0.05
    res = solve_scene(scene, h=h, iteration="union-cg")
    assert res.converged and not built  # no pair operators were made
    union = dict(estimate_memory(scene, h, "twoscale", iteration="union-cg").parts)
    assert any("union box" in k for k in union) and "cached cross-patch operators" not in union
    assert not any("far field" in k for k in union)
    res = solve_scene(scene, h=h, iteration="two-level")
    assert res.converged and built
    assert [a.iteration for a in res.details.micro.attempts] == ["two-level"]  # alone: no union CG
    two_level = dict(estimate_memory(scene, h, "twoscale", iteration="two-level").parts)
    assert not any("union box" in k for k in two_level) and "cached cross-patch operators" in two_level


def _lattice(spacing: float, n: int = 11) -> Scene:
    """n x n paraboloids ``spacing`` mm apart under load: crowded, the far field a candidate."""
    tips = [Asperity(spacing * i, spacing * j, 0.0, 5.0, shape="paraboloid") for i in range(n) for j in range(n)]
    return Scene(material=Material(E=10.0, nu=0.5), total_load=2.0 * n * n, asperities=tips)


def test_auto_counts_the_union_cg_alone_where_the_near_pairs_would_hold_more_than_its_box():
    # 121 paraboloids 2.5 mm apart crowd their box: under the far field their near pairs'
    # operators would hold more than the union box, and the policy takes the union CG
    # (checked here): the estimate counts it alone, as the union CG asked for
    scene = _lattice(2.5)
    assert solve_scene(scene, h=0.05).details.micro.choice.iteration == "union-cg"
    est = estimate_memory(scene, 0.05, "twoscale")
    assert est.bytes == estimate_memory(scene, 0.05, "twoscale", iteration="union-cg").bytes
    assert "cached cross-patch operators" not in dict(est.parts)


@pytest.mark.parametrize("spacing, iteration", [(3.0, "union-cg"), (20.0, "two-level")])
def test_auto_counts_the_route_the_policy_takes(spacing, iteration):
    # twelve patches in a row under load: 3 mm apart they crowd their box and the policy
    # takes the union CG (predicted 0.06 s against 0.35 s for the block iterations), 20 mm
    # apart they cover 13 % of it and the far-field two-level iteration runs, the union CG
    # neither chosen nor a fallback (checked by solving); the estimate counts that route
    # alone (it used to count the larger of both wherever the contacts crowded the box)
    tips = [Asperity(spacing * k, 0.0, 0.0, 5.0, shape="paraboloid") for k in range(12)]
    scene = Scene(material=Material(E=10.0, nu=0.5), total_load=24.0, asperities=tips)
    micro = solve_scene(scene, h=0.05).details.micro
    assert [a.iteration for a in micro.attempts] == [iteration]
    est = estimate_memory(scene, 0.05, "twoscale").bytes
    assert est == estimate_memory(scene, 0.05, "twoscale", iteration=iteration).bytes


def test_auto_counts_the_block_iteration_and_says_what_the_union_cg_after_it_would_need():
    # where the policy may choose either (121 paraboloids 4 mm apart: the union CG chosen on
    # some of the patches the estimate considers, a block iteration on others), the block
    # iteration is counted, as when asked for; the union CG is checked against the memory
    # available when the policy takes it (test_memory_at_choice), and the estimate says what
    # it would need: after a block attempt that gives back all but BLOCK_ATTEMPT_HELD of its
    # memory (the heap trimmed), the box counted beyond the patches' cells (the union CG alone
    # counts the whole box, its patches windows of it)
    from twoscale.memory_costs import BLOCK_ATTEMPT_HELD, PATCH_BYTES_EACH

    est = estimate_memory(_lattice(4.0), 0.05, "twoscale")
    assert not any("union box" in k for k, _ in est.parts)
    assert est.bytes == estimate_memory(_lattice(4.0), 0.05, "twoscale", iteration="two-level").bytes
    block_keys = ("FFT work on the largest patch", "cached cross-patch operators", "far field's")
    parts = dict(est.union_parts)
    blocks = sum(v for k, v in parts.items() if k.startswith(block_keys))
    alone = dict(estimate_memory(_lattice(4.0), 0.05, "twoscale", iteration="union-cg").parts)
    union = sum(v for k, v in alone.items() if k.startswith("the union box"))
    count, patches = next((int(k.split()[0]), v) for k, v in parts.items() if k.endswith(" patches"))
    assert f"{count} patches, windows of the union box" in alone
    beyond = sum(v for k, v in parts.items() if "union box" in k)
    assert blocks > 0 and union > 0
    given_back = patches - PATCH_BYTES_EACH * count + (1.0 - BLOCK_ATTEMPT_HELD) * blocks
    assert beyond == pytest.approx(max(0.0, union - given_back))
    assert est.union_bytes == pytest.approx(sum(parts.values())) and est.union_bytes > est.bytes
    assert f"up to {est.union_bytes / 1e9:.3g} GB if the policy takes the union CG" in est.text


def test_auto_leaves_out_the_union_cg_that_only_follows_a_far_field_attempt():
    # 6 mm apart the policy takes the far-field two-level iteration at a coverage of 0.17
    # (checked by solving), after which the union CG would run only if that attempt did not
    # converge and its box fits then (test_memory_fallback): the block iterations are counted
    # as when asked for, the box not
    scene = _lattice(6.0)
    micro = solve_scene(scene, h=0.05).details.micro
    assert [(a.iteration, a.far_tol is not None, a.converged) for a in micro.attempts] == [("two-level", True, True)]
    assert micro.choice.estimates["coverage"] >= 0.14  # where the union CG is its fallback
    parts = dict(estimate_memory(scene, 0.05, "twoscale").parts)
    assert not any("union box" in k for k in parts)
    assert sum(parts.values()) == estimate_memory(scene, 0.05, "twoscale", iteration="two-level").bytes


def test_pair_operators_are_counted_at_their_arrays_sizes():
    # two patches 10 mm apart: a dense block of c x c entries when it is small enough, else
    # an FFT operator of (2 n)^2 / 2 complex values; both times what the coupling keeps beside
    from twoscale.memory_costs import DENSE_PAIR_ENTRIES, PAIR_HELD
    from twoscale.memory_parts import pair_bytes

    tips = np.array([[0.0, 0.0], [10.0, 0.0]])
    for half in (0.2, 1.0):  # 9 and 41 cells across at h = 0.05 mm
        n = math.floor(2 * half / 0.05) + 1
        c = n * n
        arrays = 8.0 * c * c if c * c <= DENSE_PAIR_ENTRIES else 8.0 * (2 * n) ** 2
        assert pair_bytes(tips, np.array([half, half]), 0.05, None) == pytest.approx(PAIR_HELD * arrays)
    # under the far field only near pairs are exact: these two are far apart at 0.3
    assert pair_bytes(tips, np.array([0.2, 0.2]), 0.05, 0.3) == 0.0


def test_the_far_fields_kept_weights_are_counted_where_it_may_be_taken():
    # scattered patches (the far field is a candidate): the weights it keeps, bytes per
    # owned cell (every patch cell counted) on patches under SEPARABLE_CELLS cells, the
    # rows and columns of the larger; two crowded patches (it is not): none
    from twoscale.micro.sources import KEPT_BYTES_PER_OWNED_CELL, SEPARABLE_BYTES_PER_ROW_OR_COLUMN, SEPARABLE_CELLS

    def parts(gap, R=10.0):
        scene = Scene(
            material=Material(E=10.0, nu=0.5),
            penetration=0.5,
            asperities=[Asperity(0.0, 0.0, 0.0, R), Asperity(gap, gap, 0.0, R)],
        )
        est = estimate_memory(scene, 0.05, "twoscale")
        return est, dict(est.parts)

    est, scattered = parts(40.0, R=0.5)  # two patches of 22 x 22 cells
    assert est.cells < 2 * SEPARABLE_CELLS
    assert scattered["far field's kept weights"] == KEPT_BYTES_PER_OWNED_CELL * est.cells == 152 * est.cells
    est, scattered = parts(40.0)  # two of 121 x 121 cells
    side = math.isqrt(est.cells // 2)
    assert 2 * side**2 == est.cells and side**2 >= SEPARABLE_CELLS
    assert scattered["far field's kept weights"] == SEPARABLE_BYTES_PER_ROW_OR_COLUMN * 2 * (2 * side) == 96 * side
    assert scattered["far field's point operator"] == 2 * FAR_OPERATOR_BYTES_PER_PATCH  # two patches
    est, crowded = parts(2.0)
    assert "far field's kept weights" not in crowded and any("union box" in k for k in crowded)
    assert "far field's point operator" not in crowded


def test_the_far_fields_point_operator_holds_what_the_estimate_counts_per_patch():
    # the operator the far field builds among 1,000 scattered patches (nine stencil points
    # and nine source nodes each): its arrays, against the bytes per patch the estimate
    # counts (an upper estimate, not wildly above)
    import scipy.sparse as sp

    from twoscale.grid import Grid
    from twoscale.influence import HalfSpace
    from twoscale.micro.farfield import LaggedFarField
    from twoscale.micro.patches import Patch

    def patch(k, x, y, n=5, h=0.05):
        g = Grid.covering(x - 0.5 * n * h, x + 0.5 * n * h, y - 0.5 * n * h, y + 0.5 * n * h, h)
        return Patch(k, g, np.zeros(g.shape), np.full(g.shape, k))

    rng = np.random.default_rng(1)
    xy = 0.6 * np.argwhere(np.ones((32, 32)))[:1000] + rng.uniform(-0.1, 0.1, (1000, 2))
    far = LaggedFarField(HalfSpace(Material(10.0, 0.5)), [patch(k, x, y) for k, (x, y) in enumerate(xy)], far_tol=0.3)
    op = far._point_operator()
    held = 0
    for v in vars(op).values():
        if isinstance(v, np.ndarray):
            held += v.nbytes
        elif sp.issparse(v):
            held += v.data.nbytes + v.indices.nbytes + v.indptr.nbytes
    assert 0.5 * FAR_OPERATOR_BYTES_PER_PATCH < held / 1000 <= FAR_OPERATOR_BYTES_PER_PATCH


def test_cells_grow_as_one_over_h_squared():
    coarse = estimate_memory(HERTZ, 0.04, "reference")
    fine = estimate_memory(HERTZ, 0.01, "reference")
    assert fine.cells / coarse.cells == pytest.approx(16.0, rel=0.1)  # the grid adds 3 cells around


def test_unknown_method_and_bad_h():
    with pytest.raises(ValueError, match="method"):
        estimate_memory(HERTZ, 0.05, "fft")
    with pytest.raises(ValueError, match="h must be"):
        estimate_memory(HERTZ, 0.0, "reference")


def test_check_memory_message_is_one_line_with_gb_limit_and_option():
    est = MemoryEstimate(bytes=6.5e9, cells=10**9, dominant="patch arrays", method="twoscale", h=1e-4)
    check_memory(est, 1e10)  # under the limit: nothing
    with pytest.raises(SceneError) as info:
        check_memory(est, 2e9, option="--h")
    msg = str(info.value)
    assert "\n" not in msg
    assert "6.5 GB" in msg and "2 GB" in msg and "--h" in msg


def test_check_memory_rejects_a_meaningless_limit():
    est = estimate_memory(HERTZ, 0.05, "reference")
    for bad in (0.0, -1.0, math.nan):
        with pytest.raises(ValueError, match="limit"):
            check_memory(est, bad)


def test_available_memory_is_read():
    assert 0 < available_memory() < math.inf
    assert default_limit() == pytest.approx(0.8 * available_memory(), rel=0.2)


def test_solve_scene_refuses_before_allocating_and_can_be_told_not_to_check():
    with pytest.raises(SceneError, match="too little memory available for any h;"):
        solve_scene(HERTZ, method="reference", memory_limit=1e6)
    res = solve_scene(
        Scene(material=HERTZ.material, asperities=HERTZ.asperities, penetration=0.5, h=0.25),
        method="reference",
        memory_limit=math.inf,
    )
    assert res.converged


def test_a_python_refusal_suggests_the_h_keyword_and_that_h_is_accepted(tmp_path):
    # solve() takes h=, not the scene file's grid.h: a refusal of the default h used to say
    # "try grid.h = ..." to a Python caller; the h it suggests must pass the same check
    path = tmp_path / "fifty.toml"
    path.write_text(fifty_tips_toml(), encoding="utf-8")
    scene = read_scene(path)
    limit = 0.8 * estimate_memory(scene, default_h(scene), "twoscale").bytes
    with pytest.raises(SceneError, match=r"\(the default, chosen from the scene\)") as refused:
        solve_scene(scene, memory_limit=limit)
    advice = re.search(r"; try (\S+) = ([0-9.e+-]+) mm or larger;", str(refused.value))
    assert advice is not None and advice.group(1) == "h", str(refused.value)
    h = float(advice.group(2))
    assert estimate_memory(scene, h, "twoscale").bytes <= limit


def test_solve_refuses_a_nan_memory_limit_instead_of_skipping_the_check():
    # NaN < inf is false: a NaN limit used to turn the check off without a word
    with pytest.raises(ValueError, match="memory limit must be > 0"):
        solve_scene(HERTZ, method="reference", memory_limit=float("nan"))


def test_a_load_history_is_checked_against_the_memory_limit_before_it_runs():
    # the history's grids used to be allocated whatever the limit (a MemoryError, or the
    # machine's memory, at a fine h); now the limit refuses it as it does a single load
    scene = read_scene(EXAMPLES / "creep" / "seven_spheres.toml")
    with pytest.raises(SceneError, match="over the limit of 0.001 GB"):
        solve_scene(scene, memory_limit=1e6)
    with pytest.raises(ValueError, match="memory limit must be > 0"):
        solve_scene(scene, memory_limit=float("nan"))


def test_cli_refuses_fifty_tips_at_h_1e_4(tmp_path, capsys):
    scene = tmp_path / "fifty.toml"
    scene.write_text(fifty_tips_toml(), encoding="utf-8")
    out = tmp_path / "out"
    code = main(["solve", str(scene), "--h", "1e-4", "--out", str(out)])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("error: ") and "GB" in err[0] and "--h" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fifty.toml"]  # no output folder


def test_cli_refuses_the_reference_too(tmp_path, capsys):
    scene = tmp_path / "fifty.toml"
    scene.write_text(fifty_tips_toml(h=1e-4), encoding="utf-8")  # h from the file this time
    assert main(["solve", str(scene), "--method", "reference", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "GB" in err[0] and "--h" in err[0]
    assert not (tmp_path / "out").exists()


def test_cli_passes_a_normal_scene(tmp_path):
    path = EXAMPLES / "hertz_sphere.toml"
    scene = read_scene(path)
    assert estimate_memory(scene, default_h(scene), "twoscale").bytes < default_limit()
    assert main(["solve", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert (tmp_path / "out" / "result.json").exists()


# VmHWM (peak resident set of this process image), not ru_maxrss: Linux keeps ru_maxrss
# across fork + exec, so a child of a large pytest process would report the parent's size
PEAK = textwrap.dedent("""
    import json, sys
    from twoscale.cli.main import main
    code = main(sys.argv[1:])
    with open("/proc/self/status") as fh:
        peak = next(int(line.split()[1]) * 1024 for line in fh if line.startswith("VmHWM:"))
    print(json.dumps({"code": code, "peak": peak}))
""")


# The measured peak depends on the machine (libraries, allocator, BLAS threads): an
# opt-in check (-m slow), not part of the default run.
@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/status")
@pytest.mark.parametrize("method", ["reference", "twoscale"])
def test_the_measured_peak_is_within_1_5x_of_the_estimate_both_ways(tmp_path, method):
    # a whole `twoscale solve --out` run (outputs included) in a fresh interpreter
    h = 0.02
    path = EXAMPLES / "hertz_sphere.toml"
    run = subprocess.run(
        [
            sys.executable,
            "-c",
            PEAK,
            "solve",
            str(path),
            "--method",
            method,
            "--h",
            str(h),
            "--quiet",
            "--out",
            str(tmp_path / "out"),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    got = json.loads(run.stdout.strip().splitlines()[-1])
    assert got["code"] == 0, run.stderr
    est = estimate_memory(read_scene(path), h, method)
    assert est.bytes / 1.5 <= got["peak"] <= 1.5 * est.bytes, (got["peak"] / 1e6, est.text)
