"""An FMI 3.0 co-simulation model description from a native FMU's FMI 2.0 one, and its build description.

The FMI 3.0 FMU of a plant is the FMI 2.0 FMU's twin: the same variables,
value references, units, ranges and start values, written as FMI 3.0 writes
them (``Float64`` for Real, ``Int32`` for Integer, no ScalarVariable
wrapper, the model structure by value reference), plus the independent
variable ``time`` that FMI 3.0 requires, at the value reference after the
last. :func:`fmi3_description` translates the finished FMI 2.0 description
(:func:`dfwb.build_fmus.native._description`), so the two cannot drift.
:func:`build_description` writes ``sources/buildDescription.xml`` (FMI 3.0's
list of sources), which importers such as fmpy compile from.

Examples
--------
>>> import xml.etree.ElementTree as ET
>>> two = ET.fromstring('<fmiModelDescription fmiVersion="2.0" modelName="M" guid="{g}">'
...     '<CoSimulation modelIdentifier="M"/><ModelVariables>'
...     '<ScalarVariable name="k" valueReference="0" causality="parameter" variability="fixed">'
...     '<Real start="1" unit="N" min="0.0"/></ScalarVariable></ModelVariables>'
...     '<ModelStructure/></fmiModelDescription>')
>>> three = fmi3_description(two, "{t}")
>>> [(v.tag, v.get("name"), v.get("valueReference")) for v in three.find("ModelVariables")]
[('Float64', 'k', '0'), ('Float64', 'time', '1')]
"""

import xml.etree.ElementTree as ET

__all__ = ["fmi3_description", "build_description", "COSIMULATION3", "TIME"]

TIME = "time"  # the independent variable's name
TYPES = {"Real": "Float64", "Integer": "Int32"}
COSIMULATION3 = {
    "needsExecutionTool": "false", "canBeInstantiatedOnlyOncePerProcess": "false",
    "canGetAndSetFMUState": "true", "canSerializeFMUState": "true", "providesDirectionalDerivatives": "false",
    "providesAdjointDerivatives": "false", "providesPerElementDependencies": "false",
    "canHandleVariableCommunicationStepSize": "true", "maxOutputDerivativeOrder": "0",
    "providesIntermediateUpdate": "false", "mightReturnEarlyFromDoStep": "false",
    "canReturnEarlyAfterIntermediateUpdate": "false", "hasEventMode": "false",
    "providesEvaluateDiscreteStates": "false",
}
VARIABLE_ATTRIBUTES = ("name", "valueReference", "description", "causality", "variability", "initial")


def fmi3_description(root, token):
    """The FMI 3.0 ``fmiModelDescription`` element for the FMI 2.0 one ``root``, with instantiationToken ``token``."""
    model = ET.Element("fmiModelDescription", {"fmiVersion": "3.0"})
    for key in ("modelName", "description", "author", "version", "generationTool", "variableNamingConvention"):
        if root.get(key) is not None:
            model.set(key, root.get(key))
    model.set("instantiationToken", token)
    cosimulation = ET.SubElement(model, "CoSimulation", {"modelIdentifier": root.find("CoSimulation").get(
        "modelIdentifier")})
    cosimulation.attrib.update(COSIMULATION3)
    for name in ("UnitDefinitions", "LogCategories", "DefaultExperiment"):
        if root.find(name) is not None:
            model.append(root.find(name))
    variables = ET.SubElement(model, "ModelVariables")
    references = []
    for scalar in root.find("ModelVariables"):
        kind = scalar[0]
        if kind.tag not in TYPES:
            raise ValueError(f"{scalar.get('name')}: an FMI 2.0 {kind.tag} has no FMI 3.0 translation here")
        variable = ET.SubElement(variables, TYPES[kind.tag])
        for key in VARIABLE_ATTRIBUTES:
            if scalar.get(key) is not None:
                variable.set(key, scalar.get(key))
        for key, value in kind.attrib.items():
            variable.set(key, value)
        references.append(scalar.get("valueReference"))
    ET.SubElement(variables, "Float64", {"name": TIME, "valueReference": str(len(references)),
                                         "causality": "independent", "variability": "continuous",
                                         "description": "simulation time"})
    structure = ET.SubElement(model, "ModelStructure")
    old = root.find("ModelStructure")
    for group, tag in (("Outputs", "Output"), ("InitialUnknowns", "InitialUnknown")):
        for unknown in old.findall(f"{group}/Unknown") if old is not None else []:
            element = ET.SubElement(structure, tag, {"valueReference": references[int(unknown.get("index")) - 1]})
            if unknown.get("dependencies"):  # FMI 2.0 indices (1-based) to FMI 3.0 value references
                element.set("dependencies", " ".join(references[int(i) - 1]
                                                      for i in unknown.get("dependencies").split()))
            elif unknown.get("dependencies") == "":
                element.set("dependencies", "")
    ET.indent(model)
    return model


def build_description(model_identifier, files):
    """``sources/buildDescription.xml`` (FMI 3.0): one C99 source file set of ``files`` (names in sources/)."""
    root = ET.Element("fmiBuildDescription", {"fmiVersion": "3.0"})
    configuration = ET.SubElement(root, "BuildConfiguration", {"modelIdentifier": model_identifier})
    sources = ET.SubElement(configuration, "SourceFileSet", {"language": "C99"})
    for name in files:
        ET.SubElement(sources, "SourceFile", {"name": name})
    ET.indent(root)
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")
