"""Scene files: one study declared in TOML, validated before anything runs.

A scene says which plant and parameters, which excitation grid and which
results: DF points (``[[series]]``), time traces (``[[trace]]``), limit
cycles against a G(s) (``[[limit_cycle]]``) and figures (``[[figure]]``).
Everything is checked when the file is read (types, unknown keys, plant
parameter ranges through the solvers' own checks, grids, G(s), references
between sections), and a problem is one :class:`SceneError` naming the file,
the key and what is allowed. The schema is written with pydantic, which
gives typed, nested models and the path of every bad value.

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

import itertools
import math
import re
import sys
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Annotated, Literal, Optional

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from dfwb.base.errors import InputError
from dfwb.base.files import read_bytes
from dfwb.engine.describing import F_RANGE, OMEGA_RANGE
from dfwb.fmus.piecewise import PlantError
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
        raise InputError(f"Input should be one of {listed} (got {name!r})")
    return name


PlantName = Annotated[str, AfterValidator(_registered)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
Force = Annotated[float, Field(ge=F_RANGE[0], le=F_RANGE[1], allow_inf_nan=False)]  # [N]: what the engine accepts
Frequency = Annotated[float, Field(ge=OMEGA_RANGE[0], le=OMEGA_RANGE[1], allow_inf_nan=False)]  # [rad/s]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]
Name = Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_-]*$", max_length=64)]
FIGURE_KINDS = ("nyquist", "re_im", "harmonics", "trace", "limit_cycle", "paper")
MAX_BYTES = 1 << 20  # a scene file: a page of TOML, never a device or a data file read whole
MAX_SAMPLES = 2_000_000
MAX_TRACE_PERIODS = 100_000  # the horizon the stress suite covers; a trace is for looking at, not for soaking


@dataclass(frozen=True)
class PaperFigure:
    """What a paper figure draws from: its scene's series (name: plant) and traces (name: (plant, output))."""

    file: str
    series: dict
    traces: dict = field(default_factory=dict)
    harmonics: bool = False


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


class Strict(BaseModel):
    """No unknown keys, no silent conversions (an integer is a float, text is not)."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data):
        if isinstance(data, dict):
            unknown = [key for key in data if key not in cls.model_fields]
            if unknown:
                raise InputError(f"unknown key {unknown[0]!r} (allowed: {', '.join(cls.model_fields)})")
        return data


def _check_plant(plant, params):
    """Raise ValueError (pydantic's way) with the solver's message for a bad parameter set."""
    try:
        return find_plant(plant).check(params)
    except PlantError as error:
        raise InputError(str(error)) from None


class Frequencies(Strict):
    """Frequencies [rad/s]: ``[w1, w2, ...]`` or ``{log = [lo, hi, n], values = [...]}``, merged and sorted."""

    log: Optional[Annotated[list[Positive], Field(min_length=3, max_length=3)]] = None  # [lo, hi, n]
    values: list[Frequency] = []

    @model_validator(mode="before")
    @classmethod
    def _from_list(cls, data):
        return {"values": data} if isinstance(data, list) else data

    @model_validator(mode="after")
    def _not_empty(self):
        lo, hi = OMEGA_RANGE
        if self.log is not None and not (lo <= self.log[0] < self.log[1] <= hi and self.log[2] == int(self.log[2])
                                         and 2 <= self.log[2] <= 100_000):
            raise InputError(f"log = {self.log}: expected [lo, hi, n] with {lo:g} <= lo < hi <= {hi:g} rad/s and an "
                             "integer 2 <= n <= 100000")
        if self.log is None and not self.values:
            raise InputError("the frequency grid is empty: give values = [...] or log = [lo, hi, n]")
        return self

    def grid(self):
        spaced = []
        if self.log:
            import numpy as np  # only for a log-spaced grid

            spaced = [float(f"{w:.12g}") for w in np.geomspace(self.log[0], self.log[1], int(self.log[2]))]
        return sorted(set(spaced) | set(self.values))


class Series(Strict):
    """DF points of one plant over F x omega x the gridded parameters."""

    name: Name
    plant: PlantName
    params: dict[str, Finite] = {}
    grid: dict[str, Annotated[list[Finite], Field(min_length=1)]] = {}
    F: Annotated[list[Force], Field(min_length=1)]
    omega: Frequencies

    @model_validator(mode="after")
    def _plant_accepts(self):
        both = set(self.params) & set(self.grid)
        if both:
            raise InputError(f"{sorted(both)[0]!r} is both in params and in grid: give it in one of them")
        combos = grid_size(*(len(v) for v in self.grid.values()))
        if combos > MAX_POINTS:
            raise InputError(f"grid has {combos} parameter combinations: at most {MAX_POINTS}")
        for combo in self.combos():
            _check_plant(self.plant, combo)
        return self

    def size(self):
        """The number of points, counted without building them."""
        return grid_size(len(self.F), len(self.omega.grid()), *(len(v) for v in self.grid.values()))

    def combos(self):
        """The parameter sets: params plus each combination of the grid."""
        names = sorted(self.grid)
        return [dict(self.params, **dict(zip(names, values)))
                for values in itertools.product(*(self.grid[n] for n in names))]


class Trace(Strict):
    """A time response to F cos(omega t) from rest, sampled every ``step`` on [start, stop]."""

    name: Name
    plant: PlantName
    params: dict[str, Finite] = {}
    F: Force
    omega: Frequency
    start: NonNegative = 0.0
    stop: Positive
    step: Positive
    outputs: Annotated[list[str], Field(min_length=1)]

    @model_validator(mode="after")
    def _consistent(self):
        _check_plant(self.plant, self.params)
        if not self.start < self.stop:
            raise InputError(f"start = {self.start:g} must be < stop = {self.stop:g}")
        if self.stop / self.step > MAX_SAMPLES:
            raise InputError(f"stop / step = {self.stop / self.step:.3g} samples: at most {MAX_SAMPLES:g}")
        periods = self.stop * self.omega / (2 * math.pi)
        if periods > MAX_TRACE_PERIODS:
            raise InputError(f"stop = {self.stop:g} s is {periods:.3g} forcing periods at omega = "
                             f"{self.omega:g} rad/s: at most {MAX_TRACE_PERIODS:g}")
        known = [name for name, *_ in find_plant(self.plant).model.all_outputs()]
        for name in self.outputs:
            if name not in known:
                raise InputError(f"output {name!r} is not an output of plant {self.plant} "
                                 f"(allowed: {', '.join(known)})")
        return self


class LimitCycle(Strict):
    """Limit cycles of a plant under force = -G(s) position, optionally judged by co-simulation
    (``verify``) and against the exact closed loop's true cycles (``exact``)."""

    name: Name
    plant: PlantName
    params: dict[str, Finite] = {}
    G: Optional[str] = None
    num: Optional[list[Finite]] = None
    den: Optional[list[Finite]] = None
    F_range: Annotated[list[Force], Field(min_length=2, max_length=2)]
    omega_range: Annotated[list[Frequency], Field(min_length=2, max_length=2)]
    n_F: Annotated[int, Field(ge=2, le=1000)] = 16
    n_omega: Annotated[int, Field(ge=2, le=1000)] = 48
    verify: bool = False
    exact: bool = False
    samples_per_period: Annotated[int, Field(ge=16, le=100_000)] = 512

    @model_validator(mode="after")
    def _consistent(self):
        _check_plant(self.plant, self.params)
        if self.exact and find_plant(self.plant).loop is None:
            raise InputError(f"exact = true: plant {self.plant!r} has no exact closed loop")
        for key in ("F_range", "omega_range"):
            lo, hi = getattr(self, key)
            if not lo < hi:
                raise InputError(f"{key} = [{lo:g}, {hi:g}]: expected [lo, hi] with lo < hi")
        self.transfer_function()
        return self

    def transfer_function(self):
        """G(s) as a python-control TransferFunction (ValueError naming the problem)."""
        from dfwb.engine.transfer import from_coefficients, parse_transfer_function

        if (self.G is None) == (self.num is None and self.den is None):
            raise InputError("give the controller either as G = \"...\" or as num = [...] and den = [...]")
        if self.G is not None:
            return parse_transfer_function(self.G)
        return from_coefficients(self.num or [], self.den or [], names=("num", "den"))


class Figure(Strict):
    """A figure of the scene's results."""

    name: Name
    kind: Literal["nyquist", "re_im", "harmonics", "trace", "limit_cycle", "paper"]
    series: list[str] = []  # names of series, traces or limit cycles, by kind
    title: str = ""
    marks: list[Positive] = []  # frequencies marked on -1/N curves
    xlim: Optional[Annotated[list[Finite], Field(min_length=2, max_length=2)]] = None
    ylim: Optional[Annotated[list[Finite], Field(min_length=2, max_length=2)]] = None
    paper: Optional[str] = None  # kind = "paper": the paper's figure, e.g. "fig03"


class Engine(Strict):
    """Settings of the DF engine (see :class:`dfwb.engine.describing.DFEngine`)."""

    drive: Literal["internal", "input"] = "internal"
    samples_per_period: Annotated[int, Field(ge=4, le=100_000)] = 64
    max_periods: Annotated[int, Field(ge=25, le=100_000)] = 150


@dataclass(frozen=True)
class Point:
    """One DF point of a series."""

    series: str
    plant: str
    F: float
    omega: float
    params: dict


class Scene(Strict):
    """A study: see the module docstring; ``[[series]]``, ``[[trace]]``, ``[[limit_cycle]]``, ``[[figure]]``."""

    title: str
    description: str = ""
    harmonics: bool = False  # record X0..X10 of every point (figures of kind "harmonics" imply it)
    engine: Engine = Engine()
    series: list[Series] = []
    trace: list[Trace] = []
    limit_cycle: list[LimitCycle] = []
    figure: list[Figure] = []

    @field_validator("title")
    @classmethod
    def _has_title(cls, title):
        if not title.strip():
            raise InputError("the title is empty")
        return title

    @model_validator(mode="after")
    def _references(self):
        if not (self.series or self.trace or self.limit_cycle):
            raise InputError("the scene asks for nothing: give at least one [[series]], [[trace]] or [[limit_cycle]]")
        names = [item.name for group in (self.series, self.trace, self.limit_cycle, self.figure) for item in group]
        for name in names:
            if names.count(name) > 1:
                raise InputError(f"the name {name!r} is used twice: names must be unique in a scene")
        size = sum(s.size() for s in self.series) + sum(lc.n_F * lc.n_omega for lc in self.limit_cycle)
        if size > MAX_POINTS:
            raise InputError(f"{size} DF points (series and limit-cycle maps): at most {MAX_POINTS} in one scene "
                             "(split it)")
        for i, figure in enumerate(self.figure):
            _check_figure(self, i, figure)
        return self

    def points(self):
        """Every DF point of every series, F the outer loop (duplicates kept: they cost nothing twice)."""
        return [Point(s.name, s.plant, float(F), float(omega), combo)
                for s in self.series for F in s.F for combo in s.combos() for omega in s.omega.grid()]

    @property
    def needs_harmonics(self):
        return self.harmonics or any(
            f.kind == "harmonics" or (f.kind == "paper" and PAPER_FIGURES[f.paper].harmonics) for f in self.figure)


def _check_figure(scene, i, figure):
    where = f"figure[{i}] ({figure.name})"
    pools = {"nyquist": scene.series, "re_im": scene.series, "harmonics": scene.series,
             "trace": scene.trace, "limit_cycle": scene.limit_cycle}
    if figure.kind == "paper":
        if figure.paper not in PAPER_FIGURES:
            raise InputError(f"{where}: paper = {figure.paper!r} is not one of the paper's figures "
                             f"(allowed: {', '.join(PAPER_FIGURES)})")
        needed = PAPER_FIGURES[figure.paper]
        series = {s.name: s.plant for s in scene.series}
        traces = {t.name: (t.plant, t.outputs) for t in scene.trace}
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
    pool = {item.name for item in pools[figure.kind]}
    if not figure.series:
        raise InputError(f"{where}: series is empty (allowed: {', '.join(sorted(pool)) or 'none in this scene'})")
    for name in figure.series:
        if name not in pool:
            what = {"trace": "[[trace]]", "limit_cycle": "[[limit_cycle]]"}.get(figure.kind, "[[series]]")
            raise InputError(f"{where}: {name!r} is not a {what} of this scene "
                             f"(allowed: {', '.join(sorted(pool)) or 'none'})")


def _location(loc):
    text = ""
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        elif not re.match(r"^(function-|[a-z]+\[|tagged-union)", str(part)):
            text += ("." if text else "") + str(part)
    return text


def _message(error):
    message = error["msg"].removeprefix("Value error, ")
    if error["type"] not in ("value_error", "assertion_error") and "input" in error:
        value = error["input"]
        if not isinstance(value, (dict, list)) or len(repr(value)) < 60:
            message += f" (got {value!r})"
    return message


def parse_scene(text, source="<scene>"):
    """A validated :class:`Scene` from TOML text; SceneError names ``source``, the key and what is allowed."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise SceneError(f"{source}: not valid TOML: {error}") from None
    try:
        return Scene.model_validate(data)
    except ValidationError as error:
        first = error.errors(include_url=False)[0]
        where = _location(first["loc"])
        raise SceneError(f"{source}: {where + ': ' if where else ''}{_message(first)}") from None


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
    return parse_scene(text, str(path))

