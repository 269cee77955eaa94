"""Sphinx configuration of the casep documentation.

Build (offline, warnings as errors): ``sphinx-build -W --keep-going -b html docs docs/_build/html``
after ``pip install -e ".[docs]"``. Nothing is fetched at build time: no intersphinx, no
remote images, the theme's assets are in the package.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
# Figures are drawn off screen if any docstring example imports matplotlib.
os.environ.setdefault("MPLBACKEND", "Agg")

import casep  # noqa: E402

project = "casep"
author = "the casep developers"
copyright = "the casep developers"
version = casep.__version__
release = casep.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
    "sphinxarg.ext",
    "casep_api",  # docs/_ext/casep_api.py: one API page per public module, from its __all__
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "**/.ipynb_checkpoints"]
templates_path = ["_templates"]

# MyST: ::: fences, definition lists; headings get anchors for cross-page links. Equations are
# written as code (as in the docstrings), so the pages need no MathJax from a CDN to read offline.
myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3

# API reference: stubs generated from the docstrings on every build (reference/api/generated/).
autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "none"  # the numpydoc Parameters sections carry the types
numpydoc_show_class_members = False  # members are listed by the autosummary class template
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

html_theme = "pydata_sphinx_theme"
html_title = f"casep {release}"
html_static_path: list[str] = []
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "navbar_align": "left",
    "footer_start": ["copyright"],
    "footer_end": [],
}
html_sidebars = {"index": []}
html_last_updated_fmt = None
