"""The plants' tables (fmus/table.py): every default, order and range is read from them, never copied."""

import doctest
import inspect
import re

import pytest

from dfwb.build_fmus import plant_header
from dfwb.fmus import backlash, facade, friction, naive, native_core, plants, static_backlash
from dfwb.fmus.table import EXCITATION_NAMES, INPUT_NAMES, Output, Parameter, PlantTable
from dfwb.plants import closed_forms, loop_reference, reference
from dfwb.plants.registry import RANGES

TABLES = {"friction": friction.TABLE, "backlash": backlash.TABLE, "static-backlash": static_backlash.TABLE}
# every class or function that takes a plant's parameters as keywords with defaults, by plant
TAKERS = {
    "friction": (friction.FrictionMass, naive.NaiveFrictionMass, friction.LOOP, native_core.NativeFrictionMass,
                 native_core.NativeFrictionLoop, reference.friction_response),
    "backlash": (backlash.TwoMassBacklash, naive.NaiveTwoMassBacklash, backlash.LOOP,
                 native_core.NativeTwoMassBacklash, native_core.NativeBacklashLoop, reference.backlash_response,
                 closed_forms.validity_frequencies),
    "static-backlash": (static_backlash.StaticBacklash, naive.NaiveStaticBacklash, static_backlash.LOOP,
                        native_core.NativeStaticBacklash, native_core.NativeStaticBacklashLoop,
                        reference.static_backlash_scipy, closed_forms.static_backlash_plant_df,
                        closed_forms.backlash_df),
}
FACADES = {"friction": facade.FrictionMass, "backlash": facade.TwoMassBacklash,
           "static-backlash": facade.StaticBacklash}


def _defaults(function):
    return {name: p.default for name, p in inspect.signature(function).parameters.items()
            if p.default is not inspect.Parameter.empty}


@pytest.mark.parametrize("plant", TAKERS)
def test_every_constructor_takes_the_tables_defaults(plant):
    """A default typed again somewhere would drift: each taker's keyword defaults are the table's, the same
    object (a float equal by accident would pass ==, not is)."""
    table = TABLES[plant]
    for taker in TAKERS[plant]:
        defaults = _defaults(taker)
        shared = [name for name in table.names if name in defaults]
        assert shared, taker
        for name in shared:
            assert defaults[name] is table.defaults[name], (taker, name)


@pytest.mark.parametrize("plant", TABLES)
def test_the_facade_and_the_orders_come_from_the_table(plant):
    table, model = TABLES[plant], FACADES[plant]
    assert [row[0] for row in model.parameters] == list(table.names)
    assert {row[0]: row[1] for row in model.parameters} == {p.name: p.fmu_start for p in table.parameters}
    assert model.ranges == table.bounds()
    loop = {"friction": friction.LOOP, "backlash": backlash.LOOP,
            "static-backlash": static_backlash.LOOP}[plant]
    signature = list(inspect.signature(loop).parameters)
    assert tuple(name for name in signature if name in table.names) == table.loop_order
    solver = list(inspect.signature(model.solver_class).parameters)
    assert tuple(solver) == table.core_order  # the C order is the Python constructor's
    assert loop_reference.DEFAULTS[plant] is table.defaults


@pytest.mark.parametrize("plant", TABLES)
def test_the_outputs_come_from_the_table(plant):
    """The FMU's outputs, their order and feedthrough are the table's; the solver's output() has the table's
    non-counter outputs as its fields, and its counters are attributes."""
    table, model = TABLES[plant], FACADES[plant]
    assert [row[0] for row in model.outputs] == [o.name for o in table.outputs]
    assert model.output_signal == table.fmu_signal() and model.feedthrough == table.feedthrough()
    solver = model.solver_class(F=1.0)
    assert solver.output()._fields == table.solver_outputs
    assert all(isinstance(getattr(solver, name), int) for name in table.counters)
    with pytest.raises(ValueError, match="the signal 'z' is not one of the outputs"):
        PlantTable(plant, table.constants, table.initial, table.outputs, signal="z")


def test_the_engine_ranges_are_the_tables():
    for table in TABLES.values():
        for name, accepted in table.accepted().items():
            assert RANGES[name] == accepted


def test_the_core_is_built_with_the_header_the_tables_write():
    """dfwb_plants.h is written into every build from the tables (no copy in the tree to go stale): each plant's
    kind and the index of each of its parameters in both C orders."""
    from dfwb.build_fmus.core import NATIVE_DIR, sources

    assert not (NATIVE_DIR / plant_header.NAME).exists()
    text = sources()[plant_header.NAME].decode()
    assert text == plant_header.header_text()
    for kind, table in enumerate(plants.TABLES, start=1):
        prefix = plants.c_name(table).upper()
        assert f"#define DFWB_PLANT_{prefix} {kind}\n" in text
        for order, infix in ((table.core_order, ""), (table.loop_order, "_LOOP")):
            for index, name in enumerate(order):
                assert re.search(rf"#define DFWB_{prefix}{infix}_{name} +{index}\n", text), (prefix, name)


def test_the_core_reads_parameters_in_the_tables_order(core):
    """A parameter moved in a table moves in the C core too: a value put at the table's index for M is the
    one the core refuses by name."""
    for name, table, cls in (("friction", friction.TABLE, native_core.NativeFrictionMass),
                             ("static-backlash", static_backlash.TABLE, native_core.NativeStaticBacklash)):
        solver = getattr(core, cls.__name__[len("Native"):])
        with pytest.raises(facade.PlantError, match=r"^M = -1\.0 is out of range"):
            solver(M=-1.0)
        for parameter in table.initial:
            with pytest.raises(facade.PlantError, match=rf"^{parameter.name} = inf is out of range"):
                solver(**{parameter.name: float("inf")})


def test_a_table_refuses_a_name_twice():
    with pytest.raises(ValueError, match=r"\['M'\] are declared twice"):
        PlantTable("twice", [Parameter("M", 1.0, "kg", "mass")], [Parameter("M", 0.0, "m", "again")])
    with pytest.raises(ValueError, match=r"\['F'\] are declared twice"):
        PlantTable("twice", [Parameter("F", 1.0, "N", "a force named like the excitation's")], [])
    assert EXCITATION_NAMES == ("F", "omega", "phi") and INPUT_NAMES == ("f", "harmonics")


def test_the_modules_examples_run():
    """fmus/ is not a doctest path (it is bundled into the FMUs): the examples of its table and plant list run
    here."""
    from dfwb.fmus import table

    for module in (table, plants):
        result = doctest.testmod(module)
        assert result.attempted > 0 and result.failed == 0, module


def test_one_list_of_plants():
    """dfwb's own plants are listed once (fmus/plants.py): the registry's, the C core's and the native FMUs'
    are that list."""
    from dfwb.build_fmus.native import KINDS as NATIVE
    from dfwb.plants.registry import names

    assert [table.name for table in plants.TABLES] == list(names())
    assert [table for _c, table in plant_header.PLANTS] == list(plants.TABLES)
    assert sorted(table.name for _kind, table in NATIVE.values()) == sorted(names())
    assert [model.table for model in facade.PLANTS] == list(plants.TABLES)
    assert plants.KINDS == {table.name: kind for kind, table in enumerate(plants.TABLES, start=1)}


def _docs_rows():
    """{parameter: (default, unit)} of the parameter tables of docs/models.md (rows naming several parameters
    split: "`x0`, `v0` | 0, 0 | m, m/s")."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "docs" / "models.md").read_text()
    sections = {}
    for heading, body in re.findall(r"^## (\d\. .*?)\n(.*?)(?=^## |\Z)", text, re.MULTILINE | re.DOTALL):
        for table in re.findall(r"\| parameter \| default \| unit \| meaning \|\n\|---.*?\n((?:\|.*\n)+)", body):
            rows = {}
            for row in table.splitlines():
                names, defaults, units = (cell.strip() for cell in row.strip("|").split("|")[:3])
                names = re.findall(r"`(\w+)`", names)
                defaults, units = defaults.split(", "), units.split(", ")
                for i, name in enumerate(names):
                    rows[name] = (defaults[min(i, len(defaults) - 1)], units[min(i, len(units) - 1)])
            sections.setdefault(heading, []).append(rows)
    return [rows for tables in sections.values() for rows in tables]


def test_the_docs_tables_state_the_tables_defaults_and_units():
    """docs/models.md's parameter tables are written by hand: each states its plant's defaults and units."""
    documented = _docs_rows()
    for plant, table in TABLES.items():
        names = set(table.names)
        (rows,) = [rows for rows in documented if set(rows) == names]  # exactly one docs table per plant
        for parameter in table.parameters:
            default, unit = rows[parameter.name]
            assert float(default) == parameter.fmu_start, (plant, parameter.name)
            assert unit == (parameter.unit or "-"), (plant, parameter.name)


def test_a_registry_entry_takes_the_engine_facts_from_the_table():
    """Plant(name, model) without section, modes, ... has the table's; one given overrides it; a model
    without a table must give them (one line naming what is missing)."""
    from dfwb.plants.registry import Plant

    entry = Plant("table-friction", facade.FrictionMass)
    table = friction.TABLE
    assert (entry.output, entry.section, entry.modes, entry.initial, entry.shifts, entry.position, entry.counter) == \
        (table.signal, table.section, table.modes, table.starts, table.shifts, table.position, table.counter)
    assert Plant("table-friction", facade.FrictionMass, section=("x",), counter="events").section == ("x",)
    assert Plant("table-backlash", facade.TwoMassBacklash).counter == "impacts"

    class Untabled(facade.FrictionMass):
        """A facade that declares its variables itself."""

    Untabled.table = None
    with pytest.raises(facade.PlantError, match="plant 'bare': no output given, and Untabled has no table"):
        Plant("bare", Untabled)
    facade.FACADES.remove(Untabled)


@pytest.mark.parametrize("name", ["_x", "class", "two words", "x"])
def test_an_output_name_a_tuple_cannot_hold_is_refused_naming_the_plant(name):
    outputs = (Output("x", "m", "position"), Output(name, "m", "again"))
    with pytest.raises(ValueError, match=f"^plant 'bad': output name '{name}' is refused"):
        PlantTable("bad", constants=(), initial=(), outputs=outputs)
