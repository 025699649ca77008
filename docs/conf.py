"""Sphinx configuration of dfwb's documentation site (``make docs``: docs/_build/html/index.html).

Why these extensions: the scientific Python stack's own (NumPy, SciPy, python-control): numpydoc reads the
docstrings, which are numpydoc; myst-parser keeps the pages in Markdown, readable on a forge as they are;
myst-nb executes the example notebooks at build time, so their figures are current and their code is checked;
sphinx-argparse writes the command-line reference from the parser itself (one source, no copy to go stale).
"""

import shutil
from pathlib import Path

import dfwb

project = "dfwb"
author = "dfwb developers"
release = version = dfwb.__version__
copyright = "2026, dfwb developers"

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_nb",
    "sphinxarg.ext",
    "sphinx_copybutton",
]

source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store"]
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3
suppress_warnings = ["myst.header"]  # guide pages moved from the README start at level 2 in places

# The example notebooks (../examples) are copied in and executed at every build: their outputs are never stale.
nb_execution_mode = "force"
nb_execution_timeout = 300
nb_execution_raise_on_error = True
nb_execution_show_tb = True

autosummary_generate = True
autodoc_typehints = "none"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False

html_theme = "pydata_sphinx_theme"
html_title = f"dfwb {release}"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2}
html_static_path = []

ROOT = Path(__file__).resolve().parent
EXAMPLES = ROOT.parent / "examples"


def _copy_examples(app):
    """examples/*.ipynb into docs/examples/ (generated, ignored by git) for myst-nb to execute and render."""
    target = ROOT / "examples"
    target.mkdir(exist_ok=True)
    for notebook in sorted(EXAMPLES.glob("*.ipynb")):
        shutil.copyfile(notebook, target / notebook.name)


def setup(app):
    app.connect("builder-inited", _copy_examples)
