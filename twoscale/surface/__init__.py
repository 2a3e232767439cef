"""Measured surfaces (height maps, e.g. a road texture scan) as indenters.

The pipeline, one module per step:

* :mod:`.reading` — plain files (``.npy``, ``.npz``, text grids, x-y-z point lists) and,
  through the optional SurfaceTopography, instrument formats (X3P, SUR, OPD, PLU, DATX, ...);
* :mod:`.conditioning` — units to mm, missing samples, plane detrend, crop, resampling to
  the cell size, which side faces the body, centring on the lattice;
* :mod:`.segmentation` — summits (local maxima with a minimum distance and prominence) and
  one watershed basin per summit;
* :mod:`.sphere_fit` — the equivalent sphere of each summit cap;
* :mod:`.indenter` — the basins as indenters whose rigid surface is the height map itself
  (what the micro step and the reference solver see);
* :mod:`.laws` and :mod:`.lawcache` — per-asperity tabulated laws from single-asperity
  micro-scale solves, kept on disk;
* :mod:`.measured` — all of it for a scene (:func:`load_surface`);
* :mod:`.texture` — seeded synthetic road textures;
* :mod:`.figure` — the segmentation drawn over the height map.

To solve a map given in Python, build the surface and pass it (not its asperities) to
:func:`twoscale.solve`; it is the scene a scene file's ``[surface]`` table builds::

    surface = build_surface(RawMap(heights, spacing=0.1, units="um"), SurfaceOptions(min_distance=2.0))
    result = twoscale.solve(surface, material=twoscale.Material(10.0, 0.5), total_load=500.0)
    result.details.surface    # missing samples, units, contacts at the map's edge
"""

from .heightmap import HeightMap, SurfaceError
from .indenter import MapAsperity, map_asperities
from .lawcache import LawCache
from .laws import LawTable, sphere_law_error
from .measured import MeasuredSurface, SurfaceOptions, build_surface, load_surface
from .reading import RawMap, read_heightmap
from .conditioning import condition
from .segmentation import Segmentation, segment

__all__ = [
    "HeightMap",
    "SurfaceError",
    "MapAsperity",
    "map_asperities",
    "LawCache",
    "LawTable",
    "sphere_law_error",
    "MeasuredSurface",
    "SurfaceOptions",
    "build_surface",
    "load_surface",
    "RawMap",
    "read_heightmap",
    "condition",
    "Segmentation",
    "segment",
]
