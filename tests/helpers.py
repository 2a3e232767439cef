"""Helpers shared by several test modules (scene builders, a PNG reader).

Plain functions, not fixtures: some build module-level constants. Test modules import
them from here, never from one another.
"""

from __future__ import annotations

import math
import struct
import zlib

import numpy as np

from twoscale.indenters import Asperity


#: A scene file of three spheres under load control with a free tilt (h 0.3 mm).
THREE_SPHERES_TILT = """
[material]
E = 6.0
nu = 0.5
[load]
total = 10.0
tilt = true
[grid]
h = 0.3
[[asperity]]
x = 0.0
y = 0.0
R = 5.0
[[asperity]]
x = 8.0
y = 0.0
R = 5.0
[[asperity]]
x = 0.0
y = 8.0
R = 4.0
"""


def half_space_as_block(material, *, size, base, origin, source_spacing, progress):
    """Stands in for the finite block's builder: the half-space itself, so that every body
    of a comparison must agree exactly."""
    from twoscale.influence import HalfSpace

    return HalfSpace(material)


def small_block(material):
    """A small bonded finite block (60 x 60 x 10 mm, coarse mesh, no cache) for tests that
    need a body other than the half-space (fem_influence must be importable)."""
    from fem_influence import BlockProvider

    return BlockProvider(
        material=material,
        size=(60.0, 60.0, 10.0),
        h_fine=5.0,
        h_coarse=10.0,
        fine_half_width=10.0,
        use_cache=False,
        progress=False,
    )


def spaced_spheres(n, seed, side, spread=0.06):
    """``n`` spheres (R 2-6 mm, tip heights spread over ``spread`` mm) at random on a
    ``side`` x ``side`` mm square, centres at least 1.5 mm apart (seeded)."""
    rng = np.random.default_rng(seed)
    pts = []
    while len(pts) < n:
        c = rng.uniform(0.0, side, 2)
        if not pts or np.min(np.hypot(*(np.array(pts) - c).T)) >= 1.5:
            pts.append(c)
    R = rng.uniform(2.0, 6.0, n)
    z = rng.uniform(0.0, spread, n)
    return [Asperity(float(x), float(y), float(zz), float(r)) for (x, y), zz, r in zip(pts, z, R)]


def random_spheres(seed: int, n: int, half: float, R: float) -> list:
    """``n`` spheres of radius ``R`` at random on ``[-half, half]^2`` (x, then y drawn),
    tips 0-0.02 mm deep (seeded; they may overlap)."""
    rng = np.random.default_rng(seed)
    x, y, z = rng.uniform(-half, half, n), rng.uniform(-half, half, n), rng.uniform(0, 0.02, n)
    return [Asperity(float(a), float(b), float(c), R) for a, b, c in zip(x, y, z)]


def png_info(path):
    """Width, height and tEXt chunks of a PNG, read straight from its bytes."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, text, size = 8, {}, None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos : pos + 8])
        body = data[pos + 8 : pos + 8 + n]
        if kind == b"IHDR":
            size = struct.unpack(">II", body[:8])
        elif kind == b"tEXt":
            k, v = body.split(b"\0", 1)
            text[k.decode()] = v.decode("latin-1")
        elif kind == b"zTXt":
            k, rest = body.split(b"\0", 1)
            text[k.decode()] = zlib.decompress(rest[1:]).decode("latin-1")
        pos += 12 + n
    return size, text


def crowded(seed: int, n: int) -> list:
    """n spheres (R 3-6 mm, tips 0-0.1 mm deep) at random, about 3 mm apart: contacts merge."""
    rng = np.random.default_rng(seed)
    side = 3.0 * math.sqrt(n)
    out: list = []
    while len(out) < n:
        x, y = rng.uniform(-side / 2, side / 2, 2)
        if all(math.hypot(x - a.x, y - a.y) > 1.2 for a in out):
            out.append(Asperity(float(x), float(y), float(rng.uniform(0.0, 0.1)), float(rng.uniform(3.0, 6.0))))
    return out


def crowded_surface(material, seed: int, load: dict):
    """The surface of :func:`crowded` ``(seed, 16)`` on the reference grid (h 0.08 mm) of its
    scene under ``load`` (``penetration``/``total_load``, ``tilt``) on ``material``."""
    from twoscale.indenters import surface_on
    from twoscale.reference.on_scene import reference_grid
    from twoscale.scene import Scene

    asps = crowded(seed, 16)
    return surface_on(reference_grid(Scene(material=material, asperities=asps, h=0.08, **load), 0.08), asps)


def paraboloid_scene(xs, zs=None) -> str:
    """A scene file's text: paraboloids of R = 10 mm at (x, 0), recesses ``zs`` (mm), on a
    half-space E = 10 MPa, nu = 0.5, h = 0.1 mm."""
    head = "[material]\nE = 10.0\nnu = 0.5\n[load]\npenetration = 0.1\n[grid]\nh = 0.1\n"
    zs = [0.0] * len(xs) if zs is None else zs
    return head + "".join(
        f'[[asperity]]\nx = {x}\ny = 0.0\nz = {z}\nR = 10.0\nshape = "paraboloid"\n' for x, z in zip(xs, zs)
    )


def random_scene(seed: int, n: int):
    """n spheres of radius 4-6 mm in a square, a third of them in tight pairs (their
    reaches overlap), tip recesses 0-0.35 mm (the deepest never touch)."""
    rng = np.random.default_rng(seed)
    side = 6.0 * math.sqrt(n)
    asps = []
    while len(asps) < n:
        x, y = rng.uniform(-side / 2, side / 2, 2)
        R_ = float(rng.choice([4.0, 5.0, 6.0]))
        asps.append(Asperity(float(x), float(y), float(rng.uniform(0.0, 0.35)), R_))
        if len(asps) < n and rng.uniform() < 0.35:
            ang = rng.uniform(0, 2 * np.pi)
            dist = rng.uniform(1.0, 2.0)
            asps.append(
                Asperity(
                    float(x + dist * np.cos(ang)),
                    float(y + dist * np.sin(ang)),
                    float(rng.uniform(0.0, 0.05)),
                    float(rng.choice([4.0, 5.0, 6.0])),
                )
            )
    return asps


def sweep_macro_inputs(index: int, seed: int = 0):
    """The sweep's scene ``index`` (of ``seed``'s draws) as the macro step takes it: ``(scene,
    tips, z, provider)``, the tips' ``(x, y)`` and heights."""
    from twoscale.scenespace import build, sweep

    (spec,) = [s for s in sweep(200, seed) if s.index == index]
    scene = build(spec)
    tips = np.array([[a.x, a.y] for a in scene.asperities])
    z = np.array([a.z for a in scene.asperities])
    return scene, tips, z, scene.provider()


def paraboloid_patch_problems(rng, count: int, sizes: tuple, spread: float, h: float, E_star: float):
    """``count`` square patches of ``sizes`` (low, high) cells across at random places within
    +-``spread`` mm, each with a paraboloid's heights centred inside it, the Hertz force of a
    contact radius 0.15-0.3 of the patch and an approach putting it at 0.5-1.5 a^2 / R:
    ``(patches, heights, forces, approaches)`` for the micro step's first passes."""
    from twoscale.grid import Grid
    from twoscale.micro.patches import Patch

    patches, z, forces, approaches = [], [], [], []
    for k in range(count):
        n = int(rng.integers(*sizes))
        g = Grid(rng.uniform(-spread, spread), rng.uniform(-spread, spread), h, n, n)
        patches.append(Patch(k, g, np.zeros(g.shape), np.full(g.shape, k)))
        X, Y = g.centres()
        c = np.array([g.x0, g.y0]) + rng.uniform(0.2, 0.8, 2) * (n - 1) * h
        R = rng.uniform(2.0, 8.0)
        z.append((((X - c[0]) ** 2 + (Y - c[1]) ** 2) / (2 * R)).ravel())
        a = rng.uniform(0.15, 0.3) * n * h  # Hertz's contact radius within the patch
        forces.append(4.0 * E_star * a**3 / (3.0 * R))
        approaches.append(float(rng.uniform(0.5, 1.5) * a * a / R))  # its contact at d / 2
    return patches, z, forces, approaches


def patches_on_x(tips, h: float, half_x: float, y_range: tuple):
    """Spheres (R 5 mm) at ``(x, 0)`` for x in ``tips`` and their patches, ``half_x`` mm
    either side and ``y_range`` across: ``(asperities, patches)``."""
    from twoscale.grid import Grid
    from twoscale.micro.patches import make_patch

    asps = [Asperity(x, 0.0, 0.0, 5.0) for x in tips]
    grids = [Grid.covering(x - half_x, x + half_x, y_range[0], y_range[1], h) for x in tips]
    return asps, [make_patch(k, g, asps) for k, g in enumerate(grids)]


def disc_on_patch(pt, centre: float, radius: float) -> np.ndarray:
    """Pressure 1 on the patch's owned cells within ``radius`` of ``(centre, 0)``."""
    X, Y = pt.grid.centres()
    return np.where(np.hypot(X - centre, Y) <= radius, 1.0, 0.0)[pt.owned]


def disc_patches(tips, h, n=24, radius=0.2) -> list:
    """A patch of ``n`` x ``n`` cells of side ``h`` about each ``(x, y)`` of ``tips``, its
    cells within ``radius`` owned (height ``r^2``), the others empty."""
    from twoscale.grid import Grid
    from twoscale.micro.patches import Patch

    out = []
    for k, (x, y) in enumerate(tips):
        grid = Grid(round((x - n * h / 2) / h) * h, round((y - n * h / 2) / h) * h, h, n, n)
        X, Y = grid.centres()
        r2 = (X - x) ** 2 + (Y - y) ** 2
        owned = r2 < radius**2
        out.append(Patch(k, grid, np.where(owned, r2, np.inf), np.where(owned, k, -1)))
    return out


def every_tip_on_every_cell(grid, asps):
    """Heights and owners by every asperity evaluated on every cell of ``grid`` (a tie to
    the earlier index): the plain sampling the fast samplers must equal bit for bit."""
    X, Y = grid.centres()
    height = np.full(grid.shape, np.inf)
    owner = np.full(grid.shape, -1)
    for k, a in enumerate(asps):
        hk = a.height(X, Y)
        better = hk < height
        height[better], owner[better] = hk[better], k
    return height, owner


def newton_on_a_line(newton, x0: float, factor: float, max_iter: int, stops):
    """``newton`` on the residual r(x) = x whose step is ``-factor r``: the residual falls to
    ``1 - factor`` of itself a step (factor 1: one exact step)."""
    return newton(
        lambda x: x.copy(),
        lambda x, r: -factor * r,
        np.array([x0]),
        scale=lambda x: 1.0,
        tol=1e-10,
        max_iter=max_iter,
        stops=stops,
    )


def lattice_patches(rng, n: int, spread: float, h: float, largest: int = 24) -> list:
    """``n`` micro-step patches of 8 to ``largest`` cells a side on one lattice of cell ``h``
    over ``spread`` mm, a neighbour owning a corner of about 30 % of them."""
    from twoscale.grid import Grid
    from twoscale.micro.patches import Patch

    out = []
    for k in range(n):
        nx, ny = (int(v) for v in rng.integers(8, largest + 1, 2))
        i0, j0 = (int(v) for v in rng.integers(0, int(spread / h), 2))
        g = Grid(i0 * h, j0 * h, h, nx, ny)
        owner = np.full(g.shape, k)
        if rng.random() < 0.3:  # a neighbour owns a corner
            owner[: ny // 3, : nx // 3] = -1
        out.append(Patch(k, g, np.zeros(g.shape), owner))
    return out


def lattice_values(rng, patches) -> list:
    """Random pressures (MPa) on the patches' owned cells, zero on some cells and on the
    second patch: the right-hand sides of the lattice tests."""
    vals = [rng.random(int(pt.owned.sum())) * (rng.random(int(pt.owned.sum())) < 0.6) for pt in patches]
    vals[1] = np.zeros_like(vals[1])
    return vals
