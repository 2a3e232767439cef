"""Figures of contact results (PNG through matplotlib's Agg canvas; units mm, N, MPa).

matplotlib is imported inside this package only, so ``import twoscale`` stays light.
Every figure carries the program version in a footer and in the PNG metadata
(``Software``), its title in ``Title``, and the scene (when given) as JSON in
``Description``. Files are written atomically (temporary file, then rename).

Tips are numbered from 1 (scene order, as in every table and CSV file). Figures stay
readable from a few tips to thousands: up to ``FEW_TIPS`` (30) tips are numbered on the
maps and get one bar each; with more, histograms and maps of tips coloured by a value
replace the bars.

* :func:`pressure_map`: one result's pressure with the tip positions;
* :func:`force_bars`: force per asperity (beside macro-step forces when given), or the
  force histogram and a map of tips coloured by force;
* :func:`compare_forces`: forces per asperity of several results side by side (the
  paper's Figs. 10-11), or histograms and each body against the first;
* :func:`compare_maps`: pressure maps of several results side by side, one colour scale;
* :func:`difference_map`: per-tip force difference of each body against a reference.
"""
from .difference import difference_map
from .forces import compare_forces, force_bars
from .maps import compare_maps, pressure_map

__all__ = ["pressure_map", "force_bars", "compare_forces", "compare_maps", "difference_map"]
