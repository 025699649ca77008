"""What every plant of dfwb.fmus.plants must satisfy, run for each one: a new plant is covered by adding it.

For each model module (its TABLE, SOLVER and LOOP) the generated classes follow the table (the FMU
facade, the loop's FMU facade, the C binding's solver and loop, the registry entry), and the C core
agrees with the Python oracle bit for bit: seeded parameters around the defaults (some refused, which
both must refuse with one message) under a sine and held inputs, with every output, Fourier integral,
event count and counter compared; a state written as bytes and read back continues bit for bit; the
closed loop under a PI controller visits the same states and events in C as in Python. The plants' own
test files check their physics; tests/test_contract.py what the engine needs of any registered plant.
"""

import inspect
import math
import pickle
import random

import pytest
from test_native_core import trace

from dfwb.fmus import facade, loop_facade, native_core, plants
from dfwb.fmus.exact import PlantError
from dfwb.fmus.table import MASS
from dfwb.plants import registry

MODULES = {module.TABLE.name: module for module in plants.MODULES}
PI = ([2.0, 1.0], [0.0])  # G(s) = (2 s + 1) / s: a PI controller, hunting with static friction


def _drive(name):
    """(F, omega) that engage the plant: its demo's, else 10 N at 1 rad/s."""
    demo = registry.plant(name).demo
    return (demo.start["F"], demo.start["omega"]) if demo else (10.0, 1.0)


def _parameters(table, rng):
    """Seeded constants around the defaults (each scaled by a factor in [1/3, 3]), the initial values' defaults."""
    params = {}
    for parameter in table.constants:
        default = parameter.default
        scaled = default * math.exp(rng.uniform(-1.1, 1.1)) if default else default
        params[parameter.name] = min(scaled, parameter.bounds[1]) if parameter.bounds[1] is not None else scaled
    return params


@pytest.fixture(params=sorted(MODULES), scope="module")
def module(request):
    return MODULES[request.param]


def test_the_generated_classes_follow_the_table(module):
    table = module.TABLE
    plant = getattr(facade, table.model)
    loop = getattr(loop_facade, table.model + "Loop")
    assert plant in facade.PLANTS and plant.solver_class is module.SOLVER and plant.table is table
    assert [name for name, *_ in plant.parameters] == list(table.names)
    assert [name for name, *_ in plant.outputs] == [o.name for o in table.outputs]
    assert loop in loop_facade.LOOPS and loop.solver_class is module.LOOP
    assert [name for name, *_ in loop.parameters] == list(table.names)
    assert loop.mode_keys.keys() == set(module.LOOP.KEYS)
    assert module.LOOP.COUNTER.name in [name for name, *_ in loop.outputs]
    for cls, python in ((native_core.SOLVERS, module.SOLVER), (native_core.LOOPS, module.LOOP)):
        native = getattr(native_core, "Native" + python.__name__)
        assert native in cls
        theirs = inspect.signature(native).parameters
        for name, parameter in inspect.signature(python).parameters.items():
            assert theirs[name].default is parameter.default, (native, name)
    output = module.SOLVER().output()
    assert type(output) is table.output_type and pickle.loads(pickle.dumps(output)) == output
    entry = registry.plant(table.name)
    assert entry.model is plant and entry.loop is module.LOOP and entry.summary == table.summary
    assert entry.output == table.signal and entry.section == table.section


@pytest.mark.needs_cc
def test_the_c_solver_agrees_with_python_bit_for_bit(module, core):
    """30 seeded parameter sets; over three drive periods with a held input changed at each point."""
    table, rng = module.TABLE, random.Random(f"every plant {module.TABLE.name}")
    F, omega = _drive(table.name)
    native = getattr(core, table.model)
    ran = 0
    for case in range(30):
        params = dict(_parameters(table, rng), F=F * rng.uniform(0.2, 2.0), omega=omega * rng.uniform(0.5, 2.0),
                      phi=rng.uniform(-3.0, 3.0), harmonics=3)
        period = 2 * math.pi / params["omega"]
        times = [period * (k + 1) / 16 for k in range(48)]
        inputs = [rng.choice([None, rng.uniform(-F, F)]) for _ in times]
        python = trace(lambda: module.SOLVER(**params), times, inputs, table.counters)
        c = trace(lambda: native(**params), times, inputs, table.counters)
        assert python[0] == c[0], f"case {case} {params}: Python {python[0]!r}, C {c[0]!r}"
        assert [repr(v) for v in python[1]] == [repr(v) for v in c[1]], f"case {case} {params}"
        ran += python[0] == "ok"
    assert ran >= 10, f"only {ran} of 30 cases ran"


@pytest.mark.needs_cc
def test_a_state_read_back_continues_bit_for_bit(module, core):
    table = module.TABLE
    F, omega = _drive(table.name)
    native = getattr(core, table.model)
    period = 2 * math.pi / omega
    straight, restored = native(F=F, omega=omega, harmonics=2), native(F=F, omega=omega, harmonics=2)
    for k in range(1, 40):
        straight.advance(k * period / 8)
        restored.advance(k * period / 8)
        restored = type(restored).from_bytes(restored.to_bytes())
        assert restored.output() == straight.output() and restored.integrals() == straight.integrals()
        assert restored.events == straight.events and restored.same_parameters(straight)
    assert straight.events > 0, "the drive never engaged the plant"


@pytest.mark.needs_cc
def test_the_c_loop_agrees_with_python_bit_for_bit(module, core):
    """The loop under PI from a displaced start: the same states, modes, events and counts at 200 points."""
    table, loop = module.TABLE, module.LOOP
    start = {table.position: 0.3}
    python, c = loop(*PI, **start), getattr(core, loop.__name__)(*PI, **start)
    for k in range(1, 201):
        python.advance(0.25 * k)
        c.advance(0.25 * k)
        assert c.state() == python.state() and c.key == python.key, f"t = {0.25 * k}"
        assert c.events == python.events and c.counts() == python.counts()
    assert python.events > 0


@pytest.mark.needs_cc
def test_the_c_classes_take_and_refuse_arguments_as_python(module, core):
    """Constants given as ints stay ints on the C loop, as on the Python loop; a call that fits no signature
    is a TypeError naming the class."""
    table, loop = module.TABLE, module.LOOP
    ints = {p.name: int(p.default) for p in table.constants if p.default and float(p.default).is_integer()}
    python, c = loop(*PI, **ints), getattr(core, loop.__name__)(*PI, **ints)
    for name in loop.CONSTANTS:
        assert type(getattr(c, name)) is type(getattr(python, name)) and getattr(c, name) == getattr(python, name)
    for make, name in ((getattr(core, table.model), "Native" + table.model),
                       (getattr(core, loop.__name__), "Native" + loop.__name__)):
        with pytest.raises(TypeError, match=f"^{name}\\(\\): got an unexpected keyword argument 'nonsense'"):
            make(*PI if make is not getattr(core, table.model) else (), nonsense=1.0)
    with pytest.raises(TypeError, match=f"^Native{loop.__name__}\\(\\): missing a required argument: 'b'"):
        getattr(core, loop.__name__)()


@pytest.mark.needs_cc
@pytest.mark.parametrize("value", [1e300, 1e-300])
def test_a_loop_with_an_extreme_mass_runs_or_refuses_in_one_line(module, core, value):
    """Masses far outside the engine's range (which the solvers' classes take): each loop, Python and C, runs
    from a displaced start or refuses with PlantError, the same way. A mass of 1e300 kg once overflowed
    the chunk's Taylor bounds (h ** k with h = 1/rho = 1e300 s)."""
    table, loop = module.TABLE, module.LOOP
    masses = [p.name for p in table.constants if p.accepted == MASS]
    assert masses
    for name in masses:
        params = {table.position: 0.3, name: value}
        outcomes = []
        for cls in (loop, getattr(core, loop.__name__)):
            try:
                solver = cls(*PI, **params)
                solver.advance(10.0)
                outcomes.append(solver.state())
            except PlantError as error:
                assert "\n" not in str(error)
                outcomes.append(type(error))
        assert outcomes[0] == outcomes[1], (name, outcomes)
        assert not isinstance(outcomes[0], list) or all(math.isfinite(x) for x in outcomes[0])
