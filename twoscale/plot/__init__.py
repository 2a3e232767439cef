"""Figures of contact results (PNG through matplotlib's Agg canvas; units mm, N, MPa).

matplotlib is imported inside this package only, so ``import twoscale`` stays light.
Every figure carries the program version in a footer and in the PNG metadata
(``Software``), its title in ``Title``, and the scene (when given) as JSON in
``Description``. Files are written atomically (temporary file, then rename).

* :func:`pressure_map`: one result's pressure with the tip positions;
* :func:`force_bars`: force per asperity (beside macro-step forces when given);
* :func:`compare_forces`: forces per asperity of several results side by side (the
  paper's Figs. 10-11);
* :func:`compare_maps`: pressure maps of several results side by side, one colour scale.
"""
from .forces import compare_forces, force_bars
from .maps import compare_maps, pressure_map

__all__ = ["pressure_map", "force_bars", "compare_forces", "compare_maps"]
