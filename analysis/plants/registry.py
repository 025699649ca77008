"""The plant contract: one registry entry per plant carries every fact the rest of dfwb needs.

A plant is its solver (anything that implements :class:`dfwb.fmus.Solver`),
its FMU facade (a :class:`dfwb.fmus.facade.PlantFMU`) and one
:class:`Plant` entry, registered with :func:`register`. The command line's
choices, the scene schema, the describing-function engine, the closed-loop
judge, the benchmark, the stress suite, the demo and the tests' lists of
plants all read the registry; none of them names a plant.

Parameters are checked here, against the ranges the engine accepts and with
the solver's own validation, before any FMU is touched, so a bad value
becomes one clear line instead of an FMU failing (or running without end)
mid-sweep.

Examples
--------
>>> from dfwb.plants import names, plant
>>> names()[:3]
('friction', 'backlash', 'static-backlash')
>>> friction = plant("friction")
>>> friction.output, friction.section, friction.counter
('x', ('x', 'v'), 'events')
>>> friction.check({"M": 2})
{'M': 2.0}
"""

import re
from dataclasses import dataclass, field
from typing import Callable, Mapping, Optional

from dfwb.base.values import NUMBER_FORMS, real, short
from dfwb.fmus.piecewise import PlantError, check
from dfwb.fmus.plants import TABLES

__all__ = ["Plant", "Demo", "register", "unregister", "plant", "names", "markdown_table", "PLANTS", "RANGES",
           "check_range"]

NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]{0,63}")  # a plant's name: a CLI word, a scene value, a file name
RESERVED = {"F", "omega", "phi", "harmonics"}  # set by the engine itself
_CHECKED = {}  # (plant, model, parameter items) -> validated parameters: sweeps repeat the same sets
MAX_CHECKED = 4096  # parameter sets remembered

# The parameter ranges the engine accepts, (low, high, unit) by name: each plant's table states them
# (fmus/table.py: the edges ``dfwb stress`` covers and the engine computes; the solvers accept more).
# Parameters without one (eps, gap0) keep the solver's own ranges. A plant added outside dfwb states its
# own in its entry (:attr:`Plant.ranges`).
RANGES = {}
for _table in TABLES:
    for _name, _accepted in _table.accepted().items():
        if RANGES.setdefault(_name, _accepted) != _accepted:  # one name, one range: scenes and --set share them
            raise ValueError(f"the plants' tables give {_name} two ranges: {RANGES[_name]} and {_accepted}")


def check_range(name, value, low, high, unit=""):
    """PlantError naming the value and the range unless low <= value <= high (a finite number)."""
    check(name, value, lambda: low <= value <= high, f"{name} must be in [{low:g}, {high:g}] {unit}".rstrip())


@dataclass(frozen=True)
class Demo:
    """How ``dfwb demo`` shows a plant: start values, stop time, input samples per period, [(output, label)]."""

    start: Mapping[str, float]
    stop_time: float
    samples_per_period: int
    outputs: tuple


@dataclass(frozen=True)
class Plant:
    """Everything dfwb knows about one plant.

    Attributes
    ----------
    name : str
        The name on the command line and in scenes (``"friction"``).
    model : type
        The FMI facade class (:class:`dfwb.fmus.facade.PlantFMU`); its
        ``parameters`` and ``outputs`` name the variables. The fields from
        ``output`` to ``position`` and ``counter``, when not given, are its
        table's (:class:`dfwb.fmus.table.PlantTable`: ``signal``,
        ``section``, ``modes``, ``starts``, ``shifts``, ``position``,
        ``counter``).
    output : str
        The signal whose describing function is taken.
    section : tuple of str
        The continuous state read at whole periods (the Poincare section).
    modes : tuple of str
        The discrete state read with it (an orbit's modes must repeat).
    initial : dict
        Section component -> the parameter that sets it at t = 0 (shooting);
        components without one are not reset.
    shifts : dict
        How each section component (and the output) moves when the plant is
        translated by 1 m: a number, or ``"k"`` (the parameter k).
    position : str
        The parameter that translates the whole plant; the closed loop also
        starts the plant from it.
    summary : str
        One line for tables (README, ``dfwb --help``); not given, the table's.
    counter : str
        The FMU's integer output counting engagements (``"events"``: the
        facade's own count of every event).
    never_engaged : str or None
        What an orbit without engagement means (the output is then constant
        and N = 0), or None when every orbit engages.
    ranges : dict
        Extra parameter ranges ``name -> (low, high, unit)`` beyond
        :data:`RANGES`.
    naive : type or None
        A fixed-step twin facade for the benchmark (parameter ``dt``).
    reference : callable or None
        ``reference(F, omega, params) -> complex N`` by an independent method
        (a closed form, or scipy at tight tolerance), for the tests and the
        benchmark.
    scipy : callable or None
        ``scipy(F, omega, params, method, rtol) -> complex N``: what a user
        would write with ``solve_ivp``, for the benchmark's comparison.
    variants : tuple
        ``(label, params)`` regularised settings the benchmark also runs
        (e.g. a Karnopp band).
    bench : dict
        ``{"quick": [(F, omega, params)], "full": [...]}``: the benchmark's points.
    stress : StressProfile or None
        The stress suite's knowledge of the plant: its cases, per-point
        observer and energy balances (:class:`dfwb.plants.stress_kit.StressProfile`;
        ``dfwb stress`` runs every plant that has one).
    demo : Demo or None
        How ``dfwb demo`` shows the plant.
    masses : tuple of str
        The parameters whose sum is the mass moved by the force (it sets the
        engine's amplitude scales); empty: ``M``, else ``M1 + M2``.
    linear : tuple or None
        ``(params, N)``: parameters that make the plant linear (or linear
        to 1e-10 at F = 50 N, omega = 1 rad/s), and ``N(omega, params) ->
        complex``, its describing function there, given every parameter (the
        defaults filled in); the contract suite (tests/test_contract.py)
        checks the engine against it.
    loop : type or None
        The exact closed loop of the plant with a linear controller (a
        :class:`dfwb.fmus.loops.FeedbackLoop`): what ``dfwb limit-cycle
        --exact`` shoots periodic orbits of; not given, the facade's ``loop``
        (dfwb's own plants have one), else None: no exact loop.

    Examples
    --------
    An entry of dfwb's friction mass under another name: the facts every plant gives, checked at once
    (each name must be an output or a parameter of the FMU facade):

    >>> import dfwb
    >>> from dfwb.fmus.facade import FrictionMass
    >>> entry = dfwb.Plant("my-friction", FrictionMass, output="x", section=("x", "v"), modes=("mode",),
    ...                    initial={"x": "x0", "v": "v0"}, shifts={"x": 1.0}, position="x0")
    >>> entry.fmu_name, entry.unit, entry.defaults()["Fs"], entry.check({"M": 2})
    ('FrictionMass', 'm', 7.0, {'M': 2.0})
    >>> dfwb.Plant("my-friction", FrictionMass, output="y", section=("x", "v"), modes=(), initial={},
    ...            shifts={}, position="x0")
    Traceback (most recent call last):
    ...
    dfwb.fmus.exact.PlantError: plant 'my-friction': output ['y'] are not outputs of FrictionMass

    An entry takes no part in dfwb until it is registered (:func:`register`).
    """

    name: str
    model: type
    output: Optional[str] = None
    section: Optional[tuple] = None
    modes: Optional[tuple] = None
    initial: Optional[dict] = None
    shifts: Optional[dict] = None
    position: Optional[str] = None
    summary: str = ""
    counter: Optional[str] = None
    never_engaged: Optional[str] = None
    ranges: dict = field(default_factory=dict)
    naive: Optional[type] = None
    reference: Optional[Callable] = None
    scipy: Optional[Callable] = None
    variants: tuple = ()
    bench: dict = field(default_factory=dict)
    stress: object = None
    demo: Optional[Demo] = None
    masses: tuple = ()
    linear: Optional[tuple] = None
    loop: Optional[type] = None

    def __post_init__(self):
        from dfwb.fmus.facade import PlantFMU

        if not (isinstance(self.name, str) and NAME.fullmatch(self.name)):
            raise PlantError(f"plant name {self.name!r}: letters, digits, _ . + - (not first), like 'friction'")
        if not (isinstance(self.model, type) and issubclass(self.model, PlantFMU)):
            raise PlantError(f"plant {self.name!r}: model {self.model!r} is not an FMU facade "
                             "(a subclass of dfwb.fmus.facade.PlantFMU)")
        table = self.model.table
        for what, key, fallback in (("output", "signal", None), ("section", "section", None), ("modes", "modes", None),
                                    ("initial", "starts", {}), ("shifts", "shifts", {}),
                                    ("position", "position", None), ("counter", "counter", "events")):
            if getattr(self, what) is None:  # not given: the model's table states it
                stated = getattr(table, key, None) if table is not None else None
                if what == "section" and not stated:
                    stated = None
                if stated is None and fallback is None:
                    raise PlantError(f"plant {self.name!r}: no {what} given, and {self.model.__name__} has no "
                                     f"table that states it")
                object.__setattr__(self, what, fallback if stated is None else stated)
        if not self.summary and table is not None:
            object.__setattr__(self, "summary", table.summary)
        if self.loop is None:  # a facade of dfwb's own plants (dfwb.fmus.plants) knows its loop
            object.__setattr__(self, "loop", getattr(self.model, "loop", None))
        for what in ("section", "modes"):
            value = getattr(self, what)
            if not (isinstance(value, (tuple, list)) and all(isinstance(v, str) for v in value)):
                raise PlantError(f"plant {self.name!r}: {what} {value!r} is not a tuple of output names")
        names = {name for name, *_ in self.model.all_outputs()}
        defaults = self.defaults()
        for what, wanted in (("output", [self.output]), ("section", self.section), ("modes", self.modes),
                             ("counter", [self.counter])):
            missing = [name for name in wanted if name not in names]
            if missing:
                raise PlantError(f"plant {self.name!r}: {what} {missing} are not outputs of {self.fmu_name}")
        unknown = [p for p in list(self.initial.values()) + [self.position] + list(self.masses) if p not in defaults]
        if unknown:
            raise PlantError(f"plant {self.name!r}: {unknown} are not parameters of {self.fmu_name}")

    @property
    def fmu_name(self):
        """The FMU's model name (the facade class's name)."""
        return self.model.__name__

    @property
    def unit(self):
        """The output's unit (its FMU variable's)."""
        return next((unit for name, unit, *_ in self.model.all_outputs() if name == self.output), "")

    @property
    def loop_start(self):
        """The parameter the closed loop starts the plant from (its position)."""
        return self.position

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

    def defaults(self):
        """{parameter: default} of the FMU."""
        return {name: default for name, default, *_ in self.model.parameters}

    def check(self, params):
        """Validated {name: float}; raises PlantError naming the value and what is allowed."""
        allowed = sorted(self.defaults())
        if not isinstance(params, Mapping):
            raise PlantError(f"params = {params!r:.80} is not a mapping of parameter names to numbers")
        values = {}
        for name, value in params.items():
            if name in RESERVED:
                raise PlantError(f"{name} is set by the describing-function engine, not as a parameter of the plant "
                                 f"(its parameters: {', '.join(allowed)})")
            if name not in allowed:
                raise PlantError(f"unknown parameter {name!r} for plant {self.name} (allowed: {', '.join(allowed)})")
            values[name] = real(value)  # not 1 for True, no j dropped, not b'1' nor '1_0'
            if values[name] is None:
                raise PlantError(f"{name} = {short(value)} is not a number ({NUMBER_FORMS}, or a real number)")
            limits = self.limits(name)
            if limits is not None:
                check_range(name, values[name], *limits)
        kwargs = dict(self.defaults(), **values)
        self.model.solver_class(F=1.0, omega=1.0, **self.model.solver_kwargs(kwargs))  # the solver's own range checks
        return values

    def limits(self, name):
        """(low, high, unit) the engine accepts for parameter ``name``: the entry's :attr:`ranges`, else its
        model's table's (:class:`dfwb.fmus.table.PlantTable`), else :data:`RANGES`; None: the solver's check."""
        table = getattr(self.model, "table", None)
        accepted = table.accepted() if table is not None else {}
        return self.ranges.get(name, accepted.get(name, RANGES.get(name)))

    def checked(self, params):
        """:meth:`check`, done once per distinct parameter set in a process."""
        try:  # the types are in the key: True == 1, yet M=True is refused and M=1 is not
            key = (self.name, self.model, frozenset((k, type(v), v) for k, v in params.items()))
            hash(key)
        except (AttributeError, TypeError):  # not a mapping, or an unhashable value: check() names it
            return self.check(params)
        if key not in _CHECKED:
            if len(_CHECKED) >= MAX_CHECKED:  # a long-running process sees many sets: start over
                _CHECKED.clear()
            _CHECKED[key] = self.check(params)
        return dict(_CHECKED[key])

    def complete(self, params):
        """Every parameter as a float, the defaults filled in (equal sets for a default given or omitted)."""
        return {name: float(value) for name, value in dict(self.defaults(), **params).items()}

    def mass(self, params):
        """Total mass moved by the force (sets the amplitude scales)."""
        merged = dict(self.defaults(), **params)
        if self.masses:
            return sum(merged[name] for name in self.masses)
        return merged.get("M", merged.get("M1", 0.0) + merged.get("M2", 0.0))


PLANTS: dict = {}


def register(entry):
    """Add a plant to the registry and return the entry.

    A name may be registered again only with the same facts (a module
    imported twice makes new functions for the same plant), and the first
    entry stays; another plant of that name is an error.

    Examples
    --------
    A plant of your own (here dfwb's friction mass under a facade class of a module ``my_plants``)
    registered, used by name, and taken out again, which leaves the registry as it was:

    >>> import dfwb
    >>> from dfwb.fmus.facade import FrictionMass
    >>> class MyFriction(FrictionMass):
    ...     __module__ = "my_plants"  # as if defined there: dfwb's own classes cannot be unregistered
    >>> before = dfwb.names()
    >>> entry = dfwb.register(dfwb.Plant("my-friction", MyFriction, output="x", section=("x", "v"),
    ...                                  modes=("mode",), initial={"x": "x0", "v": "v0"}, shifts={"x": 1.0},
    ...                                  position="x0"))
    >>> dfwb.names() == before + ("my-friction",)
    True
    >>> dfwb.plant("my-friction") is entry, dfwb.register(entry) is entry  # the same facts again: no change
    (True, True)
    >>> dfwb.register(dfwb.Plant("my-friction", FrictionMass, output="v", section=("x", "v"), modes=(),
    ...                          initial={}, shifts={}, position="x0"))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    dfwb.fmus.exact.PlantError: a plant named 'my-friction' is registered already (FMU MyFriction): ...
    >>> dfwb.unregister("my-friction")
    >>> dfwb.names() == before
    True
    """
    if not isinstance(entry, Plant):
        raise PlantError(f"register() takes a dfwb.Plant, not {type(entry).__name__} {entry!r:.60}")
    known = PLANTS.get(entry.name)
    if known is not None:
        if _facts(known) != _facts(entry):
            raise PlantError(f"a plant named {entry.name!r} is registered already (FMU {known.fmu_name}): "
                             "choose another name")
        return known  # the same plant again: the first entry stays
    PLANTS[entry.name] = entry
    return entry


def _facts(entry):
    """An entry's data, without its functions (which a second import of its module makes anew)."""
    return (entry.model, entry.output, entry.section, entry.modes, entry.initial, entry.shifts, entry.position,
            entry.summary, entry.counter, entry.never_engaged, entry.ranges, entry.masses, entry.naive,
            entry.variants, entry.bench, entry.demo, entry.loop)


def unregister(name):
    """Remove a plant that was registered (tests that add one take it out again); not one dfwb ships.

    Examples
    --------
    >>> import dfwb
    >>> from dfwb.fmus.facade import StaticBacklash
    >>> class MyBacklash(StaticBacklash):
    ...     __module__ = "my_plants"  # as if defined there: dfwb's own classes cannot be unregistered
    >>> before = dfwb.names()
    >>> entry = dfwb.register(dfwb.Plant("my-backlash", MyBacklash, output="y", section=("x", "v", "y"),
    ...                                  modes=("engaged",), initial={}, shifts={"x": 1.0, "y": "k"},
    ...                                  position="x0"))
    >>> "my-backlash" in dfwb.names()
    True
    >>> dfwb.unregister("my-backlash")
    >>> dfwb.names() == before
    True
    >>> dfwb.unregister("static-backlash")
    Traceback (most recent call last):
    ...
    dfwb.fmus.exact.PlantError: plant 'static-backlash' is built into dfwb and cannot be unregistered
    """
    entry = plant(name)
    if entry.model.__module__.startswith("dfwb."):
        raise PlantError(f"plant {entry.name!r} is built into dfwb and cannot be unregistered")
    PLANTS.pop(entry.name, None)


def names():
    """The registered plants' names, in registration order.

    Examples
    --------
    >>> import dfwb
    >>> dfwb.names()[:3]  # the paper's plants first, then dfwb's others, then those registered since
    ('friction', 'backlash', 'static-backlash')
    >>> [dfwb.plant(name).fmu_name for name in dfwb.names()[:3]]
    ['FrictionMass', 'TwoMassBacklash', 'StaticBacklash']
    """
    return tuple(PLANTS)


def markdown_table():
    """The registered plants as a Markdown table (the docs' table of plants, written when they are built).

    Examples
    --------
    >>> from dfwb.plants import markdown_table
    >>> markdown_table().splitlines()[2].split(" | ")[:2]
    ['| `friction`', '`FrictionMass.fmu`']
    """
    rows = ["| plant | FMU | what it is | parameters (defaults) | outputs | DF of |", "|---|---|---|---|---|---|"]
    for name in names():
        entry = plant(name)
        parameters = ", ".join(f"`{p}` {default:g}" + (f" {unit}" if unit else "")
                               for p, default, unit, _ in entry.model.parameters)
        outputs = ", ".join(f"`{o}`" for o, *_ in entry.model.outputs)
        rows.append(f"| `{name}` | `{entry.fmu_name}.fmu` | {entry.summary} | {parameters} | {outputs} | "
                    f"`{entry.output}` |")
    return "\n".join(rows)


def plant(name):
    """The Plant called ``name``, or PlantError listing the known ones.

    An entry, or a user's FMU plant (:class:`dfwb.foreign.plant.FMUPlant`, marked ``foreign``), is
    returned as it is.

    Examples
    --------
    >>> import dfwb
    >>> friction = dfwb.plant("friction")
    >>> friction.name, friction.fmu_name, friction.output, friction.unit
    ('friction', 'FrictionMass', 'x', 'm')
    >>> dfwb.plant(friction) is friction
    True
    >>> dfwb.plant("frictoin")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    dfwb.fmus.exact.PlantError: unknown plant 'frictoin' (allowed: friction, backlash, static-backlash...)
    """
    if isinstance(name, Plant) or getattr(name, "foreign", False) is True:
        return name
    try:
        return PLANTS[name]
    except (KeyError, TypeError):
        raise PlantError(f"unknown plant {name!r} (allowed: {', '.join(PLANTS)})") from None
