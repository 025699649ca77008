"""Build the native FMUs: the plants on the C core with an FMI 2.0 wrapper, no Python inside.

``dfwb build --native`` writes FrictionMass.fmu, TwoMassBacklash.fmu and
StaticBacklash.fmu whose binaries are the C core (``fmus/native/*.c``) plus
the FMI 2.0 co-simulation wrapper ``fmus/native/fmu/fmi2_plant.c``, compiled
for each platform this machine can build for (:data:`PLATFORMS`):
``binaries/linux64/<Model>.so`` with the system's C compiler, and
``binaries/win64/<Model>.dll`` with mingw-w64 (``x86_64-w64-mingw32-gcc``,
Debian's gcc-mingw-w64-x86-64) where it is installed. Their ``sources/``
folder holds all of it (an importer can compile the FMU for another
platform, e.g. with ``fmpy.build.build_platform_binary``).

They are twins of the pythonfmu FMUs, not copies: the model description is
written from the same facade class (:mod:`dfwb.fmus.facade`) by the same
pass (:func:`~dfwb.build_fmus.builder.finish_model_description`: units,
ranges, structure), so names, value references, start values and ranges
agree by construction; the wrapper learns them from ``dfwb_model.h``, a
header written here from that description (each variable's role: a core
parameter, the input, an output of the core). Only the CoSimulation element
differs (no execution tool, memory through the host's callbacks).

A native FMU's hash covers the C sources, the facade and builder modules,
pythonfmu's version, each platform's compiler command and :data:`NATIVE_REVISION`; an
FMU whose recorded hash matches is not rebuilt (as for the pythonfmu FMUs).
"""

import functools
import hashlib
import os
import shutil
import subprocess
import tempfile
import uuid
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pythonfmu

from dfwb.fmus import facade
from dfwb.fmus.plants import c_name

from .core import FLAGS, LIBS, NATIVE_DIR, WIN64_CC, compiler, sources, win64_compiler
from .errors import BuildError
from .fmi3 import TIME, build_description, fmi3_description
from .recorded import recorded_hash

__all__ = ["build_native", "native_models", "native_hash", "platforms", "WRAPPERS", "NATIVE_REVISION", "PLATFORMS"]

NATIVE_REVISION = "1"
FMU_SOURCES = NATIVE_DIR / "fmu"  # the FMU around the core: plant_fmu.c/.h and one layer per FMI version
WRAPPERS = {2: ("fmi2_plant.c", "plant_fmu.c", "plant_fmu.h"), 3: ("fmi3_plant.c", "plant_fmu.c", "plant_fmu.h")}
BUILDER = Path(__file__).with_name("builder.py")  # writes the model description (finish_model_description)
GENERATION_TOOL = "dfwb native (C core, fmus/native)"
# The FMI platforms a native FMU carries a binary for, and its file suffix (linux64: the system's C compiler;
# win64: mingw-w64, WIN64_CC).
# win64: mingw-w64's printf made C99's (the messages name numbers as on linux64), its libgcc linked in (the DLL
# needs only KERNEL32 and msvcrt); -fPIC and -fvisibility mean nothing in a PE DLL (FMI_API is dllexport).
PLATFORMS = {"linux64": ".so", "win64": ".dll"}
BINARY_FOLDERS = {2: {"linux64": "linux64", "win64": "win64"},  # binaries/<folder>/ per FMI version
                  3: {"linux64": "x86_64-linux", "win64": "x86_64-windows"}}
FMI_VERSIONS = (2, 3)
WIN64_FLAGS = ("-O2", "-std=c99", "-shared", "-ffp-contract=off", "-D__USE_MINGW_ANSI_STDIO=1", "-static-libgcc",
               "-s")

KINDS = {model.__name__: (f"DFWB_PLANT_{c_name(model.table).upper()}", model.table)
         for model in facade.PRODUCTION if model.native_solver and model.table is not None}
"""{facade name: (its kind's macro, its table: the C order of its parameters, outputs and counters)}."""
COSIMULATION = {
    "needsExecutionTool": "false", "canHandleVariableCommunicationStepSize": "true",
    "canInterpolateInputs": "false", "maxOutputDerivativeOrder": "0", "canRunAsynchronuously": "false",
    "canBeInstantiatedOnlyOncePerProcess": "false", "canNotUseMemoryManagementFunctions": "false",
    "canGetAndSetFMUstate": "true", "canSerializeFMUstate": "true", "providesDirectionalDerivative": "false",
}


def native_models():
    """The facade classes that have a native FMU (the three plants of :data:`dfwb.fmus.facade.PRODUCTION`)."""
    return [model for model in facade.PRODUCTION if model.__name__ in KINDS]


def _headers():
    import fmpy

    folder = Path(fmpy.__file__).resolve().parent / "c-code"  # fmi2Functions.h & co. (FMI 2.0)
    if not (folder / "fmi2Functions.h").is_file():
        raise BuildError(f"building the native FMUs needs the FMI 2.0 headers of fmpy: no fmi2Functions.h in {folder}")
    return folder


def platforms():
    """The platforms of :data:`PLATFORMS` this machine can build binaries for (linux64, and win64 with mingw-w64)."""
    return ["linux64"] + (["win64"] if win64_compiler() else [])


def _version(fmi_version):
    if fmi_version not in FMI_VERSIONS:
        raise BuildError(f"FMI version {fmi_version!r}: the native FMUs are FMI 2.0 or 3.0 (2 or 3)")
    return fmi_version


def _command(extra_flags=(), platform="linux64"):
    if platform not in PLATFORMS:
        raise BuildError(f"platform {platform!r}: the native FMUs are built for {', '.join(PLATFORMS)}")
    if platform == "linux64":
        return compiler() + list(FLAGS) + [str(flag) for flag in extra_flags]
    found = win64_compiler()
    if not found:
        raise BuildError(f"building {platform} binaries needs {WIN64_CC} on PATH (Debian: apt-get install "
                         f"gcc-mingw-w64-x86-64)")
    return [found] + list(WIN64_FLAGS) + [str(flag) for flag in extra_flags]


@functools.lru_cache(maxsize=8)
def _static_digest():
    """The hash of what every native FMU is made of (sources, modules, versions), once per process."""
    digest = hashlib.sha256((NATIVE_REVISION + "\0" + pythonfmu.__version__).encode())
    wrappers = sorted(FMU_SOURCES.glob("*.[ch]"))
    # the solver package whole (the model descriptions come from its facades, which import its modules): a
    # superset of what a facade bundles, as sources() is of the core's, read without the builder's import graph
    package = sorted(Path(facade.__file__).parent.glob("*.py"))
    files = {path.name: path.read_bytes() for path in wrappers + [BUILDER, Path(__file__)] + package}
    for name, content in list(files.items()) + list(sources().items()):
        digest.update(b"\0" + name.encode() + b"\0" + content)
    return digest.hexdigest()


def native_hash(model, extra_flags=(), targets=("linux64",), fmi_version=2):
    """The hash a native FMU of ``model`` (FMI ``fmi_version``) with binaries for ``targets`` records (see the
    module's docstring)."""
    if model.__name__ not in KINDS:
        raise BuildError(f"{model.__name__} has no native FMU (native: {', '.join(KINDS)})")
    commands = [word for target in targets for word in [target] + _command(extra_flags, target)]
    words = "\0".join(commands + list(LIBS) + [model.__name__, f"FMI {_version(fmi_version)}", _static_digest()])
    return hashlib.sha256(words.encode()).hexdigest()[:16]


def _description(model, digest):
    """The finished FMI 2.0 model description of the pythonfmu FMU, made native (CoSimulation, tool, GUID)."""
    from .builder import finish_model_description  # the build machinery: only when an FMU is built

    with tempfile.TemporaryDirectory(prefix="dfwb_native_xml_") as tmp:
        instance = model(instance_name="native", resources=tmp)
        raw = ET.tostring(instance.to_xml(), encoding="utf-8")
    root = ET.fromstring(finish_model_description(raw, model, digest))
    root.set("generationTool", GENERATION_TOOL)
    root.set("guid", "{%s}" % uuid.uuid5(uuid.NAMESPACE_URL, f"dfwb/native/{model.__name__}/{digest}"))
    root.attrib.pop("generationDateAndTime", None)
    cosimulation = root.find("CoSimulation")
    cosimulation.attrib.clear()
    cosimulation.set("modelIdentifier", model.__name__)
    cosimulation.attrib.update(COSIMULATION)
    files = ET.SubElement(cosimulation, "SourceFiles")
    for name in _source_names(2):
        if name.endswith(".c"):
            ET.SubElement(files, "File", name=name)
    ET.indent(root)
    return root


def _source_names(fmi_version):
    return list(WRAPPERS[fmi_version]) + ["dfwb_model.h"] + list(sources())


def _token(model, digest):
    """The FMI 3.0 FMU's instantiationToken (the FMI 2.0 FMU's GUID is made the same way, without "fmi3/")."""
    return "{%s}" % uuid.uuid5(uuid.NAMESPACE_URL, f"dfwb/native/fmi3/{model.__name__}/{digest}")


def _c_string(text):
    if any(ch in text for ch in '"\\\n') or not text.isascii():
        raise BuildError(f"{text!r} cannot be written into dfwb_model.h")
    return f'"{text}"'


def model_header(model, root):
    """dfwb_model.h for ``model`` from its FMI 2.0 or 3.0 model description ``root``: its kind, GUID (or
    instantiationToken) and every variable's name, type, role and start value."""
    kind, table = KINDS[model.__name__]
    parameters, outputs, counters = table.core_order, table.solver_outputs, table.counters
    index = {name: i for i, name in enumerate(parameters)}
    rows, vr_of = [], {}
    fmi3 = root.get("fmiVersion") == "3.0"
    for vr, variable in enumerate(root.find("ModelVariables")):
        name, causality = variable.get("name"), variable.get("causality")
        if int(variable.get("valueReference")) != vr:
            raise BuildError(f"{model.__name__}: value references are not 0, 1, 2, ... ({name})")
        element = variable if fmi3 else variable[0]  # FMI 3.0: <Float64 .../>; FMI 2.0: <ScalarVariable><Real/>
        integer = int(element.tag in ("Integer", "Int32"))
        start = float(element.get("start", "0"))
        vr_of[name] = vr
        if causality == "independent" and name == TIME:
            role, position = "ROLE_TIME", 0
        elif causality == "parameter":
            role, position = "ROLE_PARAMETER", index[name]
        elif causality == "input":
            role, position = "ROLE_INPUT", index[name]
        elif name in outputs:
            role, position = "ROLE_OUTPUT", outputs.index(name)
        elif name == "events":
            role, position = "ROLE_EVENTS", 0
        elif name in counters:
            role, position = "ROLE_COUNTER", counters.index(name)
        elif name[:2] in ("Ic", "Is") and name[2:].isdigit():
            role, position = ("ROLE_COSINE" if name[1] == "c" else "ROLE_SINE"), int(name[2:])
        elif name == "I_error" and table.integrated:
            role, position = "ROLE_ERROR", 0
        else:
            raise BuildError(f"{model.__name__}: the native wrapper knows no role for the variable {name!r}")
        rows.append(f"    {{{_c_string(name)}, {integer}, {role}, {position}, {start!r}}},")
    defines = {"DFWB_MODEL_NAME": _c_string(model.__name__), "DFWB_MODEL_KIND": kind,
               "DFWB_MODEL_PARAMS": len(parameters), "DFWB_MODEL_OUTPUTS": len(outputs),
               "DFWB_MODEL_GUID": _c_string(root.get("instantiationToken" if fmi3 else "guid")),
               "DFWB_MODEL_INPUT_PARAMETER": index["f"], "DFWB_MODEL_PHI_PARAMETER": index["phi"],
               "DFWB_MODEL_OMEGA_PARAMETER": index["omega"], "DFWB_MODEL_OMEGA_VR": vr_of["omega"]}
    halves = [p for p in table.parameters if p.half_of]  # gap0 = -1 (its start): h/2
    if len(halves) > 1:
        raise BuildError(f"{model.__name__}: the native wrapper takes one parameter that stands for half another")
    for parameter in halves:
        defines.update(DFWB_MODEL_HALF_PARAMETER=index[parameter.name], DFWB_MODEL_HALF_START=repr(parameter.start),
                       DFWB_MODEL_HALF_OF=index[parameter.half_of])
    lines = [f"/* dfwb_model.h - {model.__name__}: written by build_fmus/native.py from the facade; do not edit. */"]
    lines += [f"#define {key} {value}" for key, value in defines.items()]
    lines += ["static const model_variable DFWB_MODEL_VARIABLES[] = {"] + rows + ["};", ""]
    return "\n".join(lines)


def _compile(stage, binaries, extra_flags, fmi_version):
    """Compile the staged sources into ``binaries`` ({platform: path}), the platforms side by side."""
    runs = {}
    for platform, target in binaries.items():
        command = (_command(extra_flags, platform) + [f"-I{_headers()}", f"-I{stage}", "-o", str(target)]
                   + [str(stage / name) for name in _source_names(fmi_version) if name.endswith(".c")] + list(LIBS))
        try:
            runs[platform] = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                              cwd=stage)
        except OSError as error:
            raise BuildError(f"compiling the native FMU failed: {command[0]}: {error}") from None
    failed = []
    for platform, run in runs.items():
        stderr = run.communicate()[1]
        if run.returncode != 0:
            lines = [line.strip() for line in stderr.splitlines() if line.strip()]
            first = next((line for line in lines if "error" in line), lines[0] if lines else "no message")
            failed.append(f"compiling the native FMU for {platform} failed (exit {run.returncode}): {first}")
    if failed:
        raise BuildError(failed[0])


def build_one_native(model, out_dir, digest=None, extra_flags=(), targets=("linux64",), fmi_version=2):
    """Build ``<out_dir>/<Model>.fmu``, the native FMI ``fmi_version`` FMU of ``model`` with binaries for
    ``targets`` (atomic replace); its path."""
    digest = digest or native_hash(model, extra_flags, targets, fmi_version)
    root = _description(model, digest)
    if fmi_version == 3:
        root = fmi3_description(root, _token(model, digest))
    dest = Path(out_dir) / f"{model.__name__}.fmu"
    names = _source_names(fmi_version)
    with tempfile.TemporaryDirectory(prefix="dfwb_native_") as tmp:
        stage = Path(tmp) / "sources"
        stage.mkdir()
        for name in WRAPPERS[fmi_version]:
            (stage / name).write_bytes((FMU_SOURCES / name).read_bytes())
        for name, content in sources().items():
            (stage / name).write_bytes(content)
        (stage / "dfwb_model.h").write_text(model_header(model, root))
        binaries = {target: Path(tmp) / f"{target}{PLATFORMS[target]}" for target in targets}
        _compile(stage, binaries, extra_flags, fmi_version)
        partial = dest.with_name(f".{dest.name}.{os.getpid()}.partial")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("modelDescription.xml",
                             b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8"))
            for target, binary in binaries.items():
                folder = BINARY_FOLDERS[fmi_version][target]
                archive.write(binary, f"binaries/{folder}/{model.__name__}{PLATFORMS[target]}")
            for name in names:
                archive.write(stage / name, f"sources/{name}")
            if fmi_version == 3:
                archive.writestr("sources/buildDescription.xml",
                                 build_description(model.__name__, [name for name in names if name.endswith(".c")]))
        partial.replace(dest)
    return dest


def build_native(out_dir, models=None, force=False, report=print, extra_flags=(), targets=None, fmi_version=2,
                 reuse=None):
    """Build the native FMI ``fmi_version`` (2 or 3) FMUs of ``models`` (default :func:`native_models`) into
    ``out_dir``; their paths.

    As :func:`dfwb.build_fmus.builder.build`: an FMU whose recorded hash matches
    is kept (``force`` rebuilds it), ``report`` gets one line per FMU.
    ``extra_flags`` go to the compiler (and into the hash), e.g. ``("-Wall", "-Werror")``.
    ``targets``: the platforms to build binaries for (default :func:`platforms`: all this machine can).
    ``reuse``: a folder of FMUs built before (dfwb's own): one there with the same recorded hash (the same
    sources, flags, platforms and FMI version) is copied instead of compiled again (not with ``force``).
    """
    fmi_version = _version(fmi_version)
    targets = tuple(platforms() if targets is None else targets)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    what = f"native, FMI {fmi_version}.0, {' + '.join(targets)}"
    for model in native_models() if models is None else models:
        path = out_dir / f"{model.__name__}.fmu"
        digest = native_hash(model, extra_flags, targets, fmi_version)
        built = None if reuse is None or force else Path(reuse) / path.name
        if not force and recorded_hash(path) == digest:
            report(f"{path}: up to date ({what})")
        elif built is not None and built.resolve() != path.resolve() and recorded_hash(built) == digest:
            partial = path.with_name(f".{path.name}.{os.getpid()}.partial")  # as the builds write theirs
            try:
                shutil.copyfile(built, partial)
                partial.replace(path)
            finally:
                partial.unlink(missing_ok=True)  # a copy that failed half way
            report(f"{path}: copied from {built.parent}, built there from the same sources ({what})")
        else:
            build_one_native(model, out_dir, digest, extra_flags, targets, fmi_version)
            report(f"{path}: built ({what})")
        paths.append(path)
    return paths
