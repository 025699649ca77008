"""A user's FMU as a plant: :func:`fmu_plant` checks it once and names its force input and position output."""

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

from dfwb.base.errors import PlantError
from dfwb.foreign.description import KINDS, FMUInfo, describe

__all__ = ["FMUPlant", "fmu_plant", "resolve_plant", "tolerance_parameter"]


@dataclass(frozen=True)
class FMUPlant:
    """A user's FMU with its force input and position output, checked (made by :func:`fmu_plant`).

    Attributes
    ----------
    info : FMUInfo
        What the FMU offers (:mod:`dfwb.foreign.description`).
    input, output : str
        The continuous Real input the force enters, the Real output whose DF is taken.
    kind : {"model-exchange", "co-simulation"}
        How it runs: model exchange when it offers it (the sine enters exactly), else co-simulation.

    Examples
    --------
    dfwb's own friction-mass FMU (built into the FMU folder on first use) taken as a user's FMU:

    >>> import dfwb
    >>> from dfwb.fmi.location import fmu_path
    >>> own = dfwb.fmu_plant(fmu_path(dfwb.plant("friction")), input="f", output="x")
    >>> own.summary
    'FrictionMass: FMI 2.0 co-simulation, force f -> position x [m]'
    >>> own.kind, own.input, own.output, own.unit, own.foreign, own.name.endswith("FrictionMass.fmu")
    ('co-simulation', 'f', 'x', 'm', True, True)
    >>> own.defaults()["Fs"], own.check({"M": 2})
    (7.0, {'M': 2.0})
    >>> own.check({"mass": 2})  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    dfwb.fmus.exact.PlantError: ...FrictionMass.fmu: no parameter 'mass' (its parameters: M, B, Fc, Fs, ...)
    """

    info: FMUInfo
    input: str
    output: str
    kind: str
    foreign = True  # what the registry and the engines know it by (dfwb.plants.plant passes it through)
    loop = None  # no exact closed loop of dfwb's own (its true cycles are the FMU's)

    @property
    def name(self):
        """The FMU's path as given: what records and tables call the plant."""
        return self.info.path

    @property
    def unit(self):
        return self.info.unit(self.output)

    @property
    def summary(self):
        info = self.info
        return (f"{info.model_name}: FMI {info.fmi_version} {self.kind}, force {self.input} -> "
                f"position {self.output} [{self.unit or '-'}]")

    def defaults(self):
        """{parameter: start value} from the model description."""
        return {name: p.start for name, p in self.info.parameters.items()}

    def check(self, params):
        """Validated {name: float}; PlantError naming the value and what is allowed."""
        if not isinstance(params, Mapping):
            raise PlantError(f"params = {params!r:.80} is not a mapping of parameter names to numbers")
        allowed = self.info.parameters
        values = {}
        for name, value in params.items():
            if name not in allowed:
                raise PlantError(f"{self.name}: no parameter {name!r} (its parameters: "
                                 f"{', '.join(allowed) or 'none'})")
            values[name] = allowed[name].check(self.name, value)
        return values

    checked = check

    def complete(self, params):
        return dict(self.defaults(), **params)


def fmu_plant(path, input=None, output=None, kind=None):
    """A user's FMU as a plant for every analysis of dfwb.

    Parameters
    ----------
    path : str or Path
        An FMI 2.0 or 3.0 FMU (model exchange or co-simulation) with a binary for this machine.
    input : str, optional
        Its continuous Real input that takes the force [N]; may be omitted when it has exactly one.
    output : str, optional
        Its Real output whose describing function is taken (the position); may be omitted when it has exactly one.
    kind : {"model-exchange", "co-simulation"}, optional
        Which interface runs; by default model exchange when offered (the sine enters exactly).

    Returns
    -------
    FMUPlant

    Raises
    ------
    dfwb.PlantError
        A file that is not a sane FMU, FMI 1.0, no binary for this machine, an input that
        is not a continuous Real input or an output that is not a Real output: one line
        naming the FMU, the reason and what it offers.

    Examples
    --------
    dfwb's own friction-mass FMU (built into the FMU folder on first use) as a user's FMU: its one
    continuous Real input is found by itself, its output (one of several) is named. Its describing
    function, computed by the generic driver with an error estimate, against dfwb's exact one:

    >>> import dfwb
    >>> from dfwb.fmi.location import fmu_path
    >>> path = fmu_path(dfwb.plant("friction"))
    >>> own = dfwb.fmu_plant(path, output="x")
    >>> own.kind, own.input, own.output
    ('co-simulation', 'f', 'x')
    >>> response = dfwb.describing_function(own, F=10.0, omega=1.0)
    >>> exact = dfwb.describing_function("friction", F=10.0, omega=1.0)
    >>> bool(abs(complex(response.N) - complex(exact.N)) <= float(response.N_error) < 1e-3)
    True

    A file that is not there, an input the FMU does not have, an output not named:

    >>> dfwb.fmu_plant("no-such.fmu")
    Traceback (most recent call last):
    ...
    dfwb.fmus.exact.PlantError: no-such.fmu: no such FMU file
    >>> dfwb.fmu_plant(path, input="force", output="x")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    dfwb.fmus.exact.PlantError: ...FrictionMass.fmu: no input 'force' (its continuous Real inputs: f)
    >>> dfwb.fmu_plant(path)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    dfwb.fmus.exact.PlantError: ...FrictionMass.fmu: name its output with --output (its Real outputs: x, v, Ff, ...)
    """
    if not isinstance(path, (str, Path)):
        raise PlantError(f"an FMU's path must be a string, not {type(path).__name__} {path!r:.60}")
    info = describe(path)
    if kind is None:
        kind = info.kinds[0]
    elif kind not in KINDS:
        raise PlantError(f"kind {kind!r} is not allowed (allowed: {', '.join(KINDS)})")
    elif kind not in info.kinds:
        raise PlantError(f"{path}: offers no {kind} with a binary here (it offers: {', '.join(info.kinds)})")
    input = _only(info, input, info.real_inputs(), "input", "continuous Real inputs")
    output = _only(info, output, info.real_outputs(), "output", "Real outputs")
    info.check_input(input)
    info.check_output(output)
    return FMUPlant(info, input, output, kind)


def _only(info, given, offered, what, label):
    if given is not None:
        if not isinstance(given, str):
            raise PlantError(f"{info.path}: the {what} must be a variable's name, not {given!r:.60}")
        return given
    if len(offered) == 1:
        return offered[0]
    raise PlantError(f"{info.path}: name its {what} with --{what} (its {label}: {', '.join(offered) or 'none'})")


def is_fmu_path(plant):
    """True for a plant given as the path of an FMU (a string ending in .fmu, or a Path)."""
    return isinstance(plant, Path) or (isinstance(plant, str) and plant.lower().endswith(".fmu"))


def resolve_plant(plant):
    """A registered plant (by name or entry), or a user's FMU: an FMUPlant, or the path of an .fmu file."""
    from dfwb.plants import plant as registered

    if isinstance(plant, FMUPlant):
        return plant
    if is_fmu_path(plant):
        return fmu_plant(plant)
    return registered(plant)


def tolerance_parameter(spec, rtol, params):
    """(rtol, params): for a plant of dfwb's integrated family (a table with a parameter rtol, the Stribeck
    mass), ``rtol`` is that parameter, as it is a user's FMU's tolerance; elsewhere it stays what it was."""
    table = getattr(getattr(spec, "model", None), "table", None)
    if rtol is None or getattr(spec, "foreign", False) or table is None or "rtol" not in table.names:
        return rtol, params
    return None, dict(params, rtol=rtol)
