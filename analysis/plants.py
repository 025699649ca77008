"""The plants the workbench knows: names, FMUs, outputs, Poincare states, parameters.

A plant is named on the command line (``friction``, ``backlash``,
``static-backlash``) and maps to one FMU. Its parameters are checked here,
against the ranges the engine accepts and with the exact solver's own
validation, before any FMU is touched, so a bad value becomes one clear line
instead of an FMU failing (or running without end) mid-sweep.
"""

from dataclasses import dataclass
from pathlib import Path

from dfwb.fmus import facade
from dfwb.fmus.piecewise import PlantError, check

DEFAULT_FMU_DIR = Path("build/fmus")
RESERVED = {"F", "omega", "phi", "harmonics"}  # set by the engine itself
_CHECKED = {}  # (plant, model, parameter items) -> validated parameters: sweeps repeat the same sets

# The parameter ranges the engine accepts: (low, high, unit). Masses, clearances, slopes,
# forces and velocities: the edges ``dfwb stress`` covers and the engine computes (the
# solvers accept more). Positions only translate the plant, which the engine removes
# (Plant.at_origin): their bound merely keeps the mean and k x0 far from overflow.
# eps and gap0 keep the solver's own ranges ([0, 1] and [0, h]).
MASS = (1e-6, 1e6, "kg")
FORCE = (0.0, 1e9, "N")
VELOCITY = (-1e6, 1e6, "m/s")
POSITION = (-1e30, 1e30, "m")
RANGES = {
    "M": MASS, "M1": MASS, "M2": MASS,
    "B": (0.0, 1e9, "N.s/m"), "Fc": FORCE, "Fs": FORCE, "Dv": (0.0, 1e3, "m/s"),
    "h": (1e-9, 1e3, "m"), "k": (1e-6, 1e6, ""),
    "x0": POSITION, "x1_0": POSITION,
    "v0": VELOCITY, "v1_0": VELOCITY, "v2_0": VELOCITY,
}


def check_range(name, value, low, high, unit=""):
    """PlantError naming the value and the range unless low <= value <= high (a finite number)."""
    check(name, value, lambda: low <= value <= high, f"{name} must be in [{low:g}, {high:g}] {unit}".rstrip())


@dataclass(frozen=True)
class Plant:
    name: str
    model: type  # the FMI facade class
    output: str  # the signal whose DF is taken
    section: tuple  # continuous Poincare state, read at whole periods
    modes: tuple  # discrete Poincare state
    initial: dict  # Poincare state name -> the parameter that sets it at t = 0 (shooting)
    shifts: dict  # how each section component (and the output) moves when the plant is translated by 1 m
    position: str  # the parameter that translates the whole plant

    def _per_metre(self, name, params):
        """How signal ``name`` moves when the plant is translated by 1 m."""
        shift = self.shifts.get(name, 0.0)
        return dict(self.defaults(), **params).get("k", 1.0) if shift == "k" else shift

    def translation(self, params):
        """Per section component, its change under a translation of the plant by 1 m."""
        return tuple(self._per_metre(name, params) for name in self.section)

    def at_origin(self, params):
        """(params with the plant translated to position 0, the output's offset there).

        The forces depend on velocities and relative positions only, so the
        output of a translated plant is the same motion plus a constant: the
        engine runs the plant at the origin, where a position of 1e20 m cannot
        round the motion away, and adds the offset to the mean X_0 only.
        """
        value = dict(self.defaults(), **params)[self.position]
        return dict(params, **{self.position: 0.0}), value * self._per_metre(self.output, params)

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
            if name in RANGES:
                check_range(name, values[name], *RANGES[name])
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
# velocities and relative positions only): "shifts" says how each section component
# moves, "position" which parameter translates the plant.
PLANTS = {
    "friction": Plant("friction", facade.FrictionMass, "x", ("x", "v"), ("mode",), {"x": "x0", "v": "v0"},
                      {"x": 1.0}, "x0"),
    "backlash": Plant("backlash", facade.TwoMassBacklash, "x1", ("x1", "v1", "gap", "v2"), ("contact",),
                      {"x1": "x1_0", "v1": "v1_0", "gap": "gap0", "v2": "v2_0"}, {"x1": 1.0}, "x1_0"),
    "static-backlash": Plant("static-backlash", facade.StaticBacklash, "y", ("x", "v", "y"), ("engaged",), {},
                             {"x": 1.0, "y": "k"}, "x0"),
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
