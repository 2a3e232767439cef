"""The package's errors and warnings, in one module that imports nothing of the package.

Every module that raises one of them imports it from here, so raising an error never
pulls in the module that defined it first (the import graph stays acyclic, see
``tests/test_import_graph.py``). Each class is still importable where it was
documented (``twoscale.scene.SceneError``, ``twoscale.surface.heightmap.SurfaceError``, ...).

Bad input is a :class:`SceneError` (a ``ValueError``) whose one-line message names the
bad value; the command line turns it into exit status 2.
"""

from __future__ import annotations

import os
import sys

#: The package's folder: a warning points at the first line outside it.
_PACKAGE = os.path.dirname(os.path.abspath(__file__)) + os.sep


def user_stacklevel() -> int:
    """``warnings.warn``'s ``stacklevel`` for a warning raised by the caller of this function
    that points at the first line outside the package (the user's call of
    ``twoscale.solve``, ``ContactSolver.solve``, ...), however deep in the package it is
    raised and by whichever entry point it was reached."""
    frame = sys._getframe(1)  # the function that warns
    level = 1
    while frame.f_back is not None and os.path.abspath(frame.f_code.co_filename).startswith(_PACKAGE):
        frame, level = frame.f_back, level + 1
    return level


class SceneError(ValueError):
    """Invalid scene data; the message names the field path and the bad value."""


class SurfaceError(SceneError):
    """A height map or a surface option that cannot be used; the message names the file
    or the option and what is wrong (a :class:`~twoscale.scene.SceneError`, so the
    command line reports it as bad input: exit 2)."""


class StudyError(SceneError):
    """Invalid study data; the message names the key and the bad value."""


class StudyBusy(ValueError):
    """Another live run holds the study folder (the message names its pid and host)."""


class SchedulerError(OSError):
    """The scheduler given by its address cannot be reached (the message names it)."""


class OutputFolderError(ValueError):
    """An output folder that cannot be used (one line naming the folder and why)."""


class BadEntry(ValueError):
    """A cache entry that cannot be trusted (the message says why)."""


class ResolutionWarning(UserWarning):
    """The cell size resolves some expected contacts with only a few cells."""


class CacheWarning(UserWarning):
    """A cache entry was damaged and dropped, or a cache folder cannot be written."""


class StepWarning(UserWarning):
    """A viscoelastic rolling step coarser than the road's samples or the fastest active
    Prony branch resolves: the hysteresis friction comes out low."""


class MemoryWarning(UserWarning):
    """A fallback the memory available at run time cannot hold was replaced by a smaller one
    (the union CG after a far-field attempt: block Gauss-Seidel with the same far field)."""


class TiltWarning(UserWarning):
    """A solved tilt beyond the small angles the linear ball-and-socket model assumes."""


class SurfaceWarning(UserWarning):
    """A height-map solve whose answer needs care (contacts reaching the map's edge)."""


class BulgeWarning(UserWarning):
    """Tips above the approach that a finite body's rising surface touches were left out of
    the solve (:mod:`twoscale.bulge`)."""
