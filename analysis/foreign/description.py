"""What a user's FMU offers, read from its model description once it is unpacked safely.

:func:`describe` returns an :class:`FMUInfo`: FMI version, the interfaces
(model exchange, co-simulation) with their capabilities, and the variables a
describing function can use -- continuous Real inputs (the force), Real
outputs (the position), parameters with their units, start values and
ranges. Everything a user can get wrong is refused with one line that names
the FMU, the reason and what the FMU does offer; so is what the standard
forbids and dfwb would otherwise act on: a modelIdentifier that is not a
plain file name (its binary loaded from outside the FMU), two variables of
one name, a name with a control character (a forged line in ``dfwb info``),
a parameter whose min exceeds its max, a count of event indicators that no
array can hold.
"""

import math
from dataclasses import dataclass, field
from pathlib import Path

from dfwb.base.errors import PlantError
from dfwb.engine.family import number as finite_number
from dfwb.foreign.archive import unpack

__all__ = ["FMUInfo", "Parameter", "describe", "KINDS", "REALS"]

KINDS = ("model-exchange", "co-simulation")  # preferred first: the sine enters exactly
REALS = {"Real", "Float64", "Float32"}
INTEGERS = {"Integer", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64", "Enumeration"}
BOOLEANS = {"Boolean"}
# The platform folder of this machine's binaries, by FMI major version.
PLATFORM = {"2": "linux64", "3": "x86_64-linux"}
MAX_EVENT_INDICATORS = 100_000  # a large Modelica model has thousands; each is a double of every evaluation


@dataclass(frozen=True)
class Parameter:
    """A parameter of the FMU: ``--set name=value`` sets it before initialisation."""

    name: str
    type: str
    start: float
    unit: str = ""
    min: float = -math.inf
    max: float = math.inf
    description: str = ""

    def check(self, fmu, value):
        """The value as a float, or PlantError naming it and what is allowed."""
        number = float(value) if isinstance(value, bool) and self.type in BOOLEANS else \
            finite_number(f"{fmu}: {self.name}", value, "is not finite")
        if self.type in BOOLEANS and number not in (0.0, 1.0):
            raise PlantError(f"{fmu}: {self.name} = {value!r} is a Boolean: 0 or 1")
        if self.type in INTEGERS and number != int(number):
            raise PlantError(f"{fmu}: {self.name} = {value!r} is an {self.type}: a whole number")
        if not self.min <= number <= self.max:
            raise PlantError(f"{fmu}: {self.name} = {value!r} is out of range: [{self.min:g}, {self.max:g}] "
                             f"{self.unit}".rstrip())
        return number


@dataclass(frozen=True)
class FMUInfo:
    """The facts of one FMU file that dfwb uses (picklable: a worker process gets it whole)."""

    path: str
    folder: str
    digest: str
    fmi_version: str
    model_name: str
    kinds: tuple  # of KINDS, offered by the FMU with a binary for this machine
    identifiers: dict  # kind -> modelIdentifier
    can_save_state: dict  # kind -> canGetAndSetFMUstate
    can_interpolate_inputs: bool
    max_output_derivative_order: int
    event_indicators: int
    states: int
    inputs: dict  # name -> (type, variability) of every input
    outputs: dict  # name -> (type, unit) of every output
    parameters: dict = field(default_factory=dict)  # name -> Parameter
    intermediate_inputs: tuple = ()  # FMI 3.0 co-simulation: inputs it asks for inside a step (intermediate update)

    @property
    def major(self):
        return self.fmi_version.split(".")[0]

    def real_inputs(self):
        return [n for n, (kind, variability) in self.inputs.items() if kind in REALS and variability == "continuous"]

    def real_outputs(self):
        return [n for n, (kind, _unit) in self.outputs.items() if kind in REALS]

    def check_input(self, name):
        """Refuse a name that is not a continuous Real input, listing the ones there are."""
        offered = ", ".join(self.real_inputs()) or "none"
        if name not in self.inputs:
            raise PlantError(f"{self.path}: no input {name!r} (its continuous Real inputs: {offered})")
        kind, variability = self.inputs[name]
        if kind not in REALS or variability != "continuous":
            raise PlantError(f"{self.path}: the input {name!r} is {variability}, of type {kind}: the force must be a "
                             f"continuous Real input (its continuous Real inputs: {offered})")

    def check_output(self, name):
        """Refuse a name that is not a Real output, listing the ones there are."""
        offered = ", ".join(self.real_outputs()) or "none"
        if name not in self.outputs:
            raise PlantError(f"{self.path}: no output {name!r} (its Real outputs: {offered})")
        if self.outputs[name][0] not in REALS:
            raise PlantError(f"{self.path}: the output {name!r} is of type {self.outputs[name][0]}: the position "
                             f"must be a Real output (its Real outputs: {offered})")

    def unit(self, name):
        return self.outputs.get(name, ("", ""))[1]


def _number(text, default):
    try:
        value = float(text)
    except (TypeError, ValueError):
        return default
    return value if not math.isnan(value) else default


def _unit(path, variable):
    unit = variable.unit or (variable.declaredType.unit if variable.declaredType is not None else None)
    return _name(path, f"the unit of {variable.name!r}", unit)


def _prose(text):
    """A description on one line: whitespace collapsed, any other unprintable character shown escaped."""
    return "".join(c if c.isprintable() else ascii(c)[1:-1] for c in " ".join(str(text or "").split()))


def _name(path, what, text):
    """``text`` if it is a name that prints as one line of itself (one rule for every name ``dfwb`` shows)."""
    text = str(text or "")
    if not text.isprintable():
        raise PlantError(f"{path}: {what} {text!r} is not accepted: a name is printable text (no control, format "
                         f"or line-separating characters)")
    return text


def _identifier(path, kind, identifier):
    """The modelIdentifier as a plain file name, so that its binary is the FMU's own."""
    name = _name(path, f"the modelIdentifier of its {kind} interface", identifier)
    if not name or name in (".", "..") or "/" in name or "\\" in name:
        raise PlantError(f"{path}: the modelIdentifier {name!r} of its {kind} interface is not accepted: a plain "
                         f"file name (its binary is binaries/<platform>/<modelIdentifier>.so inside the FMU)")
    return name


def _check_variables(path, md):
    """Refuse what the standard forbids and dfwb would act on: two variables of one name, names that forge
    lines, a range that is empty, more event indicators than memory holds."""
    seen = set()
    for v in md.modelVariables:
        name = _name(path, "the variable name", v.name)
        if name in seen:
            raise PlantError(f"{path}: two variables are named {name!r} (a variable's name is unique in an FMU)")
        seen.add(name)
        low, high = _number(v.min, -math.inf), _number(v.max, math.inf)
        if low > high:
            raise PlantError(f"{path}: the variable {name!r} is declared with min = {v.min} > max = {v.max} "
                             f"(no value is allowed)")
    count = md.numberOfEventIndicators or 0
    if not 0 <= count <= MAX_EVENT_INDICATORS:
        raise PlantError(f"{path}: numberOfEventIndicators = {count} is not accepted (0 to {MAX_EVENT_INDICATORS})")


def describe(path):
    """The :class:`FMUInfo` of an FMU file; PlantError (one line) for anything dfwb cannot run."""
    from fmpy import read_model_description  # lxml: only once the archive is known to be sane

    folder, key = unpack(path)
    import xml.etree.ElementTree as ElementTree  # the file passed unpack's checks: small, shallow, no entities

    try:
        root = ElementTree.parse(Path(folder, "modelDescription.xml")).getroot()
        version = str(root.get("fmiVersion") or "")
    except ElementTree.ParseError as error:
        raise PlantError(f"{path}: its modelDescription.xml cannot be read ({error})") from None
    if version.startswith("1."):
        raise PlantError(f"{path}: FMI {version} is not supported (an FMI 2.0 or 3.0 FMU is)")
    if not version.startswith(("2.", "3.")):
        raise PlantError(f"{path}: FMI version {version!r} is not supported (an FMI 2.0 or 3.0 FMU is)")
    try:
        md = read_model_description(str(folder), validate=False)
    except Exception as error:  # a malformed model description: lxml, fmpy or attrs say why
        raise PlantError(f"{path}: its modelDescription.xml cannot be read "
                         f"({' '.join(str(error).split())[:200] or type(error).__name__})") from None
    major = version.split(".")[0]
    interfaces = {"model-exchange": md.modelExchange, "co-simulation": md.coSimulation}
    declared = [kind for kind in KINDS if interfaces[kind] is not None]
    if not declared:
        raise PlantError(f"{path}: offers neither model exchange nor co-simulation")
    identifiers = {kind: _identifier(path, kind, interfaces[kind].modelIdentifier) for kind in declared}
    model_name = _name(path, "the modelName", md.modelName)
    _check_variables(path, md)
    binaries = Path(folder, "binaries", PLATFORM[major])
    kinds = tuple(kind for kind in declared if Path(binaries, f"{identifiers[kind]}.so").is_file())
    if not kinds:
        found = sorted(p.name for p in Path(folder, "binaries").iterdir()) if Path(folder, "binaries").is_dir() else []
        sources = " (it has sources: build its binary with fmpy.build.build_platform_binary)" \
            if Path(folder, "sources").is_dir() else ""
        raise PlantError(f"{path}: no binary for {PLATFORM[major]} (its binaries: {', '.join(found) or 'none'})"
                         f"{sources}")
    cs = md.coSimulation
    inputs, outputs, parameters = {}, {}, {}
    for v in md.modelVariables:
        if v.shape or v.dimensions:  # arrays (FMI 3.0) are not scalars dfwb can set or read
            continue
        if v.causality == "input":
            inputs[v.name] = (v.type, v.variability)
        elif v.causality == "output":
            outputs[v.name] = (v.type, _unit(path, v))
        elif v.causality == "parameter" and v.variability in ("fixed", "tunable") and \
                v.type in REALS | INTEGERS | BOOLEANS:
            start = 1.0 if str(v.start).lower() == "true" else 0.0 if str(v.start).lower() == "false" else \
                _number(v.start, 0.0)
            parameters[v.name] = Parameter(v.name, v.type, start, _unit(path, v), _number(v.min, -math.inf),
                                           _number(v.max, math.inf), _prose(v.description))
    states = len(md.derivatives) if md.derivatives else 0
    intermediate = ()  # (fmpy does not read a variable's intermediateUpdate: the XML says it)
    if major == "3" and cs is not None and cs.providesIntermediateUpdate:
        intermediate = tuple(v.get("name") for v in root.iter("Float64")
                             if v.get("causality") == "input" and v.get("intermediateUpdate") == "true"
                             and v.get("name") in inputs)
    return FMUInfo(
        path=str(path), folder=str(folder), digest=key, fmi_version=version, model_name=model_name,
        kinds=kinds, identifiers={kind: identifiers[kind] for kind in kinds},
        can_save_state={kind: bool(interfaces[kind].canGetAndSetFMUstate) for kind in kinds},
        can_interpolate_inputs=bool(cs is not None and cs.canInterpolateInputs),
        max_output_derivative_order=int(cs.maxOutputDerivativeOrder or 0) if cs is not None else 0,
        event_indicators=int(md.numberOfEventIndicators or 0), states=states,
        inputs=inputs, outputs=outputs, parameters=parameters, intermediate_inputs=intermediate)
