"""The finite-block influence provider: Love/Boussinesq half-space + smooth FEM correction.

Point compliance of the block ``K(x, x') = 1/(pi E* |x - x'|) + C(x, x')``. The
correction ``C`` (mm/N) is the top-face vertical displacement of the correction
field of :mod:`fem_influence.correction`. It is smooth in both arguments:

* in the target ``x`` it is evaluated from the top-face Q2 nodes
  (:class:`fem_influence.interpolate.TopInterpolator`: the exact Q2 interpolant on
  rectilinear top faces, Clough-Tocher on others);
* in the source ``x'`` it is interpolated with tensor cubic Lagrange weights from
  a lattice of source points of spacing ``source_spacing`` (block frame, anchored at
  the top face's centre). Only the lattice nodes around the points the scene asks
  about are ever solved ("model only what the scene needs"); each costs one
  back-substitution with the factorisation shared by all of them.

Cell blocks use ``Love + h^2 C(centres)`` (C varies on the thickness scale, so the
midpoint rule is accurate to ``O(h^2 / t^2)`` relative), and grid products use the
half-space FFT convolution plus the low-rank product ``h^2 U (W p)`` with
``U = C(targets, lattice)`` and ``W`` the sparse source-interpolation weights.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from twoscale.grid import Grid
from twoscale.influence.base import GridOperator, InfluenceProvider
from twoscale.influence.halfspace import HalfSpace
from twoscale.influence.points import KEEP_ENTRIES, check_points
from twoscale.material import Material
from twoscale.progress import Progress

from .assembly import INTORDER
from .box_entries import BoxEntries, box_entries
from .build_memory import build_bytes
from .cache import FieldCache, cache_key, default_cache_dir
from .grid_factors import grid_target, grid_weights
from .layer import BASES
from .lattice_state import LatticeState
from .factored_correction import BlockCorrection
from .operators import BlockGridOperator, TargetFactor, block_point_operator, point_weights

#: Grids whose correction factors (source weights, target interpolation) a provider keeps
#: (two entries a patch; beyond, all are dropped and rebuilt on use).
MEMO_GRIDS = 20_000
#: Factors up to this many entries are kept dense (8 bytes each), larger ones sparse or
#: factored.
DENSE_FACTOR_ENTRIES = 2_000_000


@dataclass(frozen=True, eq=False)
class BlockProvider(InfluenceProvider):
    """Rectangular elastic block on a rigid base, loaded on its top face.

    Parameters
    ----------
    material : Material
        E (MPa) and nu (0 < nu <= 0.5; 0.5 exactly is supported).
    size : (3,) floats, default (140, 140, 20)
        Block length along x, y and thickness, mm. Ignored (replaced by the mesh's
        extent) when ``mesh`` is given.
    base : {"bonded", "sliding"}, default "bonded"
        Rigid base condition: u = 0, or u_z = 0 with no shear.
    origin : (2,) floats, default (0, 0)
        Where the scene's (0, 0) sits, measured from the top face's centre, mm.
    mesh : skfem.MeshHex or path, optional
        Block mesh in the block frame ``(x, y, depth)`` (see :mod:`meshes`), or a
        file read with :func:`meshes.read_block_mesh`. Default: :func:`meshes.block_mesh`
        with ``h_fine`` around the scene and ``h_coarse`` towards the sides.
    h_fine : float, default 5
        Element size of the default mesh over ``origin +- fine_half_width``, mm.
    h_coarse : float, default 12
        Largest element size of the default mesh, mm.
    fine_half_width : float, default 25
        Half width of the finely meshed square around the scene origin, mm.
    source_spacing : float, default 5
        Spacing of the source lattice for the correction, mm.
    cache_dir : str or Path, optional
        Directory of the on-disk cache; default :func:`fem_influence.cache.default_cache_dir`
        (env ``TWOSCALE_CACHE_DIR``).
    use_cache : bool, default True
        False keeps everything in memory.
    progress : bool, default True
        Show a progress line on stderr for builds longer than 2 s.
    use_symmetry : bool, default True
        When the mesh is mirror-symmetric in x and y (the default mesh with
        ``origin = (0, 0)``), solve only sources with non-negative lattice indices and
        mirror the others (about 3.4x fewer solves for a centred scene).
    """

    material: Material
    size: tuple = (140.0, 140.0, 20.0)
    base: str = "bonded"
    origin: tuple = (0.0, 0.0)
    mesh: object = None
    h_fine: float = 5.0
    h_coarse: float = 12.0
    fine_half_width: float = 25.0
    source_spacing: float = 5.0
    cache_dir: object = None
    use_cache: bool = True
    progress: bool = True
    use_symmetry: bool = True
    kind: str = field(default="block", init=False)
    #: Local solves cut a block again per active set, not stored (4,753 tips stored 3 GB).
    cheap_grid_matrix = True
    surface_rises = True  # beside a contact (a bonded base bulges): twoscale.bulge checks

    def __post_init__(self) -> None:
        from meshes import block_mesh, read_block_mesh

        if not isinstance(self.material, Material):
            raise ValueError(f"material must be a Material, got {self.material!r}")
        if not self.material.nu > 0:
            raise ValueError(f"material.nu must be > 0 for the mixed block model, got {self.material.nu!r}")
        if self.base not in BASES:
            raise ValueError(f"base must be one of {BASES}, got {self.base!r}")
        origin = tuple(float(v) for v in np.asarray(self.origin, dtype=float).reshape(2))
        if not self.source_spacing > 0:
            raise ValueError(f"source_spacing must be > 0 (mm), got {self.source_spacing!r}")
        mesh = self.mesh
        if mesh is None:
            size = tuple(float(v) for v in self.size)
            if len(size) != 3 or min(size) <= 0:
                raise ValueError(f"size must be three positive lengths (mm), got {self.size!r}")
            w = self.fine_half_width
            mesh = block_mesh(
                size,
                h_fine=self.h_fine,
                h_coarse=self.h_coarse,
                fine_box=(origin[0] - w, origin[0] + w, origin[1] - w, origin[1] + w),
            )
        elif isinstance(mesh, (str, Path)):
            mesh = read_block_mesh(mesh)
        p = mesh.p
        size = (float(np.ptp(p[0])), float(np.ptp(p[1])), float(p[2].max()))
        if abs(origin[0]) >= size[0] / 2 or abs(origin[1]) >= size[1] / 2:
            raise ValueError(f"origin {self.origin!r} lies outside the top face of size {size[:2]}")
        object.__setattr__(self, "mesh", mesh)
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "origin", origin)
        directory = None
        if self.use_cache:
            directory = Path(self.cache_dir) if self.cache_dir is not None else default_cache_dir()
        key = cache_key(mesh, nu=self.material.nu, base=self.base, spacing=self.source_spacing, intorder=INTORDER)
        fc = FieldCache(key, directory)
        fc.load()
        state = LatticeState(fields=fc)
        state.refresh()
        object.__setattr__(self, "_state", state)
        object.__setattr__(self, "_halfspace", HalfSpace(self.material))

    def cache_usage(self) -> tuple:
        """What the correction cache on disk read, wrote and dropped so far."""
        return self._state.fields.usage()

    # ------------------------------------------------------------------ the correction
    @property
    def timings_s(self) -> dict:
        """Seconds spent in assembly, factorisation and lattice solves so far."""
        return dict(self._state.timings_s)

    def _lattice_bounds(self) -> tuple[int, int, int, int]:
        d = self.source_spacing
        # lattice nodes stay one spacing inside the sides (side data near a source are
        # peaked; the graded mesh resolves sources at least ~h_coarse from the sides)
        ix = int(np.floor((self.size[0] / 2 - d) / d))
        iy = int(np.floor((self.size[1] / 2 - d) / d))
        return -ix, ix, -iy, iy

    def domain(self) -> tuple[float, float, float, float]:
        """Scene-frame rectangle ``(x0, x1, y0, y1)`` (mm) where loaded points are answered:
        the correction lattice, one ``source_spacing`` inside the block's sides."""
        d = self.source_spacing
        x0, x1, y0, y1 = self._lattice_bounds()
        ox, oy = self.origin
        return (x0 * d - ox, x1 * d - ox, y0 * d - oy, y1 * d - oy)

    def check_answered(self, points: np.ndarray) -> None:
        """Refuse loaded points (scene frame, (N, 2)) outside :meth:`domain`."""
        d = self.source_spacing
        S = np.asarray(points, dtype=float).reshape(-1, 2) + np.asarray(self.origin)
        x0, x1, y0, y1 = self._lattice_bounds()
        tol = 1e-9 * d
        out = (S[:, 0] < x0 * d - tol) | (S[:, 0] > x1 * d + tol) | (S[:, 1] < y0 * d - tol) | (S[:, 1] > y1 * d + tol)
        if out.any():
            # beyond the outermost lattice node the cubic stencil would extrapolate (errors
            # of ~20 % of C measured 3 mm from a side): refuse rather than answer badly
            bad = S[out][0] - np.asarray(self.origin)
            x_lo, x_hi, y_lo, y_hi = self.domain()
            raise ValueError(
                f"loaded point ({bad[0]:.3g}, {bad[1]:.3g}) mm (scene frame) is outside "
                f"the block's answered region x in [{x_lo:.4g}, {x_hi:.4g}], y in "
                f"[{y_lo:.4g}, {y_hi:.4g}] mm (one source_spacing = {d} mm inside the "
                f"sides); move the indenters inward or lower source_spacing"
            )

    _weights = point_weights  # sparse source weights (lattice nodes used) x (sources), and the nodes
    build_bytes = build_bytes  # the factorisation where the cache lacks a field (.build_memory)

    def _ensure(self, nodes: np.ndarray) -> np.ndarray:
        """Solve the lattice nodes not yet known; return their columns in the field table."""
        st = self._state
        cols = st.column_of(nodes)
        if (cols >= 0).all():
            return cols
        missing = nodes[cols < 0]
        from .correction import CorrectionSolver

        perms = self._state.mirror_permutations(self.mesh) if self.use_symmetry else None
        # with a mirror-symmetric mesh, only sources with i, j >= 0 are solved; the
        # others are the same fields read at mirrored nodes
        solve = np.unique(np.abs(missing), axis=0) if perms is not None else missing
        solve = solve[st.column_of(solve) < 0] if len(solve) else solve
        pr = Progress(
            len(solve) + 1, label=f"block correction ({self.base}, nu={self.material.nu})", quiet=not self.progress
        )
        if len(solve) and st.solver is None:
            st.solver = CorrectionSolver.build(self.mesh, self.material.nu, self.base)
            for k, v in st.solver.timings_s.items():
                st.timings_s[k] = st.timings_s.get(k, 0.0) + v
        pr.update(1, note="factorised")
        t0 = time.perf_counter()
        batch = 32
        for b in range(0, len(solve), batch):
            chunk = solve[b : b + batch]
            fields = st.solver.top_displacement(chunk * self.source_spacing)
            st.fields.add(chunk, fields, st.solver.top_xy)
            pr.update(len(chunk), note="sources")
        if perms is not None:
            mirrored = [ij for ij in missing.tolist() if tuple(ij) not in st.fields.fields]
            if mirrored:
                px, py = self._state.mirror_permutations(self.mesh)
                out = []
                for i, j in mirrored:
                    f = st.fields.fields[(abs(i), abs(j))]
                    f = f[px] if i < 0 else f
                    f = f[py] if j < 0 else f
                    out.append(f)
                st.fields.add(np.array(mirrored), np.array(out), st.fields.top_xy)
        st.timings_s["solves"] = st.timings_s.get("solves", 0.0) + time.perf_counter() - t0
        pr.close()
        st.refresh()
        return st.column_of(nodes)

    def _top_values(self, targets: np.ndarray, nodes: np.ndarray) -> np.ndarray:
        """Correction at ``targets`` (scene frame) from each lattice node, (M, K), mm/N."""
        cols = self._ensure(nodes)
        st = self._state
        T = np.asarray(targets, dtype=float).reshape(-1, 2) + np.asarray(self.origin)
        if not st.interpolator.rectilinear:
            return st.interpolator(T, st.table[:, cols]) / self.material.E
        M, rows = st.interpolator.compressed(T)  # the table's rows of the nodes used only
        return M @ st.table[np.ix_(rows, cols)] / self.material.E

    def correction(self, targets: np.ndarray, sources: np.ndarray) -> np.ndarray:
        """Smooth part ``C(x, x')`` of the point compliance, (M, N), mm/N (scene frame)."""
        nodes, W = self._weights(sources)
        return np.asarray((W.T @ self._top_values(targets, nodes).T).T)

    def displacement_field(self, points, forces, *, aggregate: float = 1.0):
        """Displacement inside the block for surface point forces (mm, N).

        Parameters
        ----------
        points : (N, 2) array
            Force positions on the top face, scene frame, mm (e.g. loaded micro-cell centres).
        forces : (N,) array
            Forces into the block, N (e.g. ``h^2 p``).
        aggregate : float, default 1
            Side of the square bins (mm) the forces are merged into for the Boussinesq
            part (0: every force on its own); see :mod:`fem_influence.field` for where
            this approximation is poor (nodes within a few bins of the loaded surface).

        Returns
        -------
        fem_influence.field.BlockField
            Vertices (scene frame x, y and depth) and ``(n, 3)`` displacements.
        """
        from .correction import CorrectionSolver
        from .field import BlockField, aggregate_forces, halfspace_field

        P = np.asarray(points, dtype=float).reshape(-1, 2)
        f = np.asarray(forces, dtype=float).reshape(-1)
        if len(f) != len(P) or not (np.isfinite(P).all() and np.isfinite(f).all()):
            raise ValueError(f"points ({P.shape}) and forces ({f.shape}) must be finite, one force per point")
        st = self._state
        nodes_xyz = self.mesh.p.T.copy()
        nodes_xyz[:, :2] -= np.asarray(self.origin)
        S, F = aggregate_forces(P, f, aggregate)
        lift = aggregate if aggregate > 0 else 1e-3 * self.source_spacing
        u_b = halfspace_field(nodes_xyz, S, F, self.material, lift=lift)
        u_c = np.zeros_like(u_b)
        if len(f):
            lattice, W = self._weights(P)
            coeff = W @ f  # force carried by each lattice node, N
            if st.solver is None:
                st.solver = CorrectionSolver.build(self.mesh, self.material.nu, self.base)
            u_c = st.solver.vertex_displacement(lattice * self.source_spacing, coeff) / self.material.E
        return BlockField(
            points=nodes_xyz,
            displacement=u_b + u_c,
            halfspace=u_b,
            cells=np.asarray(self.mesh.t.T, dtype=np.int64),
            n_forces=len(F),
            total_force=float(f.sum()),
            aggregate=float(aggregate),
        )

    # ------------------------------------------------------------------ the contract
    def point_compliance(self, targets, sources):
        return self._halfspace.point_compliance(targets, sources) + self.correction(targets, sources)

    def pair_compliance(self, points, i, j):
        """``point_compliance(points, points)[i, j]`` of the pairs ``(i, j)`` alone (mm/N)."""
        from .operators import pair_compliance

        return pair_compliance(self, points, i, j)

    def smooth_self_compliance(self, points):
        # the diagonal of ``correction(p, p)`` alone (4,753 tips: not its 22.6 M values)
        p = np.asarray(points, dtype=float).reshape(-1, 2)
        nodes, W = self._weights(p)
        return np.asarray(W.multiply(self._top_values(p, nodes).T).sum(axis=0)).ravel()

    def cell_block(self, targets, sources, h):
        return self._halfspace.cell_block(targets, sources, h) + h * h * self.correction(targets, sources)

    def grid_matrix(self, target: Grid, source: Grid | None = None) -> np.ndarray:
        """Love's block plus ``h^2 U W`` from the factors kept per grid (a rank of ~16-36
        lattice nodes: cheap next to factorising the block, see ``cheap_grid_matrix``)."""
        source = target if source is None else source
        cols, W = self._source_weights(source)
        C = self._target_factor(target, cols) @ (W.toarray() if hasattr(W, "toarray") else W)
        return self._halfspace.grid_matrix(target, source, tables=self._state.love_tables) + target.h**2 * C

    def box_window(self, box: Grid) -> BoxEntries | None:
        """A dense local block's own entries from factors kept for ``box`` (:func:`box_entries`)."""
        return box_entries(self, box)

    def grid_operator(self, target: Grid, source: Grid | None = None) -> "BlockGridOperator":
        source = target if source is None else source
        hs = self._state.halfspace_operator(self._halfspace, target, source)
        return self._with_correction(hs, target, source)

    def split(self):
        """(half-space, :class:`BlockCorrection`): Love's cell blocks plus ``h^2 U (W p)``."""
        return self._halfspace, BlockCorrection(self)

    def point_operator(self, targets, sources, *, exclude=None, rtol: float = 1e-6):
        """As the contract's; above ``KEEP_ENTRIES`` pairs the half-space's fast operator plus
        the low-rank correction (:func:`~.operators.block_point_operator`)."""
        t, s = check_points(targets, "targets"), check_points(sources, "sources")
        if len(t) * len(s) <= KEEP_ENTRIES:
            return super().point_operator(t, s, exclude=exclude, rtol=rtol)
        return block_point_operator(self, t, s, exclude, rtol)

    def separated_operator(self, target: Grid, source: Grid, *, rtol: float = 1e-8):
        """The half-space's Chebyshev block for a well-separated pair plus the same low-rank
        correction as :meth:`grid_operator` (exact); ``None`` where the half-space has none."""
        hs = self._halfspace.separated_operator(target, source, rtol=rtol)
        return None if hs is None else self._with_correction(hs, target, source)

    def _source_weights(self, source: Grid):
        """(columns in the field table, weights (columns x cells)) of a source grid, kept per
        grid as its axis factors (:class:`~.grid_factors.GridWeights`; dense: 104 kB a patch)."""
        st = self._state
        if len(st.grid_memo) > MEMO_GRIDS:
            st.grid_memo.clear()
        key_w = ("W", source)
        if key_w not in st.grid_memo:
            nodes, W = grid_weights(self, source)
            cols = self._ensure(nodes)
            st.grid_memo[key_w] = (cols, W)
        return st.grid_memo[key_w]

    def _target_factor(self, target: Grid, cols: np.ndarray | None = None):
        """Correction at the target cells from the lattice nodes of the table columns ``cols``
        (default all), mm/N (:class:`TargetFactor`): factored, the interpolation on the nodes
        the grid uses kept per grid (rectilinear meshes), dense for a few columns (up to
        :data:`DENSE_FACTOR_ENTRIES` entries), or separable above (a union box's)."""
        st = self._state
        if not st.interpolator.rectilinear:
            cols = np.arange(st.table.shape[1]) if cols is None else cols
            return TargetFactor(None, self._top_values(target.points(), st.nodes_of(cols)))
        T = st.scaled_table(self.material.E)
        if cols is not None and target.size * len(cols) > DENSE_FACTOR_ENTRIES:
            return grid_target(st.interpolator, target, self.origin, T[:, cols])
        M, rows = st.interpolation(target, self.origin)
        # the table's rows and columns the grid uses only (not its rows across every column)
        return TargetFactor(M, T[rows]) if cols is None else TargetFactor(None, np.asarray(M @ T[np.ix_(rows, cols)]))

    def _with_correction(self, halfspace_op: GridOperator, target: Grid, source: Grid) -> "BlockGridOperator":
        # U and W depend on one grid each (the micro step asks for every pair): kept per grid
        cols, W = self._source_weights(source)
        return BlockGridOperator(halfspace_op, self._target_factor(target, cols), W, target.h**2)
