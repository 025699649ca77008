"""Scene files: one study declared in TOML, validated before anything runs.

A scene says which plant and parameters, which excitation grid and which
results: DF points (``[[series]]``), time traces (``[[trace]]``), limit
cycles against a G(s) (``[[limit_cycle]]``), cycles followed in one
parameter with their bifurcations (``[[continuation]]``), hunting maps over
two parameters (``[[map]]``) and figures (``[[figure]]``).
Everything is checked when the file is read (types, unknown keys, plant
parameter ranges through the solvers' own checks, grids, G(s), references
between sections), and a problem is one :class:`SceneError` naming the file,
the key and what is allowed. The sections are records of
:mod:`dfwb.base.schema` (strict types, the path of every bad value).

Examples
--------
>>> scene = parse_scene('''
... title = "friction at two forces"
... [[series]]
... name = "friction"
... plant = "friction"
... F = [10, 50]
... omega = {log = [0.1, 10, 3]}
... ''', "example.toml")
>>> [(p.F, p.omega) for p in scene.points()][:3]
[(10.0, 0.1), (10.0, 1.0), (10.0, 10.0)]
>>> try:
...     parse_scene('title = "t"\\n[[series]]\\nname = "a"\\nplant = "friction"\\nF = [1]\\nomega = [1]\\n'
...                 'params = {eps = 0.5}', "bad.toml")
... except SceneError as error:
...     print(error)
bad.toml: series[0]: unknown parameter 'eps' for plant friction (allowed: B, Dv, Fc, Fs, M, v0, x0)
"""

import functools
import itertools
import math
import sys
from dataclasses import dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import Optional

from dfwb.base.defaults import BRANCH_POINTS, DF_MAP_SIZE, DF_PERIODS, JUDGE_SAMPLES, SAMPLES_PER_PERIOD
from dfwb.base.errors import InputError, fmu_only
from dfwb.base.files import read_bytes
from dfwb.base.grids import log_grid
from dfwb.base.schema import (
    Boolean,
    Checked,
    Integer,
    Invalid,
    ListOf,
    Number,
    OneOf,
    Table,
    TableOf,
    Text,
    record,
    rule,
    shown,
)
from dfwb.engine.compensators import CHOICES, check_judged
from dfwb.engine.describing import F_RANGE, OMEGA_RANGE
from dfwb.fmus.piecewise import PlantError
from dfwb.foreign.description import KINDS
from dfwb.foreign.plant import is_fmu_path
from dfwb.plants import names
from dfwb.plants import plant as find_plant
from dfwb.studies.sweep import MAX_POINTS, grid_size

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def _registered(name):
    """A registered plant's name (the registry, not this file, says which exist)."""
    known = names()
    if name not in known:
        listed = ", ".join(repr(n) for n in known)
        raise InputError(f"Input should be one of {listed} (got {shown(name)})")
    return name


def _plant_or_fmu(name):
    """A registered plant's name, or the path of a user's FMU (opened with the section's input and output)."""
    return name if is_fmu_path(name) else _registered(name)


def section_plant(section):
    """The plant a section names: a registry entry, or the user's FMU with the section's ``input``,
    ``output`` and ``kind`` (checked: :func:`dfwb.foreign.plant.fmu_plant`)."""
    if not is_fmu_path(section.plant):
        if (section.input, section.output, section.kind) != (None, None, None):
            raise InputError(f"input, output and kind are for a plant given as an FMU: plant "
                             f"{section.plant!r} is dfwb's own")
        return find_plant(section.plant)
    path = Path(section.plant)
    try:
        stat = path.stat()
    except OSError as error:
        raise InputError(f"plant = {shown(section.plant)}: cannot read the FMU ({error.strerror})") from None
    return _fmu_plant(str(path), stat.st_mtime_ns, stat.st_size, section.input, section.output, section.kind)


@functools.lru_cache(maxsize=32)
def _fmu_plant(path, mtime, size, input, output, kind):
    """The checked FMU plant, once per file version (its name, time and size), variables and kind."""
    from dfwb.foreign.plant import fmu_plant

    try:
        return fmu_plant(path, input=input, output=output, kind=kind)
    except PlantError as error:
        raise InputError(str(error)) from None


def _has_title(title):
    if not title.strip():
        raise InputError("the title is empty")
    return title


PlantOrFMU = Checked(Text(), _plant_or_fmu)  # a registered plant, or a user's FMU
Variable = Text(max_length=200)  # an FMU's input or output
FMUKind = OneOf(*KINDS)  # how a user's FMU runs
MapSide = Integer(ge=2, le=1000)  # a DF map's forces or frequencies
Positive = Number(gt=0)
Force = Number(ge=F_RANGE[0], le=F_RANGE[1])  # [N]: what the engine accepts
Frequency = Number(ge=OMEGA_RANGE[0], le=OMEGA_RANGE[1])  # [rad/s]
ForceRange = ListOf(Force, min_length=2, max_length=2)  # [lo, hi]
FrequencyRange = ListOf(Frequency, min_length=2, max_length=2)
NonNegative = Number(ge=0)
Finite = Number()
Name = Text(pattern=r"[A-Za-z_][A-Za-z0-9_-]*", max_length=64)
Params = TableOf(Finite)
# a loop's parameters: numbers, or the text of a compensator's choice (signal = "control"), checked by its family
LoopParams = TableOf(lambda value: value if isinstance(value, str) else Finite(value))
FIGURE_KINDS = ("nyquist", "re_im", "harmonics", "trace", "limit_cycle", "continuation", "map", "paper")
MAX_BYTES = 1 << 20  # a scene file: a page of TOML, never a device or a data file read whole
MAX_SAMPLES = 2_000_000
MAX_MESSAGE = 300  # characters of a SceneError: the file, the key, the problem and what is allowed
MAX_TRACE_PERIODS = 100_000  # the horizon the stress suite covers; a trace is for looking at, not for soaking
MAX_STUDIES = 100  # continuations and maps in one scene: each takes seconds to minutes
SECTION = dataclass(frozen=True, kw_only=True)  # a scene's table: fields by name, read by dfwb.base.schema.record


@dataclass(frozen=True)
class PaperFigure:
    """What a paper figure draws from: its scene's series (name: plant) and traces (name: (plant, output))."""

    file: str
    series: dict
    traces: dict = field(default_factory=dict)
    harmonics: bool = False


FRICTION_F = [10.0, 20.0, 30.0, 40.0, 50.0]  # the paper's forces of Fig. 3-6 [N]
EPS_FIG8 = [0.1, 0.3, 0.5, 0.7, 0.9]  # its gap ratios of Fig. 8 and 9 (the report's validity table needs them
EPS_FIG9 = [0.2, 0.8]  # without loading the plots)
PAPER_FIGURES = {  # the paper's figures (dfwb.studies.paper draws them), by id
    "fig03": PaperFigure("fig03_friction_nyquist", {"friction": "friction", "friction_linear": "friction"}),
    "fig04": PaperFigure("fig04_friction_re_im", {"friction": "friction", "friction_linear": "friction",
                                                  "friction_karnopp": "friction"}),
    "fig05": PaperFigure("fig05_friction_time", {}, {"friction_F10": ("friction", "x"),
                                                     "friction_F50": ("friction", "x")}),
    "fig06": PaperFigure("fig06_friction_harmonics", {"friction": "friction"}, harmonics=True),
    "fig08": PaperFigure("fig08_backlash_nyquist_eps", {"backlash_F50": "backlash"}),
    "fig09": PaperFigure("fig09_backlash_nyquist_F", {"backlash_F": "backlash", "backlash_F50": "backlash"}),
    "fig10": PaperFigure("fig10_backlash_re_im", {"static": "static-backlash", "backlash_F50": "backlash"}),
    "fig11": PaperFigure("fig11_backlash_velocity", {"backlash_F50": "backlash"},
                         {"backlash_w20_eps08": ("backlash", "v1"), "backlash_w40_eps02": ("backlash", "v1")}),
    "fig12": PaperFigure("fig12_backlash_harmonics", {"backlash_F50": "backlash"}, harmonics=True),
}


class SceneError(InputError):
    """A scene that cannot run: one line naming the file, the key and what is allowed."""


def _check_plant(plant, params):
    """The solver's message for a bad parameter set, as an InputError (the section's problem)."""
    try:
        return find_plant(plant).check(params)
    except PlantError as error:
        raise InputError(str(error)) from None


@SECTION
class Frequencies:
    """Frequencies [rad/s]: ``[w1, w2, ...]`` or ``{log = [lo, hi, n], values = [...]}``, merged and sorted."""

    log: Optional[list] = rule(ListOf(Positive, min_length=3, max_length=3), None)  # [lo, hi, n]
    values: list = rule(ListOf(Frequency), [])

    def __post_init__(self):
        lo, hi = OMEGA_RANGE
        if self.log is not None and not (lo <= self.log[0] < self.log[1] <= hi and self.log[2] == int(self.log[2])
                                         and 2 <= self.log[2] <= 100_000):
            raise InputError(f"log = {self.log}: expected [lo, hi, n] with {lo:g} <= lo < hi <= {hi:g} rad/s and an "
                             "integer 2 <= n <= 100000")
        if self.log is None and not self.values:
            raise InputError("the frequency grid is empty: give values = [...] or log = [lo, hi, n]")

    def grid(self):
        spaced = log_grid(*self.log) if self.log else []
        return sorted(set(spaced) | set(self.values))


Omega = Table(Frequencies, shorthand=lambda value: {"values": value} if isinstance(value, list) else value)


@SECTION
class Series:
    """DF points of one plant over F x omega x the gridded parameters."""

    name: str = rule(Name)
    plant: str = rule(PlantOrFMU)
    input: Optional[str] = rule(Variable, None)  # a user's FMU: its force input and position output
    output: Optional[str] = rule(Variable, None)
    kind: Optional[str] = rule(FMUKind, None)  # ... and how it runs
    params: dict = rule(Params, {})
    grid: dict = rule(TableOf(ListOf(Finite, min_length=1)), {})
    F: list = rule(ListOf(Force, min_length=1))
    omega: Frequencies = rule(Omega)

    def __post_init__(self):
        both = set(self.params) & set(self.grid)
        if both:
            raise InputError(f"{sorted(both)[0]!r} is both in params and in grid: give it in one of them")
        combos = grid_size(*(len(v) for v in self.grid.values()))
        if combos > MAX_POINTS:
            raise InputError(f"grid has {combos} parameter combinations: at most {MAX_POINTS}")
        # each parameter set is checked by the Scene, once the scene's size is known to be within bounds

    def size(self):
        """The number of points, counted without building them."""
        return grid_size(len(self.F), len(self.omega.grid()), *(len(v) for v in self.grid.values()))

    def combos(self):
        """The parameter sets: params plus each combination of the grid."""
        names = sorted(self.grid)
        return [dict(self.params, **dict(zip(names, values)))
                for values in itertools.product(*(self.grid[n] for n in names))]


@SECTION
class Trace:
    """A time response to F cos(omega t) from rest, sampled every ``step`` on [start, stop]."""

    name: str = rule(Name)
    plant: str = rule(PlantOrFMU)
    input: Optional[str] = rule(Variable, None)  # a user's FMU: its force input and position output
    output: Optional[str] = rule(Variable, None)
    kind: Optional[str] = rule(FMUKind, None)  # ... and how it runs
    params: dict = rule(Params, {})
    F: float = rule(Force)
    omega: float = rule(Frequency)
    start: float = rule(NonNegative, 0.0)
    stop: float = rule(Positive)
    step: float = rule(Positive)
    outputs: list = rule(ListOf(Text(), min_length=1))

    def __post_init__(self):
        spec = section_plant(self)
        _check_plant(spec, self.params)
        if not self.start < self.stop:
            raise InputError(f"start = {self.start:g} must be < stop = {self.stop:g}")
        if self.stop / self.step > MAX_SAMPLES:
            raise InputError(f"stop / step = {self.stop / self.step:.3g} samples: at most {MAX_SAMPLES:g}")
        periods = self.stop * self.omega / (2 * math.pi)
        if periods > MAX_TRACE_PERIODS:
            raise InputError(f"stop = {self.stop:g} s is {periods:.3g} forcing periods at omega = "
                             f"{self.omega:g} rad/s: at most {MAX_TRACE_PERIODS:g}")
        known = spec.info.real_outputs() if getattr(spec, "foreign", False) else \
            [name for name, *_ in spec.model.all_outputs()]
        for name in self.outputs:
            if name not in known:
                raise InputError(f"output {shown(name)} is not an output of plant {self.plant} "
                                 f"(allowed: {', '.join(known)})")


def _check_ranges(section, spec):
    """A section's F_range and omega_range: each [lo, hi] with lo < hi, and both given for a user's FMU."""
    if getattr(spec, "foreign", False) and (section.F_range is None or section.omega_range is None):
        raise InputError("give F_range and omega_range: dfwb cannot derive them from a user's FMU")
    for key in ("F_range", "omega_range"):
        if getattr(section, key) is not None:
            lo, hi = getattr(section, key)
            if not lo < hi:
                raise InputError(f"{key} = [{lo:g}, {hi:g}]: expected [lo, hi] with lo < hi")


def _no_fmu_keys(section):
    """A section of dfwb's own plant given a user's FMU's keys (away from their defaults): refused, never
    ignored."""
    defaults = {f.name: f.default for f in fields(section)}
    fmu_only({key: (getattr(section, key), defaults[key]) for key in ("F_range", "omega_range", "n_F", "n_omega",
                                                                      "samples") if key in defaults},
             "dfwb's own plants derive their ranges")


def _controller(section):
    """G as a section gives it: the expression (with parameters), or (num, den), checked."""
    from dfwb.engine.transfer import checked_pair

    if (section.G is None) == (section.num is None and section.den is None):
        raise InputError("give the controller either as G = \"...\" or as num = [...] and den = [...]")
    if section.G is not None:
        return section.G
    return checked_pair(section.num or [], section.den or [], names=("num", "den"))


def _family(section, free=()):
    """The :class:`~dfwb.engine.family.LoopFamily` of a section's plant, G and params (checked: text only for a
    compensator's choice, never converted to a number)."""
    from dfwb.engine.family import LoopFamily

    for name, value in section.params.items():
        if isinstance(value, str) and name not in CHOICES:
            raise InputError(f"params.{name} = {value!r:.60}: text where a number belongs (give a number; text is "
                             f"only for a choice: {', '.join(CHOICES)})")
    try:
        plant = section_plant(section) if hasattr(section, "input") else section.plant
        return LoopFamily(plant, _controller(section), section.params, free=free, compensate=section.compensate)
    except PlantError as error:
        raise InputError(str(error)) from None


@SECTION
class _Loop:
    """What every section of a plant in feedback with G(s) gives: the plant (or a user's FMU, its variables,
    how it runs and its DF map), the controller and the parameters."""

    name: str = rule(Name)
    plant: str = rule(PlantOrFMU)
    input: Optional[str] = rule(Variable, None)  # a user's FMU: its force input and position output
    output: Optional[str] = rule(Variable, None)
    kind: Optional[str] = rule(FMUKind, None)  # ... and how it runs
    params: dict = rule(LoopParams, {})  # the plant's parameters, G's and the compensators'
    compensate: list = rule(ListOf(Text(max_length=64), max_length=8), [])  # compensators (dfwb.engine.compensators)
    G: Optional[str] = rule(Text(), None)
    num: Optional[list] = rule(ListOf(Finite), None)
    den: Optional[list] = rule(ListOf(Finite), None)
    F_range: Optional[list] = rule(ForceRange, None)  # None: derived (a user's FMU: required)
    omega_range: Optional[list] = rule(FrequencyRange, None)
    n_F: Optional[int] = rule(MapSide, None)  # None: the DF's own size (DF_MAP_SIZE, or its engine's map_size)
    n_omega: Optional[int] = rule(MapSide, None)

    def map_size(self):
        """(n_F, n_omega) of a DF map computed here, before its engine is known: as given, else DF_MAP_SIZE
        (the largest default: a dithered loop's DF maps fewer)."""
        return self.n_F or DF_MAP_SIZE[0], self.n_omega or DF_MAP_SIZE[1]

    def controller(self):
        """G as given: the expression (with parameters), or (num, den)."""
        return _controller(self)

    def exact_plant(self, what):
        """The section's plant, refused unless it has an exact closed loop (to ``what``) or is a user's FMU
        (then with its DF map's ranges)."""
        spec = section_plant(self)
        if getattr(spec, "foreign", False):
            _check_ranges(self, spec)
        elif spec.loop is None:
            raise InputError(f"plant {self.plant!r} has no exact closed loop to {what}")
        else:
            _no_fmu_keys(self)
        return spec


@SECTION
class LimitCycle(_Loop):
    """Limit cycles of a plant under force = -G(s) position, optionally judged by co-simulation
    (``verify``) and against the exact closed loop's true cycles (``exact``)."""

    verify: bool = rule(Boolean(), False)
    exact: bool = rule(Boolean(), False)
    samples_per_period: int = rule(Integer(ge=16, le=100_000), JUDGE_SAMPLES)

    def __post_init__(self):
        spec = section_plant(self)
        if self.exact and spec.loop is None and not getattr(spec, "foreign", False):
            raise InputError(f"exact = true: plant {self.plant!r} has no exact closed loop")
        if getattr(spec, "foreign", False) and self.verify:
            raise InputError("verify runs dfwb's own closed-loop FMUs: not for a user's FMU (use exact = true)")
        _check_ranges(self, spec)
        check_judged(self.family().compensation, self.exact, self.verify)

    def family(self):
        """The :class:`~dfwb.engine.family.LoopFamily` of the plant, G and params (checked)."""
        return _family(self)


@SECTION
class Continuation(_Loop):
    """Limit cycles (true and predicted) followed in one parameter of G or of the plant, with bifurcations."""

    parameter: str = rule(Text(max_length=64))
    start: float = rule(Finite)
    stop: float = rule(Finite)
    sources: list = rule(ListOf(OneOf("truth", "df"), min_length=1, max_length=2), ["truth", "df"])
    max_points: int = rule(Integer(ge=2, le=10_000), BRANCH_POINTS)
    samples: int = rule(Integer(ge=2, le=1000), 11)  # a user's FMU: the values its true cycles are searched at

    def __post_init__(self):
        from dfwb.studies.continuation import check_parameter, check_somewhere

        spec = self.exact_plant("follow cycles of")
        if getattr(spec, "foreign", False) and spec.kind != "model-exchange":
            raise InputError("the DF and the cycles of a co-simulation FMU are too rough to follow: give "
                             "kind = \"model-exchange\" where the FMU offers it")
        if self.parameter in self.params:
            raise InputError(f"{self.parameter} is the parameter followed: give its range, not a value in params")
        family = _family(self, free=(self.parameter,))
        check_parameter(family, self.parameter, self.start, self.stop)
        check_somewhere(family, [{self.parameter: value} for value in (self.start, self.stop)],
                        "both ends of the range")


@SECTION
class Axis:
    """A map's axis: a parameter of G or of the plant from ``start`` to ``stop`` in ``n`` cells."""

    name: str = rule(Text(max_length=64))
    start: float = rule(Finite)
    stop: float = rule(Finite)
    n: int = rule(Integer(ge=2, le=1000))


@SECTION
class Map(_Loop):
    """A hunting map: every cell of two parameters classified by the truth and by the DF."""

    x: Axis = rule(Table(Axis))
    y: Axis = rule(Table(Axis))
    amplitudes: int = rule(Integer(ge=1, le=100), 5)
    curves: bool = rule(Boolean(), True)

    def __post_init__(self):
        from dfwb.studies.continuation import check_parameter, check_somewhere
        from dfwb.studies.hunting import MAX_CELLS

        self.exact_plant("classify")
        if self.x.name == self.y.name:
            raise InputError(f"x and y are both {self.x.name}: a map needs two different parameters")
        for axis in (self.x, self.y):
            if axis.name in self.params:
                raise InputError(f"{axis.name} is an axis of the map: give its range, not a value in params")
        family = _family(self, free=(self.x.name, self.y.name))
        for axis in (self.x, self.y):
            check_parameter(family, axis.name, axis.start, axis.stop)
        check_somewhere(family, [{self.x.name: a, self.y.name: b} for a in (self.x.start, self.x.stop)
                                 for b in (self.y.start, self.y.stop)], "every corner of the map")
        if self.x.n * self.y.n > MAX_CELLS:
            raise InputError(f"a map of {self.x.n} x {self.y.n} = {self.x.n * self.y.n} cells: at most {MAX_CELLS}")

    def axes(self):
        """(x, y) as (name, start, stop, n)."""
        return tuple((a.name, a.start, a.stop, a.n) for a in (self.x, self.y))


@SECTION
class Figure:
    """A figure of the scene's results."""

    name: str = rule(Name)
    kind: str = rule(OneOf(*FIGURE_KINDS))
    series: list = rule(ListOf(Text()), [])  # names of series, traces or limit cycles, by kind
    title: str = rule(Text(), "")
    marks: list = rule(ListOf(Positive), [])  # frequencies marked on -1/N curves
    xlim: Optional[list] = rule(ListOf(Finite, min_length=2, max_length=2), None)
    ylim: Optional[list] = rule(ListOf(Finite, min_length=2, max_length=2), None)
    paper: Optional[str] = rule(Text(), None)  # kind = "paper": the paper's figure, e.g. "fig03"

    def pngs(self):
        """The PNG file names this figure writes (each with an SVG twin), known before drawing."""
        if self.kind == "paper":
            return [f"{PAPER_FIGURES[self.paper].file}.png"]
        if self.kind in ("limit_cycle", "continuation", "map"):
            return [f"{self.name}_{name}.png" for name in self.series]
        return [f"{self.name}.png"]

    def files(self):
        """Every file this figure writes: each PNG and its SVG twin."""
        return [f"{png[:-len('.png')]}{suffix}" for png in self.pngs() for suffix in (".png", ".svg")]


@SECTION
class Engine:
    """Settings of the DF engine (see :class:`dfwb.engine.describing.DFEngine`)."""

    drive: str = rule(OneOf("internal", "input"), "internal")
    samples_per_period: int = rule(Integer(ge=4, le=100_000), SAMPLES_PER_PERIOD)
    max_periods: int = rule(Integer(ge=25, le=100_000), DF_PERIODS)
    rtol: Optional[float] = rule(Number(ge=1e-13, le=1e-2), None)  # a user's FMU's tolerance (None: its kind's)


@dataclass(frozen=True)
class Point:
    """One DF point of a series."""

    series: str
    plant: str
    F: float
    omega: float
    params: dict


@SECTION
class Scene:
    """A study: see the module docstring; ``[[series]]``, ``[[trace]]``, ``[[limit_cycle]]``, ``[[continuation]]``,
    ``[[map]]``, ``[[figure]]``."""

    title: str = rule(Checked(Text(), _has_title))
    description: str = rule(Text(), "")
    harmonics: bool = rule(Boolean(), False)  # record X0..X10 of every point (figures of kind "harmonics" imply it)
    engine: Engine = rule(Table(Engine), Engine())
    series: list = rule(ListOf(Table(Series)), [])
    trace: list = rule(ListOf(Table(Trace)), [])
    limit_cycle: list = rule(ListOf(Table(LimitCycle)), [])
    continuation: list = rule(ListOf(Table(Continuation)), [])
    map: list = rule(ListOf(Table(Map)), [])
    figure: list = rule(ListOf(Table(Figure)), [])

    def __post_init__(self):
        if not (self.series or self.trace or self.limit_cycle or self.continuation or self.map):
            raise InputError("the scene asks for nothing: give at least one [[series]], [[trace]], [[limit_cycle]], "
                             "[[continuation]] or [[map]]")
        seen = set()
        for group in (self.series, self.trace, self.limit_cycle, self.continuation, self.map, self.figure):
            for item in group:
                if item.name in seen:
                    raise InputError(f"the name {item.name!r} is used twice: names must be unique in a scene")
                seen.add(item.name)
        if len(self.continuation) + len(self.map) > MAX_STUDIES:
            raise InputError(f"{len(self.continuation) + len(self.map)} continuations and maps: at most {MAX_STUDIES} "
                             "in one scene (split it)")
        if self.map:  # (a scene without maps does not load them)
            from dfwb.studies.hunting import MAX_CELLS

            cells = sum(m.x.n * m.y.n for m in self.map)
            if cells > MAX_CELLS:
                raise InputError(f"{cells} map cells in all: at most {MAX_CELLS} in one scene (split it)")
        size = sum(s.size() for s in self.series) + sum(math.prod(lc.map_size()) for lc in self.limit_cycle)
        if size > MAX_POINTS:
            raise InputError(f"{size} DF points (series and limit-cycle maps): at most {MAX_POINTS} in one scene "
                             "(split it)")
        self._one_fmu_plant_each()
        if self.engine.rtol is not None and not any(
                is_fmu_path(section.plant)
                for section in itertools.chain(self.series, self.trace, self.limit_cycle, self.continuation,
                                               self.map)):
            raise Invalid("rtol is the tolerance of a user's FMU: this scene names none (dfwb's own plants are "
                          "computed exactly)", ["engine"])
        for i, series in enumerate(self.series):  # at most MAX_POINTS parameter sets in all: bounded work
            for combo in series.combos():
                try:
                    _check_plant(section_plant(series), combo)
                except InputError as error:
                    raise Invalid(str(error), ["series", i]) from None
        computed = Computed(self)
        files = {}
        for i, figure in enumerate(self.figure):
            _check_figure(computed, i, figure)
            for png in figure.pngs():  # (checked: a paper figure names one of PAPER_FIGURES)
                if png in files:
                    raise Invalid(f"figure {figure.name} writes {png}, as figure {files[png]} does: rename one "
                                  "(one figure per file)", ["figure", i])
                files[png] = figure.name

    def _one_fmu_plant_each(self):
        """A user's FMU named in several sections is named with the same input, output and kind in each
        (results and the cache know the plant by its file)."""
        chosen = {}
        for group, sections in (("series", self.series), ("trace", self.trace), ("limit_cycle", self.limit_cycle),
                                ("continuation", self.continuation), ("map", self.map)):
            for i, section in enumerate(sections):
                if is_fmu_path(section.plant):
                    variables = (section.input, section.output, section.kind)
                    if chosen.setdefault(section.plant, variables) != variables:
                        raise Invalid(f"plant {shown(section.plant)} is named with input, output, kind = "
                                      f"{variables} here and {chosen[section.plant]} before: one input, output and "
                                      "kind per FMU in a scene", [group, i])

    def plant(self, name):
        """The plant a section of this scene names by ``name`` (a user's FMU with its input and output)."""
        for section in itertools.chain(self.series, self.trace, self.limit_cycle, self.continuation, self.map):
            if section.plant == name:
                return section_plant(section)
        return find_plant(name)

    def points(self):
        """Every DF point of every series, F the outer loop (duplicates kept: they cost nothing twice)."""
        return [Point(s.name, s.plant, float(F), float(omega), combo)
                for s in self.series for F in s.F for combo in s.combos() for omega in s.omega.grid()]

    @property
    def needs_harmonics(self):
        return self.harmonics or any(
            f.kind == "harmonics" or (f.kind == "paper" and PAPER_FIGURES[f.paper].harmonics) for f in self.figure)


class Computed:
    """What a scene's figures may draw, by name, gathered once: {series: plant}, {trace: (plant, outputs)}, cycles."""

    def __init__(self, scene):
        self.series = {s.name: s.plant for s in scene.series}
        self.traces = {t.name: (t.plant, t.outputs) for t in scene.trace}
        self.pools = {"nyquist": set(self.series), "re_im": set(self.series), "harmonics": set(self.series),
                      "trace": set(self.traces), "limit_cycle": {lc.name for lc in scene.limit_cycle},
                      "continuation": {c.name for c in scene.continuation}, "map": {m.name for m in scene.map}}


def _check_figure(computed, i, figure):
    where = f"figure[{i}] ({figure.name})"
    if figure.kind == "paper":
        if figure.paper not in PAPER_FIGURES:
            raise InputError(f"{where}: paper = {shown(figure.paper)} is not one of the paper's figures "
                             f"(allowed: {', '.join(PAPER_FIGURES)})")
        needed = PAPER_FIGURES[figure.paper]
        series, traces = computed.series, computed.traces
        for name, plant in needed.series.items():
            if series.get(name) != plant:
                raise InputError(f"{where}: the paper's {figure.paper} needs a [[series]] {name!r} of plant {plant} "
                                 f"(see scenes/{needed.file}.toml)")
        for name, (plant, output) in needed.traces.items():
            if name not in traces or traces[name][0] != plant or output not in traces[name][1]:
                raise InputError(f"{where}: the paper's {figure.paper} needs a [[trace]] {name!r} of plant {plant} "
                                 f"with output {output!r} (see scenes/{needed.file}.toml)")
        return
    if figure.paper is not None:
        raise InputError(f"{where}: paper is only allowed with kind = \"paper\"")
    pool = computed.pools[figure.kind]
    if not figure.series:
        raise InputError(f"{where}: series is empty (allowed: {', '.join(sorted(pool)) or 'none in this scene'})")
    for name in figure.series:
        if name not in pool:
            what = {"trace": "[[trace]]", "limit_cycle": "[[limit_cycle]]", "continuation": "[[continuation]]",
                    "map": "[[map]]"}.get(figure.kind, "[[series]]")
            raise InputError(f"{where}: {shown(name)} is not a {what} of this scene "
                             f"(allowed: {', '.join(sorted(pool)) or 'none'})")


def _one_line(message):
    """A message as one line of readable length: newlines escaped, the middle of a very long one cut."""
    message = message.replace("\r", "\\r").replace("\n", "\\n")
    return message if len(message) <= MAX_MESSAGE else f"{message[:200]} ... {message[-90:]}"


def parse_scene(text, source="<scene>", folder=None):
    """A validated :class:`Scene` from TOML text; SceneError names ``source``, the key and what is allowed.

    ``folder``: where a relative FMU path (``plant = "drive.fmu"``) starts from (the scene file's folder;
    default the current one)."""
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise SceneError(f"{source}: not valid TOML: arrays or tables nested too deeply") from None
    except tomllib.TOMLDecodeError as error:
        raise SceneError(_one_line(f"{source}: not valid TOML: {error}")) from None
    except ValueError:  # an integer beyond Python's digit limit for text (4300 digits)
        raise SceneError(f"{source}: not valid TOML for dfwb: an integer of more than 4300 digits") from None
    _anchor_fmus(data, Path(folder) if folder is not None else None)
    try:
        return record(Scene, data)
    except Invalid as error:
        raise SceneError(_one_line(f"{source}: {error.where + ': ' if error.where else ''}{error}")) from None


def _anchor_fmus(data, folder):
    """Make each FMU path of the sections that take one start from ``folder`` (the checks come later)."""
    for group in ("series", "trace", "limit_cycle", "continuation", "map"):
        sections = data.get(group)
        for section in sections if isinstance(sections, list) else ():
            plant = section.get("plant") if isinstance(section, dict) else None
            if folder is not None and isinstance(plant, str) and is_fmu_path(plant) and not Path(plant).is_absolute():
                section["plant"] = str(folder / plant)


def shipped_scenes(prefix):
    """Paths of the scenes shipped with dfwb (package ``dfwb.scenes``) whose names start with ``prefix``."""
    return sorted(Path(str(path)) for path in resources.files("dfwb.scenes").iterdir()
                  if path.name.startswith(prefix) and path.name.endswith(".toml"))


def load_scene(path):
    """The validated scene in the TOML file ``path``."""
    path = Path(path)
    try:
        text = read_bytes(path, MAX_BYTES, "scene").decode("utf-8")
    except OSError as error:
        raise SceneError(f"{path}: cannot read the scene ({error.strerror})") from None
    except UnicodeDecodeError as error:
        raise SceneError(f"{path}: not UTF-8 text (byte {error.start}): a scene is a TOML file") from None
    if text.startswith("\ufeff"):
        raise SceneError(f"{path}: starts with a byte-order mark (BOM), which TOML does not allow: save it as UTF-8 "
                         "without BOM")
    return parse_scene(text, str(path), path.parent)

