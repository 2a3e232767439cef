"""Sphinx configuration of the twoscale documentation.

Build (from the repository root): ``python -m sphinx -W -b html docs docs/_build/html``.
The guides are Markdown (MyST), the API reference comes from the numpydoc docstrings
(autodoc + napoleon), and the examples in ``docs/examples`` run at build time
(sphinx-gallery) so their figures are the current tool's.
"""

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the source tree, also when twoscale is not installed
os.environ.setdefault("MPLBACKEND", "Agg")

from twoscale import __version__

project = "twoscale"
author = "the twoscale authors"
copyright = "the twoscale authors, MIT licence"
release = version = __version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx_gallery.gen_gallery",
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "gallery/make_gallery.py", "examples/README.txt"]
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]

# numpydoc docstrings, read by napoleon
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # the docstrings give types with units
autodoc_default_options = {"members": True}

sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib",),
}

html_theme = "alabaster"
html_title = f"twoscale {version}"
html_theme_options = {
    "description": "Multi-asperity contact on elastic bodies",
    "page_width": "1100px",
    "sidebar_width": "230px",
}
