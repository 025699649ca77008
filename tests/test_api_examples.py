"""Issue 24: every public name of dfwb has a tested example in its docstring and an entry in the API reference.

A public name is one of ``dfwb.__all__``; ``__version__`` is a string, with neither docstring nor entry of its
own (the reference shows it in its title). The examples run as doctests: pytest's ``--doctest-modules``
collects those of the modules under its testpaths, and :func:`test_examples_outside_the_doctest_paths_run`
runs the others (``DfwbError`` and ``PlantError`` are defined in ``dfwb.fmus.exact``, bundled into the FMUs
and not a testpath; ``dfwb.base.errors`` documents them).
"""

import doctest
import inspect
import re
import sys
from pathlib import Path

import pytest

import dfwb

ROOT = Path(__file__).resolve().parents[1]
API = ROOT / "docs" / "reference" / "api.rst"
DOCTEST_PATHS = ("analysis", "build_fmus")  # pyproject's testpaths whose modules --doctest-modules reads
PUBLIC = [name for name in dfwb.__all__ if name != "__version__"]
# Public names known to lack what a test asks for, with the reason: expected failures, strict, so that the test
# fails (and the entry must go) once the gap is closed.
EXAMPLE_GAPS = {}  # name: why it has no Examples section yet (a strict xfail: it fails once fixed)
REFERENCE_GAPS = {}  # name: why docs/reference/api.rst does not list it yet


def _names(gaps):
    return [pytest.param(name, marks=pytest.mark.xfail(reason=gaps[name], strict=True)) if name in gaps else name
            for name in PUBLIC]


def examples(doc):
    """The text of a numpydoc docstring's Examples section ("" when it has none)."""
    match = re.search(r"^Examples\n-{8,}\n(.*?)(?=^\S[^\n]*\n-{3,}\n|\Z)", doc or "", re.MULTILINE | re.DOTALL)
    return match.group(1) if match else ""


@pytest.mark.parametrize("name", _names(EXAMPLE_GAPS))
def test_every_public_name_has_an_examples_section_with_a_doctest(name):
    doc = inspect.getdoc(getattr(dfwb, name))
    assert doc, f"dfwb.{name} has no docstring"
    section = examples(doc)
    assert section, f"dfwb.{name}: its docstring has no numpydoc Examples section (Examples, then a line of dashes)"
    assert re.search(r"^\s*>>> ", section, re.MULTILINE), f"dfwb.{name}: its Examples section has no >>> line"


def test_the_examples_section_is_found_as_numpydoc_writes_it():
    assert examples("Summary.\n\nExamples\n--------\n>>> 1 + 1\n2\n") == ">>> 1 + 1\n2\n"
    assert examples("Summary.\n\nExamples\n--------\nText.\n\nNotes\n-----\n>>> 1\n") == "Text.\n\n"
    assert examples("Summary.\n\n>>> 1 + 1\n2\n") == ""  # an example without the heading is no section


def _outside_doctest_paths():
    """The public names whose docstrings --doctest-modules does not read: their defining module's file is not
    under a doctest path."""
    outside = []
    for name in PUBLIC:
        obj = getattr(dfwb, name)
        module = obj if inspect.ismodule(obj) else sys.modules[obj.__module__]
        path = Path(module.__file__).resolve()
        if not any(path.is_relative_to(ROOT / folder) for folder in DOCTEST_PATHS):
            outside.append(name)
    return outside


def test_the_error_classes_defined_with_the_solvers_are_among_those_run_here():
    assert {"DfwbError", "PlantError"} <= set(_outside_doctest_paths())


@pytest.mark.parametrize("name", _outside_doctest_paths())
def test_examples_outside_the_doctest_paths_run(name):
    tests = doctest.DocTestFinder(recurse=False).find(getattr(dfwb, name), f"dfwb.{name}", module=False, globs={})
    assert tests and any(test.examples for test in tests), f"dfwb.{name}: no examples found"
    report = []
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    for test in tests:
        runner.run(test, out=report.append)
    assert runner.failures == 0, "".join(report)


def reference_entries(text):
    """The names an API page's ``autosummary`` blocks list, and those of its ``auto*`` directives."""
    names = re.findall(r"^\.\. auto(?:function|class|data|module|exception)::\s*(\S+)", text, re.MULTILINE)
    for block in re.findall(r"^\.\. autosummary::[^\n]*\n((?:[ \t]+[^\n]*\n|\n)*)", text, re.MULTILINE):
        names += [line.strip() for line in block.splitlines() if line.strip() and not line.strip().startswith(":")]
    return names


def test_the_reference_documents_the_dfwb_namespace():
    text = API.read_text()
    assert re.search(r"^\.\. currentmodule:: dfwb\s*$", text, re.MULTILINE), "api.rst must list names of dfwb"
    assert re.search(r"^\.\. autosummary::\n(?:\s+:[^\n]*\n)*?\s+:toctree:", text, re.MULTILINE), \
        "api.rst's autosummary must generate a page per name (:toctree:)"


@pytest.mark.parametrize("name", _names(REFERENCE_GAPS))
def test_every_public_name_is_in_the_reference(name):
    assert name in reference_entries(API.read_text()), f"dfwb.{name} is not listed in {API.relative_to(ROOT)}"


def test_the_reference_lists_only_public_names_once():
    entries = [name for name in reference_entries(API.read_text()) if name != "dfwb"]  # the automodule itself
    assert sorted(set(entries) - set(dfwb.__all__)) == [], "api.rst lists names that are not in dfwb.__all__"
    assert len(entries) == len(set(entries)), "api.rst lists a name twice"
