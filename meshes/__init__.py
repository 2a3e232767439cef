"""Block meshes for the finite-block influence provider (``fem_influence``).

Frame of every mesh here: ``x, y`` on the top face with the top face's centre at
the origin, third coordinate = depth (mm, positive into the body, 0 on the top
face). :func:`block_mesh` is the default graded recipe; :func:`read_block_mesh`
reads a user's hexahedral mesh with meshio.
"""

from .block import block_mesh, graded_axis
from .read import read_block_mesh, write_block_mesh

__all__ = ["block_mesh", "graded_axis", "read_block_mesh", "write_block_mesh"]
