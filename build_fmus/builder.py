"""Build the plant FMUs: pythonfmu, then a pass that makes them FMI 2.0 clean.

What goes into an FMU
---------------------
An FMU bundles the module that defines its facade class and the modules
that one needs, no more: :func:`sources` follows the imports inside the
solver package (``from .x import y`` and ``from dfwb.fmus.x import y``)
from the facade's module, read with :mod:`ast`, and always adds
:mod:`~dfwb.fmus.facade` (the base classes and ``pin``). The production
facades (:mod:`dfwb.fmus.facade`) thus bundle the three exact solvers and
the linear system, never :mod:`dfwb.fmus.naive`; the benchmark's twins
(:mod:`dfwb.fmus.naive_facade`) bundle those and the naive solvers.

Each FMU's hash, :func:`source_hash`, covers exactly what it bundles (file
names and contents), pythonfmu's version and :data:`BUILDER_REVISION`:
editing a module outside an FMU's closure neither changes its hash nor
rebuilds it. An FMU whose recorded hash matches is not rebuilt.

A plant defined outside dfwb
----------------------------
A facade class may live in any single-file module (a plugin, a test: see
``docs/plants/adding-a-plant.md``). That module is bundled into the package next
to the solver modules, and its imports of the solver package are rewritten
to relative ones: ``from dfwb.fmus.exact import Motion`` becomes ``from
.exact import Motion``, ``from dfwb.fmus import PlantError`` becomes
``from .exact import PlantError`` (the module that defines the name), line
numbers unchanged. An FMU runs without dfwb, so the module may import other
parts of dfwb (the registry, to make its entry) only inside functions, which
the FMU never calls; ``import dfwb.fmus...``, relative imports and other
dfwb imports at module level are refused with :class:`BuildError`.

Two FMUs in one process must never share Python code by accident
(pythonfmu imports each FMU's script and bundled modules by name, and the
first module of a name wins). So every build bundles its modules as a
package whose name carries the hash, ``dfwb_fmus_<hash>``, next to a
one-line script ``<Model>_<hash>.py``: FMUs of the same sources share
identical code, FMUs of different sources cannot collide.

pythonfmu writes no units, no ModelStructure/InitialUnknowns and a random
GUID; :func:`finish_model_description` adds the first two (so that ``fmpy
validate`` passes) and makes the GUID a function of the model and the hash.

The compiled core
-----------------
A facade with ``native_solver`` (the three plants and their closed loops
of :mod:`dfwb.fmus.loop_facade`, not the naive twins nor LinearSystem) gets
the C core (``fmus/native``, compiled by
:func:`dfwb.build_fmus.core.build_core`) as ``resources/libdfwb_core.so``,
which its Python code loads (see :mod:`dfwb.fmus.facade`); the C sources
are then part of its hash. The core is compiled at most once per process
(kept in memory, like the FMI shim), only when such an FMU is built. If it
cannot be compiled, :func:`build` reports one line and builds the FMU
without it: it then runs on the pure-Python solver.
"""

import ast
import functools
import hashlib
import importlib
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import uuid
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pythonfmu
from pythonfmu.builder import FmuBuilder

from dfwb.fmus import facade

from .core import WIN64_CC, win64_compiler
from .errors import BuildError
from .recorded import HASH_PREFIX, recorded_hash

__all__ = ["build", "build_all", "source_hash", "sources", "recorded_hash", "BuildError"]

FMUS_DIR = Path(facade.__file__).resolve().parent
PACKAGE = "dfwb.fmus"
BUILDER_REVISION = "5"  # 5: the compiled core in the plant FMUs' resources (4: the FMI shim is binaries/linux64)
INIT = '"""dfwb solver modules bundled into one FMU (only those its facade needs)."""\n'
SCRIPT = '''"""dfwb {model} FMU: the facade from the bundled, hash-named solver package."""
from {package}.{module} import {model}
from {package}.facade import pin

pin(globals())  # pythonfmu 0.7.0 releases this namespace once per instantiation
'''


# SI base-unit exponents of every unit the models use
BASE_UNITS = {
    "N": {"kg": 1, "m": 1, "s": -2},
    "kg": {"kg": 1},
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "N.s/m": {"kg": 1, "s": -1},
    "N/m": {"kg": 1, "s": -2},
    "rad/s": {"rad": 1, "s": -1},
    "rad": {"rad": 1},
    "m.s": {"m": 1, "s": 1},
    "s": {"s": 1},
}


def _imports(tree):
    """[(import node, whether it sits inside a function body)] (an import there runs only when it is called)."""
    found, todo = [], [(tree, False)]
    while todo:
        node, lazy = todo.pop()
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            found.append((node, lazy))
            continue
        inner = lazy or isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
        # an expression holds no statement, so no import: skipped (the walk stays linear and short)
        todo.extend((child, inner) for child in ast.iter_child_nodes(node) if not isinstance(child, ast.expr))
    return sorted(found, key=lambda item: (item[0].lineno, item[0].col_offset))


def _is_module(name):
    return (FMUS_DIR / f"{name}.py").is_file() and name != "__init__"


def _import_lines(names, where):
    """``from dfwb.fmus import a, b as c`` -> relative statements, each name from its defining module."""
    package = importlib.import_module(PACKAGE)
    statements = []
    for alias in names:
        bound = f" as {alias.asname}" if alias.asname else ""
        if _is_module(alias.name):
            statements.append(f"from . import {alias.name}{bound}")
            continue
        home = getattr(getattr(package, alias.name, None), "__module__", "") or ""
        if not home.startswith(PACKAGE + ".") or not _is_module(home[len(PACKAGE) + 1:]):
            raise BuildError(f"{where}: cannot bundle 'from {PACKAGE} import {alias.name}': "
                             f"import it from the module that defines it")
        statements.append(f"from .{home[len(PACKAGE) + 1:]} import {alias.name}{bound}")
    return statements


@functools.lru_cache(maxsize=256)
def _dependencies(text, where, external, modules):
    """(names of the solver modules a module imports, its text with dfwb.fmus imports made relative).

    ``modules``: the solver package's module names now (a key of the cache, which
    saves parsing the same text again at each ``fmu_path``).
    """
    found, edits = set(), []
    for node, lazy in _imports(ast.parse(text, where)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "dfwb" and (alias.name.startswith(PACKAGE) or not lazy):
                    raise BuildError(f"{where}:{node.lineno}: 'import {alias.name}' cannot be bundled into an FMU "
                                     f"(write 'from {PACKAGE}.<module> import <name>'; other dfwb imports only "
                                     f"inside functions)")
        elif isinstance(node, ast.ImportFrom) and node.level:
            if node.level != 1 or external:
                raise BuildError(f"{where}:{node.lineno}: a relative import cannot be bundled into an FMU "
                                 f"(only this module and {PACKAGE} are)")
            targets = [node.module.split(".")[0]] if node.module else [alias.name for alias in node.names]
            missing = [target for target in targets if not _is_module(target)]
            if missing:
                raise BuildError(f"{where}:{node.lineno}: {missing} are not modules of {PACKAGE}")
            found.update(targets)
        elif isinstance(node, ast.ImportFrom) and node.module.split(".")[0] == "dfwb":
            if node.module == PACKAGE:
                statements = _import_lines(node.names, f"{where}:{node.lineno}")
            elif node.module.startswith(PACKAGE + ".") and _is_module(node.module[len(PACKAGE) + 1:]):
                names = ", ".join(alias.name + (f" as {alias.asname}" if alias.asname else "") for alias in node.names)
                statements = [f"from .{node.module[len(PACKAGE) + 1:]} import {names}"]
            elif lazy:
                continue  # another layer of dfwb, imported only when a function runs (never inside the FMU)
            else:
                raise BuildError(f"{where}:{node.lineno}: 'from {node.module} import ...' at module level cannot be "
                                 f"bundled into an FMU (an FMU runs without dfwb): import it inside a function")
            for statement in statements:  # "from .x import y" or "from . import x [as y]"
                words = statement.split()
                found.add(words[1][1:] or words[3])
            edits.append((node, statements))
    return frozenset(found), _rewrite(text, edits, where)


def _rewrite(text, edits, where):
    """Replace each import statement by its relative statements on the same lines (line numbers kept)."""
    if not edits:
        return text
    lines = text.splitlines(keepends=True)
    for node, statements in sorted(edits, key=lambda edit: edit[0].lineno, reverse=True):
        first, last = lines[node.lineno - 1], lines[node.end_lineno - 1]
        before, after = first[:node.col_offset], last[node.end_col_offset:]
        if before.strip() or after.strip() and not after.strip().startswith("#"):
            raise BuildError(f"{where}:{node.lineno}: put the import of {PACKAGE} on lines of its own")
        replaced = before + "; ".join(statements) + after
        lines[node.lineno - 1:node.end_lineno] = [replaced] + ["\n"] * (node.end_lineno - node.lineno)
    return "".join(lines)


def _facade_module(model):
    """(the bundled module name of the facade class, its text, whether it lives outside dfwb.fmus)."""
    name = model.__module__
    if name.startswith(PACKAGE + ".") and _is_module(name[len(PACKAGE) + 1:]):
        stem = name[len(PACKAGE) + 1:]
        return stem, (FMUS_DIR / f"{stem}.py").read_text(), False
    path = Path(getattr(sys.modules.get(name), "__file__", None) or "")
    if path.suffix != ".py" or path.stem == "__init__":
        raise BuildError(f"{model.__name__}: its module {name!r} is not a single .py file, which the builder bundles")
    if _is_module(path.stem):
        raise BuildError(f"{model.__name__}: its module's name {path.stem!r} is a module of {PACKAGE} already")
    return path.stem, path.read_text(), True


def sources(model):
    """{file name: bytes} bundled into the FMU of facade class ``model`` (its module's closure).

    The facade's module, every solver module reached from it through imports
    of the solver package, :mod:`~dfwb.fmus.facade`, and the package's
    ``__init__.py`` (a docstring: nothing is imported that the closure
    does not name). A module outside dfwb.fmus has its imports rewritten
    (see the module's docstring).
    """
    stem, text, external = _facade_module(model)
    where = f"{model.__module__} ({stem}.py)"
    modules = frozenset(path.stem for path in FMUS_DIR.glob("*.py"))
    found, text = _dependencies(text, where, external, modules)
    files = {f"{stem}.py": text.encode()}
    todo = sorted(found | {"facade"})
    while todo:
        name = todo.pop()
        if f"{name}.py" in files:
            continue
        more, content = _dependencies((FMUS_DIR / f"{name}.py").read_text(), f"{PACKAGE}.{name}", False, modules)
        files[f"{name}.py"] = content.encode()
        todo.extend(sorted(more))
    files["__init__.py"] = INIT.encode()
    return dict(sorted(files.items()))


def native(model):
    """Whether the FMU of ``model`` carries the compiled core (its facade names a ``native_solver``)."""
    return bool(getattr(model, "native_solver", None))


def core_sources():
    """{name: bytes} of the C core's sources and headers (empty if the package has none)."""
    from .core import CoreBuildError
    from .core import sources as native_sources

    try:
        return native_sources()
    except CoreBuildError:
        return {}


def source_hash(model):
    """Hash of everything that goes into the FMU of ``model``: its sources (the C core's too, for a facade
    with ``native_solver``), the shim, pythonfmu, this builder."""
    digest = hashlib.sha256()
    for name, content in sources(model).items():
        digest.update(name.encode() + b"\0" + content + b"\0")
    if native(model):
        for name, content in core_sources().items():
            digest.update(b"native/" + name.encode() + b"\0" + content + b"\0")
    digest.update(SHIM_SOURCE.read_bytes() + b"\0" + "+".join(shim_platforms()).encode() + b"\0")
    digest.update(pythonfmu.__version__.encode() + BUILDER_REVISION.encode())
    return digest.hexdigest()[:16]


def finish_model_description(xml_bytes, model, digest):
    """Units, UnitDefinitions, min/max, the FMU-state flags, ModelStructure and a deterministic GUID."""
    root = ET.fromstring(xml_bytes)
    root.set("guid", "{%s}" % uuid.uuid5(uuid.NAMESPACE_URL, f"dfwb/{model.__name__}/{digest}"))
    root.set("version", HASH_PREFIX + digest)
    units = model.units()
    variables = root.find("ModelVariables")
    for scalar in variables:
        real = scalar.find("Real")
        unit = units.get(scalar.get("name"))
        if real is not None and unit:
            real.set("unit", unit)
    used = sorted(set(units.values()))
    unknown = [name for name in used if name not in BASE_UNITS]
    if unknown:
        raise BuildError(f"{model.__name__}: units {unknown} are not in the builder's BASE_UNITS")
    definitions = ET.Element("UnitDefinitions")
    for name in used:
        unit = ET.SubElement(definitions, "Unit", name=name)
        ET.SubElement(unit, "BaseUnit", {k: str(v) for k, v in BASE_UNITS[name].items()})
    if used:  # the schema wants at least one Unit in a UnitDefinitions
        position = list(root).index(root.find("CoSimulation")) + 1
        root.insert(position, definitions)
    _set_limits(variables, model)
    cosimulation = root.find("CoSimulation")
    cosimulation.set("canGetAndSetFMUstate", "true")  # the facades copy their solver exactly (dfwb.fmus.state)
    cosimulation.set("canSerializeFMUstate", "true")
    _set_structure(root.find("ModelStructure"), variables, model)
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


SHIM_SOURCE = Path(__file__).resolve().parent / "shim" / "fmi2_shim.c"
SHIM_SUFFIX = {"linux64": ".so", "win64": ".dll"}  # pythonfmu's own binary goes next to the shim, as
INNER_NAME = ".pythonfmu"  # binaries/<platform>/<Model>.pythonfmu<suffix>
PYTHON_RECORD = "resources/dfwb_python.txt"  # the libpython the shim loads first in a host without Python


def _compiler():
    """The C compiler for the shim: $CC, else cc, gcc or clang on PATH (BuildError if none)."""
    for name in ([os.environ["CC"]] if os.environ.get("CC") else []) + ["cc", "gcc", "clang"]:
        found = shutil.which(name.split()[0])
        if found:
            return [found] + name.split()[1:]
    raise BuildError("building the FMUs needs a C compiler for the FMI shim (build_fmus/shim/fmi2_shim.c): "
                     "no $CC, cc, gcc or clang on PATH")


def shim_platforms():
    """The platforms whose binary is dfwb's shim: linux64, and win64 where mingw-w64 is installed (without it,
    binaries/win64 keeps pythonfmu's own DLL, untested)."""
    return ["linux64"] + (["win64"] if win64_compiler() else [])


@functools.lru_cache(maxsize=8)
def _shim_binary(source_digest, platform):
    """The compiled shim (bytes) for ``platform``, compiled once per process for each shim source."""
    import fmpy

    headers = Path(fmpy.__file__).resolve().parent / "c-code"  # fmi2Functions.h & co. (FMI 2.0)
    if not (headers / "fmi2Functions.h").is_file():
        raise BuildError(f"building the FMUs needs the FMI 2.0 headers of fmpy: no fmi2Functions.h in {headers}")
    with tempfile.TemporaryDirectory(prefix="dfwb_shim_") as tmp:
        binary = Path(tmp) / f"shim{SHIM_SUFFIX[platform]}"
        if platform == "win64":  # C99's printf (%zu), libgcc linked in: the DLL needs only KERNEL32 and msvcrt
            command = [win64_compiler() or WIN64_CC, "-std=gnu99", "-shared", "-O2", "-static-libgcc", "-s",
                       "-D__USE_MINGW_ANSI_STDIO=1", f"-I{headers}", "-o", str(binary), str(SHIM_SOURCE)]
        else:
            command = _compiler() + ["-std=gnu99", "-shared", "-fPIC", "-O2", "-fvisibility=hidden",
                                     f"-I{headers}", "-o", str(binary), str(SHIM_SOURCE), "-ldl", "-lpthread"]
        run = subprocess.run(command, capture_output=True, text=True)
        if run.returncode != 0:
            raise BuildError(f"compiling the FMI shim failed ({' '.join(command)}):\n{run.stderr.strip()}")
        return binary.read_bytes()


def shim_binary(platform="linux64"):
    """The shim for binaries/<platform> (see build_fmus/shim/fmi2_shim.c), cached by the hash of its source."""
    return _shim_binary(hashlib.sha256(SHIM_SOURCE.read_bytes()).hexdigest(), platform)


CORE_RESOURCE = "resources/libdfwb_core.so"  # what dfwb.fmus.facade.core_in opens


@functools.lru_cache(maxsize=4)
def _core_binary(key):
    """(the compiled core's bytes, None) or (None, why it cannot be built), once per process for each key."""
    from .core import CoreBuildError, build_core

    with tempfile.TemporaryDirectory(prefix="dfwb_core_") as tmp:
        try:
            return build_core(tmp).read_bytes(), None
        except (CoreBuildError, OSError) as error:
            return None, str(error)


def core_binary():
    """(bytes of the C core for ``resources/libdfwb_core.so``, None), or (None, the one-line reason it cannot be
    built); compiled at most once per process for the same sources and $CC."""
    digest = hashlib.sha256()
    for name, content in core_sources().items():
        digest.update(name.encode() + b"\0" + content + b"\0")
    return _core_binary((digest.hexdigest(), os.environ.get("CC", "")))


def python_record():
    """resources/dfwb_python.txt: the shared libpython of the Python that builds (empty line if static)."""
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    for key in ("INSTSONAME", "LDLIBRARY"):
        name = sysconfig.get_config_var(key) or ""
        if ".so" in name and Path(libdir, name).is_file():
            return f"{Path(libdir, name)}\n"
    return "\n"


def _shimmed(item, data, target, platform):
    """Write pythonfmu's binary as <Model>.pythonfmu.so (.dll) and the shim as <Model>.so (.dll)."""
    suffix = SHIM_SUFFIX[platform]
    moved = zipfile.ZipInfo(item.filename[:-len(suffix)] + INNER_NAME + suffix, item.date_time)
    moved.compress_type, moved.external_attr = item.compress_type, item.external_attr
    target.writestr(moved, data)
    target.writestr(item, shim_binary(platform))


def _shim_platform(name, platforms):
    """The platform of binaries/<platform>/<Model>.<suffix> if dfwb's shim replaces it, else None."""
    for platform in platforms:
        if name.startswith(f"binaries/{platform}/") and name.endswith(SHIM_SUFFIX[platform]) \
                and name.count("/") == 2:
            return platform
    return None


def _limit_text(value, kind):
    return str(int(value)) if kind == "Integer" else repr(float(value))


def _set_limits(variables, model):
    """``min``/``max`` of every variable the facade declares a range for (``model.limits()``)."""
    limits = model.limits()
    names = {scalar.get("name") for scalar in variables}
    unknown = sorted(set(limits) - names)
    if unknown:
        raise BuildError(f"{model.__name__}: ranges declared for {unknown}, which are not variables")
    for scalar in variables:
        bounds = limits.get(scalar.get("name"))
        if bounds is None:
            continue
        element = scalar[0]  # <Real> or <Integer>
        for attribute, value in zip(("min", "max"), bounds):
            if value is not None:
                element.set(attribute, _limit_text(value, element.tag))


def _set_structure(structure, variables, model):
    """Outputs with their dependencies on the input, and InitialUnknowns.

    An output that the input does not feed directly (a continuous state such
    as x, v, gap, y, or a counter; every output of an FMU without input,
    ``input_name`` None) has ``dependencies=""``; one the facade
    names in ``feedthrough`` lists the input's index with that
    dependenciesKind. InitialUnknowns lists the same outputs without a
    dependency list (at initialisation they depend on the parameters and the
    input: all the knowns).
    """
    for child in list(structure):
        structure.remove(child)
    index = {scalar.get("name"): i for i, scalar in enumerate(variables, start=1)}
    feedthrough = model.feedthrough
    unknown = sorted(set(feedthrough) - set(index))
    if unknown or (model.input_name is not None and model.input_name not in index) \
            or (feedthrough and model.input_name is None):
        raise BuildError(f"{model.__name__}: feedthrough names {unknown} or input {model.input_name!r} unknown")
    outputs = [scalar.get("name") for scalar in variables if scalar.get("causality") == "output"]
    node = ET.SubElement(structure, "Outputs")
    for name in outputs:
        attributes = {"index": str(index[name]), "dependencies": ""}
        if name in feedthrough:
            attributes.update(dependencies=str(index[model.input_name]), dependenciesKind=feedthrough[name])
        ET.SubElement(node, "Unknown", attributes)
    node = ET.SubElement(structure, "InitialUnknowns")
    for name in outputs:
        ET.SubElement(node, "Unknown", index=str(index[name]))


def build_one(model, out_dir, digest=None, core=None):
    """Build ``<out_dir>/<Model>.fmu`` from the current sources (atomic replace).

    ``core``: the bytes of the compiled core (:func:`core_binary`), written as
    ``resources/libdfwb_core.so`` for a facade with ``native_solver``; None: the
    FMU has no core and runs on the pure-Python solver.
    """
    files = sources(model)
    digest = digest or source_hash(model)
    package = f"dfwb_fmus_{digest}"
    module = _facade_module(model)[0]
    dest = Path(out_dir) / f"{model.__name__}.fmu"
    with tempfile.TemporaryDirectory(prefix="dfwb_build_") as tmp:
        tmp = Path(tmp)
        stage = tmp / package
        stage.mkdir()
        for name, content in files.items():
            (stage / name).write_bytes(content)
        script = tmp / f"{model.__name__}_{digest}.py"
        script.write_text(SCRIPT.format(model=model.__name__, package=package, module=module))
        raw = FmuBuilder.build_FMU(script, dest=tmp / "raw", project_files=[stage])
        partial = dest.with_name(f".{dest.name}.{os.getpid()}.partial")  # concurrent builds never mix
        platforms = shim_platforms()
        with zipfile.ZipFile(raw) as source, zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as target:
            for item in source.infolist():
                data = source.read(item.filename)
                if item.filename == "modelDescription.xml":
                    data = finish_model_description(data, model, digest)
                platform = _shim_platform(item.filename, platforms)
                if platform:
                    _shimmed(item, data, target, platform)
                    continue
                target.writestr(item, data)
            record = zipfile.ZipInfo(PYTHON_RECORD, source.getinfo("modelDescription.xml").date_time)
            record.compress_type = zipfile.ZIP_DEFLATED
            target.writestr(record, python_record())
            # documentation/, not sources/: fmpy would list a "c-code" platform for sources/ (the shim alone is no FMU)
            shim_source = zipfile.ZipInfo("documentation/fmi2_shim.c", record.date_time)
            shim_source.compress_type = zipfile.ZIP_DEFLATED
            target.writestr(shim_source, SHIM_SOURCE.read_bytes())
            if core is not None and native(model):
                library = zipfile.ZipInfo(CORE_RESOURCE, record.date_time)
                library.compress_type, library.external_attr = zipfile.ZIP_DEFLATED, 0o100755 << 16
                target.writestr(library, core)
        partial.replace(dest)
    return dest


def build(out_dir, models=None, force=False, report=print):
    """Build the FMUs of the facade classes ``models`` that are missing or stale; return their paths.

    Parameters
    ----------
    out_dir : str or Path
        The folder of the FMUs (created if needed); ``<Model>.fmu`` each.
    models : sequence of facade classes, optional
        By default the production FMUs, :data:`dfwb.fmus.facade.PRODUCTION`
        (the three plants and LinearSystem). ``dfwb.fmi.location.models()``
        lists the registry's plants (and, when asked, their naive twins).
    force : bool
        Rebuild even an FMU whose recorded hash matches its sources.
    report : callable
        Called with one line per FMU (``built`` or ``up to date``), and one line if
        the compiled core cannot be built (those FMUs then run on the pure-Python solver).
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    compiled = []  # [(core bytes or None, reason)]: the core, compiled once per call when an FMU needs it
    for model in facade.PRODUCTION if models is None else models:
        path = out_dir / f"{model.__name__}.fmu"
        digest = source_hash(model)
        if not force and recorded_hash(path) == digest:
            report(f"{path}: up to date")
        else:
            if native(model) and not compiled:
                compiled.append(core_binary())
                if compiled[0][0] is None:
                    report(f"the C core cannot be built ({compiled[0][1]}): the plant and loop FMUs built now run "
                           f"on the pure-Python solver")
            build_one(model, out_dir, digest, compiled[0][0] if native(model) else None)
            report(f"{path}: built")
        paths.append(path)
    return paths


def build_all(out_dir, force=False, report=print):
    """Build every FMU of dfwb, the benchmark's naive twins included (see :func:`build`)."""
    from dfwb.fmus.naive_facade import NAIVE

    return build(out_dir, facade.PRODUCTION + NAIVE, force, report)
