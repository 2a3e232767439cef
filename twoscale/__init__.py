"""Two-scale multi-asperity contact on elastic bodies (units: mm, N, MPa).

Light on import: heavy optional modules (scikit-fem, meshio, pyvista, matplotlib)
are imported only where they are used.
"""
from ._version import __version__
from .material import Material
from .grid import Grid

__all__ = ["__version__", "Material", "Grid"]
