"""Figures of contact results (matplotlib, Agg canvas; units mm, N, MPa).

matplotlib is imported inside this package only, so ``import twoscale`` stays light.

Two kinds of function:

* ``plot_*`` draw one panel and return the matplotlib ``Figure``; each takes ``ax=`` (an
  Axes of your own, e.g. in a notebook) or makes a new Figure:
  :func:`plot_pressure_map`, :func:`plot_forces`, :func:`plot_tip_values`,
  :func:`plot_parity`;
* the file writers compose them into the PNG files the command line writes, and return
  the Path: :func:`pressure_map`, :func:`force_bars`, :func:`compare_forces`,
  :func:`compare_maps`, :func:`difference_map`. Every PNG carries the program version in
  a footer and in its metadata (``Software``), its title in ``Title``, and the scene
  (when given) as JSON in ``Description``; files are written atomically.

Every function takes what the figure says about itself as a :class:`Caption` (title, scene
record, scene name, PNG metadata; the ``plot_*`` of one panel take a ``title``) and how it is
drawn as a :class:`FigureStyle` (size, dpi, colour map, colour bar and scale, panel size).

Tips are numbered from 1 (scene order, as in every table and CSV file). Figures stay
readable from one tip to thousands: up to ``FEW_TIPS`` (30) tips are numbered and get one
bar each; with more, the ten most loaded are numbered, and histograms and maps of tips
coloured by a value replace the bars. Only loaded tips get a marker. Pressure colour
scales end at the 99th percentile of the loaded cells when a single peak would flatten
them (:func:`~twoscale.plot.scale.robust_scale`); the peak is given in the title and on
the colour bar. Titles name the scene and the body (:func:`scene_text`).
"""

from .difference import difference_map
from .forces import compare_forces, force_bars, plot_forces, plot_parity, plot_tip_values
from .labels import body_text, scene_text
from .maps import compare_maps, plot_pressure_map, pressure_map
from .scale import ColourScale, robust_scale
from .style import Caption, FigureStyle

__all__ = [
    "plot_pressure_map",
    "plot_forces",
    "plot_tip_values",
    "plot_parity",
    "pressure_map",
    "force_bars",
    "compare_forces",
    "compare_maps",
    "difference_map",
    "body_text",
    "scene_text",
    "Caption",
    "ColourScale",
    "FigureStyle",
    "robust_scale",
]
