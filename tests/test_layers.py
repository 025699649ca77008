"""The layers of dfwb import one way only, and no two modules import each other.

Every import statement counts, at module level or inside a function: a lazy
import is still a dependency. The order, lowest first:

    fmus, build_fmus < base < plants < fmi < engine < plotting < studies < verify < api < cli < dfwb
"""

import ast
import itertools
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("fmus", "build_fmus", "base", "plants", "fmi", "engine", "foreign", "plotting", "studies", "verify", "api", "cli",
          "dfwb")
RANK = {"fmus": 0, "build_fmus": 0, **{layer: rank for rank, layer in enumerate(LAYERS[1:], start=1)}}
FOLDERS = {"fmus": ROOT / "fmus", "build_fmus": ROOT / "build_fmus"}


def modules():
    """{module name: file} of every dfwb module."""
    found = {}
    for path in (ROOT / "analysis").rglob("*.py"):
        parts = path.relative_to(ROOT / "analysis").with_suffix("").parts
        parts = parts[:-1] if parts[-1] == "__init__" else parts
        found[".".join(("dfwb",) + parts)] = path
    for package, folder in FOLDERS.items():
        for path in folder.glob("*.py"):
            stem = path.stem
            found[f"dfwb.{package}" + ("" if stem == "__init__" else f".{stem}")] = path
    return found


def layer(module):
    """The layer of a dfwb module name."""
    parts = module.split(".")
    if len(parts) == 1:
        return "dfwb"
    return parts[1] if parts[1] in RANK else "dfwb"


def imports(path, module, known):
    """The dfwb modules a file imports (absolute and relative, anywhere in the file)."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            names = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base for alias in node.names]
        else:
            continue
        found.update(name for name in names if name.split(".")[0] == "dfwb" and name != module)
    return found


GRAPH = {module: imports(path, module, modules()) for module, path in modules().items()}


def test_every_module_belongs_to_a_layer():
    assert {layer(module) for module in GRAPH} <= set(LAYERS)
    assert {"dfwb.plants.registry", "dfwb.engine.describing", "dfwb.studies.runner", "dfwb.cli"} <= set(GRAPH)


@pytest.mark.parametrize("module", sorted(GRAPH))
def test_imports_go_down_the_layers(module):
    upward = sorted(target for target in GRAPH[module] if RANK[layer(target)] > RANK[layer(module)])
    assert not upward, f"{module} ({layer(module)}) imports from higher layers: {upward}"


def test_no_import_cycles():
    """No module reaches itself through the modules it imports."""

    def reach(start):
        seen, todo = set(), [start]
        while todo:
            for target in GRAPH.get(todo.pop(), ()):
                if target not in seen:
                    seen.add(target)
                    todo.append(target)
        return seen

    cycles = [module for module in GRAPH if module in reach(module)]
    assert not cycles, f"modules that import themselves through others: {cycles}"


def test_the_checker_sees_an_upward_import(tmp_path):
    """The test can fail: a plants module importing the engine is reported."""
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from dfwb.engine.describing import DFEngine\n")
    found = imports(bad, "dfwb.plants.bad", modules())
    assert "dfwb.engine.describing" in found and RANK[layer("dfwb.engine.describing")] > RANK["plants"]
    assert list(itertools.islice(GRAPH, 1))  # the graph is not empty
