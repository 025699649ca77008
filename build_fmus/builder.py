"""Build the plant FMUs: pythonfmu, then a pass that makes them FMI 2.0 clean.

Two FMUs in one process must never share Python code by accident
(pythonfmu imports each FMU's script and bundled modules by name, and the
first module of a name wins). So every build bundles the solver package
under a name that carries the hash of its sources, ``dfwb_fmus_<hash>``,
next to a one-line script ``<Model>_<hash>.py``: FMUs of the same sources
share identical code, FMUs of different sources cannot collide.

pythonfmu writes no units, no ModelStructure/InitialUnknowns and a random
GUID; :func:`finish_model_description` adds the first two (so that ``fmpy
validate`` passes) and makes the GUID a function of the model and the hash.
An FMU whose recorded hash matches the sources is not rebuilt.
"""

import hashlib
import os
import shutil
import tempfile
import uuid
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pythonfmu
from pythonfmu.builder import FmuBuilder

from dfwb.fmus import facade

FMUS_DIR = Path(facade.__file__).resolve().parent
BUILDER_REVISION = "2"
HASH_PREFIX = "dfwb-sources-"
SCRIPT = '''"""dfwb {model} FMU: the facade from the bundled, hash-named solver package."""
from {package}.facade import {model}, pin

pin(globals())  # pythonfmu 0.7.0 releases this namespace once per instantiation
'''

# SI base-unit exponents of every unit the models use
BASE_UNITS = {
    "N": {"kg": 1, "m": 1, "s": -2},
    "kg": {"kg": 1},
    "m": {"m": 1},
    "m/s": {"m": 1, "s": -1},
    "N.s/m": {"kg": 1, "s": -1},
    "rad/s": {"rad": 1, "s": -1},
    "rad": {"rad": 1},
    "m.s": {"m": 1, "s": 1},
    "s": {"s": 1},
}


def source_hash():
    """Hash of everything that goes into an FMU: solver sources, pythonfmu, this builder."""
    digest = hashlib.sha256()
    for path in sorted(FMUS_DIR.glob("*.py")):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    digest.update(pythonfmu.__version__.encode() + BUILDER_REVISION.encode())
    return digest.hexdigest()[:16]


def recorded_hash(fmu_path):
    """The source hash an existing FMU was built from, or None."""
    try:
        with zipfile.ZipFile(fmu_path) as archive:
            root = ET.fromstring(archive.read("modelDescription.xml"))
    except (OSError, KeyError, zipfile.BadZipFile, ET.ParseError):
        return None
    version = root.get("version", "")
    return version[len(HASH_PREFIX):] if version.startswith(HASH_PREFIX) else None


def finish_model_description(xml_bytes, model, digest):
    """Units, UnitDefinitions, InitialUnknowns and a deterministic GUID."""
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
    definitions = ET.Element("UnitDefinitions")
    for name in used:
        unit = ET.SubElement(definitions, "Unit", name=name)
        ET.SubElement(unit, "BaseUnit", {k: str(v) for k, v in BASE_UNITS[name].items()})
    if used:  # the schema wants at least one Unit in a UnitDefinitions
        position = list(root).index(root.find("CoSimulation")) + 1
        root.insert(position, definitions)
    structure = root.find("ModelStructure")
    for child in list(structure):
        structure.remove(child)
    indices = [str(i) for i, scalar in enumerate(variables, start=1) if scalar.get("causality") == "output"]
    for section in ("Outputs", "InitialUnknowns"):
        node = ET.SubElement(structure, section)
        for index in indices:
            ET.SubElement(node, "Unknown", index=index)
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


def build_one(model, out_dir, digest):
    """Build ``<out_dir>/<Model>.fmu`` from the current sources (atomic replace)."""
    package = f"dfwb_fmus_{digest}"
    dest = Path(out_dir) / f"{model.__name__}.fmu"
    with tempfile.TemporaryDirectory(prefix="dfwb_build_") as tmp:
        tmp = Path(tmp)
        stage = tmp / package
        stage.mkdir()
        for path in FMUS_DIR.glob("*.py"):
            shutil.copy2(path, stage / path.name)
        script = tmp / f"{model.__name__}_{digest}.py"
        script.write_text(SCRIPT.format(model=model.__name__, package=package))
        raw = FmuBuilder.build_FMU(script, dest=tmp / "raw", project_files=[stage])
        partial = dest.with_name(f".{dest.name}.{os.getpid()}.partial")  # concurrent builds never mix
        with zipfile.ZipFile(raw) as source, zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as target:
            for item in source.infolist():
                data = source.read(item.filename)
                if item.filename == "modelDescription.xml":
                    data = finish_model_description(data, model, digest)
                target.writestr(item, data)
        partial.replace(dest)
    return dest


def build_all(out_dir="build/fmus", force=False, report=print):
    """Build every plant FMU that is missing or stale; return their paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    digest = source_hash()
    paths = []
    for model in facade.FACADES:
        path = out_dir / f"{model.__name__}.fmu"
        if not force and recorded_hash(path) == digest:
            report(f"{path}: up to date")
        else:
            build_one(model, out_dir, digest)
            report(f"{path}: built")
        paths.append(path)
    return paths
