"""The plants the workbench knows: names, FMUs, outputs, Poincare states, parameters.

A plant is named on the command line (``friction``, ``backlash``,
``static-backlash``) and maps to one FMU. Its parameters are checked here,
with the exact solver's own validation, before any FMU is touched, so a bad
value becomes one clear line instead of an FMU failing mid-sweep.
"""

from dataclasses import dataclass
from pathlib import Path

from dfwb.fmus import facade
from dfwb.fmus.piecewise import PlantError

DEFAULT_FMU_DIR = Path("build/fmus")
RESERVED = {"F", "omega", "phi", "harmonics"}  # set by the engine itself
_CHECKED = {}  # (plant, model, parameter items) -> validated parameters: sweeps repeat the same sets


@dataclass(frozen=True)
class Plant:
    name: str
    model: type  # the FMI facade class
    output: str  # the signal whose DF is taken
    section: tuple  # continuous Poincare state, read at whole periods
    modes: tuple  # discrete Poincare state
    initial: dict  # Poincare state name -> the parameter that sets it at t = 0 (shooting)
    shifts: dict  # how each section component moves when the plant is translated by 1 m

    def translation(self, params):
        """Per section component, its change under a translation of the plant by 1 m."""
        slope = dict(self.defaults(), **params).get("k", 1.0)
        return tuple(slope if self.shifts.get(name) == "k" else self.shifts.get(name, 0.0) for name in self.section)

    @property
    def fmu_name(self):
        return self.model.__name__

    def defaults(self):
        return {name: default for name, default, *_ in self.model.parameters}

    def check(self, params):
        """Validated {name: float}; raises PlantError naming the value and what is allowed."""
        allowed = sorted(self.defaults())
        values = {}
        for name, value in params.items():
            if name in RESERVED:
                raise PlantError(f"{name} is set by the describing-function engine, not by --set "
                                 f"(allowed: {', '.join(allowed)})")
            if name not in allowed:
                raise PlantError(f"unknown parameter {name!r} for plant {self.name} (allowed: {', '.join(allowed)})")
            try:
                values[name] = float(value)
            except (TypeError, ValueError):
                raise PlantError(f"{name} = {value!r} is not a number") from None
        kwargs = dict(self.defaults(), **values)
        self.model.solver_class(F=1.0, omega=1.0, **self.model.solver_kwargs(kwargs))  # the solver's own range checks
        return values

    def checked(self, params):
        """:meth:`check`, done once per distinct parameter set in a process."""
        key = (self.name, self.model, tuple(sorted(params.items())))
        if key not in _CHECKED:
            _CHECKED[key] = self.check(params)
        return dict(_CHECKED[key])

    def complete(self, params):
        """Every parameter as a float, the defaults filled in (equal sets for a default given or omitted)."""
        return {name: float(value) for name, value in dict(self.defaults(), **params).items()}

    def mass(self, params):
        """Total mass moved by the force (sets the amplitude scales)."""
        merged = dict(self.defaults(), **params)
        return merged.get("M", merged.get("M1", 0.0) + merged.get("M2", 0.0))


# The plants are invariant under a translation of all positions (forces depend on
# velocities and relative positions only): "shifts" says how each section component moves.
PLANTS = {
    "friction": Plant("friction", facade.FrictionMass, "x", ("x", "v"), ("mode",), {"x": "x0", "v": "v0"},
                      {"x": 1.0}),
    "backlash": Plant("backlash", facade.TwoMassBacklash, "x1", ("x1", "v1", "gap", "v2"), ("contact",),
                      {"x1": "x1_0", "v1": "v1_0", "gap": "gap0", "v2": "v2_0"}, {"x1": 1.0}),
    "static-backlash": Plant("static-backlash", facade.StaticBacklash, "y", ("x", "v", "y"), ("engaged",), {},
                             {"x": 1.0, "y": "k"}),
}


def plant(name):
    """The Plant called ``name``, or PlantError listing the known ones."""
    try:
        return PLANTS[name]
    except KeyError:
        raise PlantError(f"unknown plant {name!r} (allowed: {', '.join(PLANTS)})") from None


def fmu_path(model, fmu_dir=DEFAULT_FMU_DIR):
    """Path of an FMU (a Plant, or a model name like "LinearSystem"), built first if missing or stale."""
    from dfwb.build_fmus import build_all

    paths = build_all(fmu_dir, report=lambda message: None)
    return {path.stem: path for path in paths}[model.fmu_name if isinstance(model, Plant) else model]
