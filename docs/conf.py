"""Sphinx configuration of dfwb's documentation site (``make docs``: docs/_build/html/index.html).

Why these extensions: the scientific Python stack's own (NumPy, SciPy, python-control): numpydoc reads the
docstrings, which are numpydoc; myst-parser keeps the pages in Markdown, readable on a forge as they are;
myst-nb executes the example notebooks at build time, so their figures are current and their code is checked;
sphinx-argparse writes the command-line reference from the parser itself (one source, no copy to go stale).
"""

import json
import os
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

# The example notebooks (../examples) are copied in and executed, their outputs kept by jupyter-cache between
# builds: a notebook runs again when its code or dfwb's changes (_copy_examples puts dfwb's revision into it),
# and then its maps come from dfwb's own cache where dfwb's computing code is the same. `make docs-check` (CI)
# executes every notebook afresh (-D nb_execution_mode=force).
nb_execution_mode = "cache"
nb_execution_cache_path = str(Path(__file__).resolve().parent / "_build" / ".jupyter_cache")
nb_execution_timeout = 1200  # seconds per cell: a 12 x 12 hunting map from an empty cache on a slow 2-core machine
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


def _dfwb_revision():
    """A hash of dfwb's sources (Python and C, every subpackage): the notebooks' outputs are stale when it changes."""
    from dfwb.studies.cache import sources_digest

    return sources_digest([path for folder in (ROOT.parent / "analysis", ROOT.parent / "fmus")
                           for path in sorted(folder.rglob("*")) if path.suffix in (".py", ".c", ".h")], ROOT.parent)


def _copy_examples(app):
    """examples/*.ipynb into docs/examples/ (generated, ignored by git) for myst-nb to execute and render, each with
    a hidden first cell naming dfwb's revision and the DFWB_ settings (DFWB_HUNTING_N), so that jupyter-cache
    (which keys on the code cells) runs it again when either changes. A copy is rewritten only when it changes
    (Sphinx then reads only changed notebooks)."""
    target = ROOT / "examples"
    target.mkdir(exist_ok=True)
    settings = "".join(f", {name}={value}" for name, value in sorted(os.environ.items()) if name.startswith("DFWB_"))
    stamp = {"cell_type": "code", "execution_count": None, "id": "dfwb-revision", "outputs": [],
             "metadata": {"tags": ["remove-cell"]}, "source": f"# dfwb revision {_dfwb_revision()}{settings}"}
    for notebook in sorted(EXAMPLES.glob("*.ipynb")):
        content = json.loads(notebook.read_text())
        content["cells"].insert(0, stamp)
        text = json.dumps(content, indent=1) + "\n"
        copy = target / notebook.name
        if not copy.exists() or copy.read_text() != text:
            copy.write_text(text)


PLANTS_MARK = "<!-- plants: the table of the registered plants"


def _plants_table(app, docname, source):
    """The table of plants (guide/plant-fmus.md) from the registry, at build time: no copy to go stale."""
    if docname == "guide/plant-fmus" and PLANTS_MARK in source[0]:
        from dfwb.plants import markdown_table

        head, mark, tail = source[0].partition(PLANTS_MARK)
        comment, end, rest = tail.partition("-->")
        source[0] = f"{head}{mark}{comment}{end}\n\n{markdown_table()}\n{rest}"


def setup(app):
    app.connect("builder-inited", _copy_examples)
    app.connect("source-read", _plants_table)
