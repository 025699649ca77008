"""Fuzzing the command line (issue 10): no input may hang dfwb, eat the machine, lose a result, answer
wrongly in silence, or write outside its folder.

Hypothesis draws command-line arguments (``df``, ``sweep``, ``limit-cycle``), scene files (``run``) and
controller expressions G(s); every case runs ``python -m dfwb.cli ...`` in a subprocess of its own
(``tests/fuzz/harness.py``): a fresh sandbox as working folder, HOME, XDG_CACHE_HOME and TMPDIR inside it,
a wall-clock time limit, and resource limits on address space, CPU time and file size. The oracle:

- exit 0: the results are finite (``df --json`` and ``limit-cycle --json`` on stdout, ``results.json`` and
  ``results.csv`` of ``sweep`` and ``run``: no NaN, no infinity);
- exit 2: stderr is one line ``dfwb <command>: error: ...`` (argparse's usage block before it is accepted);
- anything else fails: another exit code, a signal (the resource limits kill with SIGKILL/SIGXCPU/SIGXFSZ),
  a ``Traceback``, a time-out ("hang"), a process left running, a file created, changed or removed in the
  sandbox outside the output folder (and the cache and temporary folders), or next to the sandbox.

Run time: the default profile draws a few examples per strategy, the same ones at every run (about two
to three minutes on two cores); ``DFWB_HYPOTHESIS=stress`` (the project's switch, see conftest.py) draws
20 times as many, new ones each time.
``DFWB_FUZZ_EXAMPLES=N`` sets the number per strategy explicitly. The module is marked ``fuzz``:
``pytest -m "not fuzz"`` leaves it out.
"""

import copy
import json
import math
import os
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fuzz import harness  # noqa: E402
from fuzz.harness import Sandbox, check, run_dfwb  # noqa: E402

from dfwb.fmus.plants import KINDS, TABLES  # noqa: E402

pytestmark = pytest.mark.fuzz

STRESS = os.environ.get("DFWB_HYPOTHESIS", "default") == "stress"


def _examples(default):
    explicit = os.environ.get("DFWB_FUZZ_EXAMPLES")
    if explicit:
        return max(1, int(explicit))
    return default * 20 if STRESS else default


def fuzz_settings(default):
    # The default run (CI) draws the same examples every time, so a red run is a change of dfwb, not of
    # luck; the longer profiles explore new ones.
    return settings(max_examples=_examples(default), deadline=None, print_blob=True,
                    derandomize=not (STRESS or os.environ.get("DFWB_FUZZ_EXAMPLES")),
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.filter_too_much, HealthCheck.large_base_example])


def judge(result):
    """check() a fuzz case, counting how it ended (pytest --hypothesis-show-statistics shows the counts)."""
    event(f"exit {result.returncode}")
    check(result)


# ----------------------------------------------------------------------------------------------------------
# The plants' real parameter names (checked against dfwb.plants.registry below) and values that pass their checks.

def _ranges(table):
    """Fuzzed ranges of a plant's parameters: each constant from a tenth to ten times its default (within its
    bounds), an initial value in [-1, 1], a gap within a tenth of its clearance."""
    ranges = {}
    for p in table.constants:
        lo, hi = p.bounds
        ranges[p.name] = ((0.1 * p.default, 10.0 * p.default if hi is None else min(10.0 * p.default, hi))
                          if p.default else (0.0, 1.0))
    for p in table.initial:
        ranges[p.name] = (0.0, 0.1 * table.defaults[p.half_of]) if p.half_of else (-1.0, 1.0)
    return ranges


PAPER = {  # the paper's plants, with ranges chosen by hand
    "friction": {"M": (0.1, 10.0), "B": (0.0, 5.0), "Fc": (0.0, 5.0), "Fs": (5.0, 10.0), "Dv": (0.0, 0.1),
                 "x0": (-1.0, 1.0), "v0": (-1.0, 1.0)},
    "backlash": {"M1": (0.1, 10.0), "M2": (0.1, 10.0), "h": (0.01, 1.0), "eps": (0.0, 1.0),
                 "x1_0": (-1.0, 1.0), "v1_0": (-1.0, 1.0), "v2_0": (-1.0, 1.0), "gap0": (0.0, 0.01)},
    "static-backlash": {"M": (0.1, 10.0), "k": (0.1, 10.0), "h": (0.01, 1.0), "x0": (-1.0, 1.0),
                        "v0": (-1.0, 1.0)},
}
PARAMETERS = {**{table.name: _ranges(table) for table in TABLES}, **PAPER}  # every plant of dfwb.fmus.plants
PLANTS = tuple(PARAMETERS)
RESERVED = ("F", "omega", "phi", "harmonics")
JUNK_NAMES = ("", "m", "eps ", "M1=2", "__class__", "é", "x" * 300, "../h", "-h")

EDGE_NUMBERS = ("0", "-0", "0.0", "-1", "1e300", "-1e300", "1e-300", "5e-324", "1e308", "1.8e308", "1e20",
                "-1e20", "1e-20", "1e9", "1e5", "nan", "NaN", "-nan", "inf", "-inf", "Infinity", "abc", "",
                "0x10", "1_000", " 1", "1e", "--1", "\u0661", "1,5", "2**10", "9" * 400, "True")


def number_text(lo, hi, wild=None):
    """Command-line text of a number: plausible (in [lo, hi]) if ``wild`` is False, an edge or junk value if
    True, either if None."""
    plausible = st.floats(min_value=lo, max_value=hi, allow_nan=False, allow_infinity=False).map(
        lambda x: f"{x:.6g}")
    odd = st.one_of(st.sampled_from(EDGE_NUMBERS), st.sampled_from(EDGE_NUMBERS), st.floats().map(repr))
    return plausible if wild is False else odd if wild else st.one_of(plausible, plausible, odd)


def wildness(draw):
    """A function () -> bool, called inside a composite strategy with its ``draw``: which value groups of the
    case get odd values. A third of the cases are plausible throughout (most of those must run), a third
    have an odd group now and then, a third many."""
    mode = draw(st.sampled_from(["none", "some", "many"]))
    return lambda: False if mode == "none" else draw(st.integers(0, 3)) == 0 if mode == "some" \
        else draw(st.booleans())


@st.composite
def option(draw, name, values):
    """``--name V1 V2`` or, for one value, sometimes ``--name=V`` (the only way to pass a value like -inf)."""
    if len(values) == 1 and draw(st.booleans()):
        return [f"{name}={values[0]}"]
    return [name, *values]


@st.composite
def assignments(draw, plant, wild=None):
    """NAME=VALUE words for --set: real names (of this and the other plants), reserved and junk names."""
    words = []
    for _ in range(draw(st.integers(1, 3))):
        kind = "own" if wild is False else \
            draw(st.sampled_from(["own", "own", "own", "other", "reserved", "junk", "malformed"]))
        if kind == "own" and plant in PARAMETERS:
            name = draw(st.sampled_from(sorted(PARAMETERS[plant])))
            lo, hi = PARAMETERS[plant][name]
            words.append(f"{name}={draw(number_text(lo, hi, wild))}")
        elif kind == "malformed":
            words.append(draw(st.sampled_from(["M", "=1", "M:1", "M = 1", "M==1", ""])))
        else:
            pool = {"other": sorted({n for p in PARAMETERS.values() for n in p}), "reserved": RESERVED,
                    "junk": JUNK_NAMES, "own": JUNK_NAMES}[kind]
            words.append(f"{draw(st.sampled_from(pool))}={draw(number_text(0.1, 10.0))}")
    return words


# The F and omega strategies keep valid cases small: at most three values each, in ranges where a point
# costs milliseconds; the rest are edge and junk values that must be refused.
def omega_log_n(wild):
    plausible = st.sampled_from(["2", "3", "4"])
    odd = st.sampled_from(["0", "1", "-2", "2.5", "1e7", "1e9", "1e300", "9223372036854775808", "nan", "inf", "x"])
    return odd if wild else plausible


@st.composite
def point_arguments(draw, command, out=None):
    """argv for ``df`` or ``sweep``: a plant (or junk), then options in any order, some repeated."""
    wild = wildness(draw)
    plant = draw(st.sampled_from(PLANTS * 6 + ("Friction", "static_backlash", ""))) if wild() else \
        draw(st.sampled_from(PLANTS))
    groups = []
    if not wild() or draw(st.integers(0, 9)):
        groups.append(draw(option("--F", draw(st.lists(number_text(1.0, 100.0, wild()), min_size=1, max_size=3)))))
    if draw(st.booleans()):
        groups.append(draw(option("--omega", draw(st.lists(number_text(0.1, 50.0, wild()), min_size=1,
                                                           max_size=3)))))
    else:
        groups.append(["--omega-log", draw(number_text(0.1, 5.0, wild())), draw(number_text(5.0, 50.0, wild())),
                       draw(omega_log_n(wild()))])
    if draw(st.booleans()):
        groups.append(["--set", *draw(assignments(plant, wild()))])
    if draw(st.integers(0, 4)) == 0:
        groups.append(["--drive", draw(st.sampled_from(["internal", "input", "exact", ""]))])
    if draw(st.integers(0, 4)) == 0:
        groups.append(draw(option("--samples-per-period", [draw(st.sampled_from(
            ["0", "-1", "3", "1e3", "x", "1000000", "1000000000000"] if wild() else ["4", "8", "16", "64"]))])))
    if command == "df" and draw(st.integers(0, 3)):
        groups.append(["--json"])
    if command == "sweep":
        groups.append(["--out", out])
        groups.append(draw(option("--jobs", [draw(st.sampled_from(
            ["0", "-3", "x", "1.5", "1000000"] if wild() else ["1", "1", "1", "2"]))])))
        groups.append(["--quiet"])
        if draw(st.integers(0, 3)) == 0:
            name = draw(st.sampled_from(sorted(PARAMETERS.get(plant, {"M": 0})) + list(JUNK_NAMES[:3]))) \
                if wild() else {"friction": "B", "backlash": "eps", "static-backlash": "k"}.get(plant, "M")
            values = draw(st.lists(number_text(0.1, 1.0, wild()), min_size=1, max_size=3))
            groups.append(["--grid", f"{name}={','.join(values)}"])
        if draw(st.integers(0, 5)) == 0:
            groups.append(["--no-resume"])
    if wild() and draw(st.integers(0, 3)) == 0:  # an option given twice
        groups.append(list(draw(st.sampled_from(groups))))
    groups = draw(st.permutations(groups))
    return [command, plant] + [word for group in groups for word in group]


# ----------------------------------------------------------------------------------------------------------
# 1. Command-line arguments.

@fuzz_settings(20)
@given(data=st.data())
def test_df_arguments(sandbox_factory, data):
    argv = data.draw(point_arguments("df"))
    with sandbox_factory() as box:
        judge(run_dfwb(box, argv))


# What an output folder may already hold: results of another run, damaged files, and links that lead out of
# it (a write through one would land outside the folder).
OUTPUT_STATES = st.sampled_from(["fresh"] * 8 + ["garbage-csv", "garbage-json", "garbage-manifest", "link-csv",
                                                 "link-json", "link-summary", "link-traces", "file", "lock"])


def prepare_output(box, folder, state):
    """Put the output ``folder`` in ``state``; the link targets lie outside it, in the working folder."""
    victim, victims = box.work / "victim.txt", box.work / "victims"
    victim.write_text("not dfwb's\n")
    victims.mkdir()
    if state == "fresh":
        return
    if state == "file":
        folder.parent.mkdir(parents=True, exist_ok=True)
        folder.write_text("a file where the output folder should be\n")
        return
    folder.mkdir(parents=True, exist_ok=True)
    garbage = {"garbage-csv": ("results.csv", "a,b\n1,2\n"), "garbage-json": ("results.json", "{"),
               "garbage-manifest": ("manifest.json", "[]"), "lock": (".dfwb.lock", "12345\n")}
    if state in garbage:
        name, text = garbage[state]
        (folder / name).write_text(text)
    elif state == "link-traces":
        (folder / "traces").symlink_to(victims, target_is_directory=True)
    else:
        (folder / {"link-csv": "results.csv", "link-json": "results.json", "link-summary": "summary.md"}[state]
         ).symlink_to(victim)


@fuzz_settings(12)
@given(data=st.data(), state=OUTPUT_STATES)
def test_sweep_arguments(sandbox_factory, data, state):
    with sandbox_factory() as box:
        prepare_output(box, box.out, state)
        argv = data.draw(point_arguments("sweep", out=str(box.out)))
        judge(run_dfwb(box, argv))


VALID_G = ("20*(s+2)/(s+20)", "100/(s+1)", "10/s", "2*s/(0.1*s+1) + 5", "(s+1)/(s**2+2*s+1)")


@st.composite
def limit_cycle_arguments(draw, out):
    wild = wildness(draw)
    plant = draw(st.sampled_from(["static-backlash"] * 3 + ["friction", "backlash", "nope"])) if wild() else \
        "static-backlash"
    groups = []
    controller = draw(st.sampled_from(["G", "G", "G", "numden", "none", "both"])) if wild() else \
        draw(st.sampled_from(["G", "numden"]))
    if controller in ("G", "both"):
        groups.append([f"--G={draw(g_expressions(argv=True) if wild() else st.sampled_from(VALID_G))}"])
    if controller in ("numden", "both"):
        groups.append(draw(option("--num", draw(st.lists(number_text(0.1, 10.0, wild()), min_size=1,
                                                         max_size=2)))))
        if not wild() or draw(st.integers(0, 5)):
            groups.append(draw(option("--den", draw(st.lists(number_text(0.1, 10.0, wild()), min_size=2,
                                                             max_size=4)))))
    # Valid ranges are narrow and low (a cheap DF map); the rest must be refused.
    groups.append(["--F-range", draw(number_text(1.0, 5.0, wild())), draw(number_text(10.0, 30.0, wild()))])
    groups.append(["--omega-range", draw(number_text(0.5, 2.0, wild())), draw(number_text(3.0, 10.0, wild()))])
    if draw(st.booleans()):
        groups.append(["--set", *draw(assignments(plant, wild()))])
    if draw(st.integers(0, 3)) == 0:
        groups.append(["--verify"])
        groups.append(draw(option("--samples-per-period", [draw(st.sampled_from(
            ["0", "-1", "15", "1e3", "x", "1000000000000"] if wild() else ["16", "32"]))])))
    if draw(st.integers(0, 2)) == 0:
        groups.append(["--plot", draw(st.sampled_from([f"{out}/cycle.png", f"{out}/cycle.svg", f"{out}/cycle",
                                                       f"{out}/missing/cycle.png", f"{out}/", f"{out}/."]))])
    if wild() and draw(st.integers(0, 7)) == 0:
        groups.append(["--jobs", draw(st.sampled_from(["1", "-3"]))])  # no such option: argparse refuses
    if draw(st.integers(0, 5)):
        groups.append(["--json"])
    if wild() and draw(st.integers(0, 6)) == 0:
        groups.append(list(draw(st.sampled_from(groups))))
    groups = draw(st.permutations(groups))
    return ["limit-cycle", plant] + [word for group in groups for word in group]


@pytest.mark.slow
@fuzz_settings(12)
@given(data=st.data())
def test_limit_cycle_arguments(sandbox_factory, data):
    with sandbox_factory() as box:
        box.out.mkdir()
        judge(run_dfwb(box, data.draw(limit_cycle_arguments(str(box.out)))))


# ----------------------------------------------------------------------------------------------------------
# 3. G(s) expressions.

G_ATOMS = st.one_of(
    st.just("s"), st.just("s"), st.integers(0, 100).map(str),
    st.sampled_from(["0", "0.0", "1e309", "1e308", "1e-320", "1e-300", "1e300", "9" * 400, "0x10", "1_0",
                     "1j", "2.5", ".5", "1e3", "True", "None", "...", "x", "S", "pi", "e", "__import__",
                     "'s'", '"s"', "b's'", "[s]", "{s}", "(s,)", "lambda: s", "s if s else s",
                     "[s for s in s]", "f's'", "s.real", "s[0]", "abs(s)", "exp(s)", "os.system('true')",
                     "__builtins__", "s.__class__", "()", "s:=1"]),
)


def _combine(children):
    binary = st.tuples(children, st.sampled_from(["+", "-", "*", "/", "**", "//", "%", "@", "&", "<<", "<",
                                                  "==", " and ", " if s else ", ","]),
                       children, st.booleans())
    return st.one_of(
        binary.map(lambda t: f"({t[0]}){t[1]}({t[2]})" if t[3] else f"{t[0]}{t[1]}{t[2]}"),
        binary.map(lambda t: f"{t[0]}{t[1]}{t[2]}"),
        st.tuples(st.sampled_from(["-", "+", "~", "not ", "--", "- -"]), children).map("".join),
        children.map(lambda c: f"({c})"),
        st.tuples(children, st.sampled_from(["2", "20", "21", "-1", "0.5", "1e9", "(1e309)", "s", "(2**64)"])
                  ).map(lambda t: f"({t[0]})**{t[1]}"),
        st.tuples(st.sampled_from(["f", "abs", "tf", "s"]), children).map(lambda t: f"{t[0]}({t[1]})"),
    )


G_SPECIAL = st.one_of(
    st.integers(1, 100_000).map(lambda n: "-" * n + "s"),
    st.integers(1, 50_000).map(lambda n: "(" * n + "s" + ")" * n),
    st.integers(1, 50_000).map(lambda n: "(" * n + "s"),  # unbalanced
    st.integers(2, 20_000).map(lambda n: "/".join(["s"] * n)),
    st.integers(2, 20_000).map(lambda n: "1/(" + "+".join(["s"] * n) + ")"),
    st.integers(2, 5_000).map(lambda n: "1/(" + "*".join(["(s+1)"] * n) + ")"),
    st.integers(2, 60).map(lambda n: "1/(s" + "**2" * n + ")"),
    st.sampled_from(["s**(1e309)", "1/(s-s)", "s/(0*s)", "(s+1)/(s+1)", "1e309*s/(s+1)", "1/(1e-320*s+1)",
                     "1/0", "1/0.0", "s/(s**21)", "(s+1)**20/(s+2)**20", "1/(s**20+1e-300)", "1e308*(s+1e308)/s",
                     "-1e308/(1e-308*s)", "0*s/(s+1)", "s/s", "1/s**0", "(1/s)**20", "s**-1",
                     "\x00", "s\x00", "\u0455", "ｓ", "1/(s+1)\n", "#", "s # comment", "   ", ""]),
    st.text(max_size=40),
)


def g_expressions(argv=False):
    """G(s) texts; ``argv``: only those a command line can carry (no NUL)."""
    texts = st.one_of(st.recursive(G_ATOMS, _combine, max_leaves=10), G_SPECIAL)
    return texts.filter(lambda text: "\x00" not in text) if argv else texts


@pytest.mark.slow
@fuzz_settings(25)
@given(expression=g_expressions(), via_scene=st.integers(0, 2))
def test_controller_expressions(sandbox_factory, expression, via_scene):
    """Mostly refused at once; a valid G runs a small search (static backlash, narrow ranges)."""
    with sandbox_factory() as box:
        if via_scene == 0 or "\x00" in expression:  # the same text in a scene, with a 2 x 3 DF map
            text = harness.toml_document({
                "title": "G", "limit_cycle": [{"name": "lc", "plant": "static-backlash", "G": expression,
                                               "F_range": [1.0, 20.0], "omega_range": [0.5, 5.0],
                                               "n_F": 2, "n_omega": 3}]})
            scene = box.write_input("scene.toml", text.encode("utf-8", "surrogatepass"))
            argv = ["run", str(scene), "--out", str(box.out), "--no-cache", "--jobs", "1", "--quiet"]
        else:
            argv = ["limit-cycle", "static-backlash", f"--G={expression}", "--F-range", "1", "20",
                    "--omega-range", "0.5", "5", "--json"]
        judge(run_dfwb(box, argv))


# ----------------------------------------------------------------------------------------------------------
# 2. Scene files.

BASE_SCENES = [
    {"title": "friction", "series": [{"name": "friction", "plant": "friction", "F": [10.0, 20.0],
                                      "omega": [1.0, 2.0]}]},
    {"title": "backlash", "description": "two restitutions", "harmonics": True,
     "series": [{"name": "backlash", "plant": "backlash", "params": {"h": 0.1}, "grid": {"eps": [0.2, 0.8]},
                 "F": [50.0], "omega": {"log": [10.0, 30.0, 3], "values": [20.0]}}]},
    {"title": "trace", "trace": [{"name": "t", "plant": "friction", "params": {"B": 0.5}, "F": 10.0,
                                  "omega": 1.0, "start": 0.0, "stop": 2.0, "step": 0.01, "outputs": ["x", "v"]}]},
    {"title": "cycle", "limit_cycle": [{"name": "lc", "plant": "static-backlash", "G": "20*(s+2)/(s+20)",
                                        "F_range": [1.0, 50.0], "omega_range": [1.0, 20.0], "n_F": 3,
                                        "n_omega": 4}]},
    {"title": "cycle by coefficients",
     "limit_cycle": [{"name": "lc", "plant": "static-backlash", "num": [20.0, 40.0], "den": [1.0, 20.0],
                      "F_range": [1.0, 50.0], "omega_range": [1.0, 20.0], "n_F": 2, "n_omega": 3}]},
    {"title": "figure", "engine": {"drive": "internal", "max_periods": 150},
     "series": [{"name": "static", "plant": "static-backlash", "params": {"h": 0.1}, "F": [10.0],
                 "omega": [5.0, 10.0]}],
     "figure": [{"name": "nyq", "kind": "nyquist", "series": ["static"], "marks": [5.0], "title": "N"}]},
    {"title": "held input", "engine": {"drive": "input", "samples_per_period": 16},
     "series": [{"name": "friction", "plant": "friction", "F": [10.0], "omega": [1.0]}]},
]

SCALAR_MUTANTS = st.one_of(
    st.sampled_from([0, -1, 1, 2, 3, 2**63 - 1, -2**63, 10**6, 1001, 0.0, -0.0, 1e300, -1e300, 1e-300, 5e-324,
                     math.nan, math.inf, -math.inf, 1e9, 1e9 * (1 + 1e-12), 1e-6, 1e-7, 1e5, 100001.0, 1e-4,
                     9.9e-5, 0.5, 1.5, 2.5, True, False]),
    st.sampled_from(["", "10", "nan", "../x", "../../x", "/tmp/x", "..", ".", "a/b", "a\\b", "con", "x" * 5000,
                     "friction", "backlash", "static-backlash", "nyquist", "paper", "fig03", "internal", "input",
                     "x", "v", "s", "1/s", "\u00e9", "\u202e", "a b", "-x", "name\nnext", "\x00"]),
    st.floats(), st.integers(-2**63, 2**63 - 1), st.text(max_size=12),
)
MUTANTS = st.one_of(
    SCALAR_MUTANTS, SCALAR_MUTANTS,
    st.lists(SCALAR_MUTANTS, max_size=3),
    st.dictionaries(st.sampled_from(["eps", "h", "M", "log", "values", "name", "x"]), SCALAR_MUTANTS, max_size=2),
    st.just([]), st.just({}),
)
UNKNOWN_KEYS = st.sampled_from(["omgea", "Title", "params ", "", "series", "a.b", "\u00e9", "x" * 100, "F",
                                "verify", "paper", "name"])
# Large inputs that must be refused before anything is allocated or run: each makes the scene exceed a limit.
HUGE = [
    ("series", "F", [float(1 + i % 90) for i in range(250_001)]),
    ("series", "omega", {"log": [1e-4, 1e5, 10**9]}),
    ("series", "omega", {"log": [1.0, 10.0, 10**6]}),
    ("series", "grid", {"eps": [0.5] * 1000, "h": [0.1] * 1000}),
    ("trace", "step", 1e-12),
    ("trace", "stop", 1e300),
    ("limit_cycle", "n_F", 10**9),
    ("limit_cycle", "samples_per_period", 10**12),
]


def _paths(value, prefix=()):
    """Every path (keys and indices) into a nested value, containers included."""
    yield prefix
    if isinstance(value, dict):
        for key, item in value.items():
            yield from _paths(item, prefix + (key,))
    elif isinstance(value, list) and len(value) < 50:
        for i, item in enumerate(value):
            yield from _paths(item, prefix + (i,))


def _legitimately_slow(document):
    """A trace of 1e5 to 2e6 samples: within dfwb's limits (2e6), and tens of seconds of honest work, which
    the time limit would call a hang. (Few samples far apart are not exempt: their cost is not bounded.)"""
    for trace in document.get("trace", []) if isinstance(document.get("trace"), list) else []:
        stop, step = (trace.get(key) if isinstance(trace, dict) else None for key in ("stop", "step"))
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (stop, step)) and step > 0 \
                and 1e5 < stop / step <= 2.1e6:
            return True
    return False


def _parent(document, path):
    for part in path[:-1]:
        document = document[part]
    return document


@st.composite
def scenes(draw):
    """(TOML bytes, what was done): a base scene with up to three mutations, sometimes damaged as text."""
    document = json.loads(json.dumps(draw(st.sampled_from(BASE_SCENES))))
    done = []
    for _ in range(draw(st.integers(0, 3))):
        paths = [p for p in _paths(document) if p]
        path = draw(st.sampled_from(paths))
        parent = _parent(document, path)
        op = draw(st.sampled_from(["replace", "replace", "replace", "delete", "add", "wrap", "duplicate",
                                   "huge"]))
        if op == "replace":
            parent[path[-1]] = draw(MUTANTS)
        elif op == "delete":
            del parent[path[-1]]
        elif op == "add":
            target = parent[path[-1]] if isinstance(parent[path[-1]], dict) else parent
            if isinstance(target, dict):
                target[draw(UNKNOWN_KEYS)] = draw(MUTANTS)
        elif op == "wrap":
            parent[path[-1]] = [parent[path[-1]]] if not isinstance(parent[path[-1]], list) else \
                (parent[path[-1]][0] if parent[path[-1]] else None)
            if parent[path[-1]] is None:
                del parent[path[-1]]
        elif op == "duplicate" and isinstance(parent, list):
            parent.append(json.loads(json.dumps(parent[path[-1]])))
        elif op == "huge":
            section, key, value = copy.deepcopy(draw(st.sampled_from(HUGE)))
            if isinstance(document.get(section), list) and document[section] and \
                    isinstance(document[section][0], dict):
                document[section][0][key] = value
        done.append((op, path))
    assume(not _legitimately_slow(document))
    try:
        text = harness.toml_document(document)
    except TypeError:  # a value TOML cannot hold (None): leave the key out
        text = harness.toml_document(json.loads(json.dumps(document), object_hook=lambda d: {
            k: v for k, v in d.items() if v is not None}))
    data = text.encode("utf-8", "surrogatepass")
    damage = draw(st.sampled_from(["none"] * 6 + ["truncate", "insert", "bytes", "duplicate-key", "bom",
                                                  "crlf", "table"]))
    if damage == "truncate":
        data = data[:draw(st.integers(0, len(data)))]
    elif damage == "insert":
        at = draw(st.integers(0, len(data)))
        data = data[:at] + draw(st.sampled_from([b"=", b"[", b"]]", b"\n[[series]]\n", b"\"", b"'''", b"#",
                                                 b"\x00", b"\n = 1\n", b"{", b"\\"])) + data[at:]
    elif damage == "bytes":
        data = data + draw(st.sampled_from([b"\xff\xfe", b"\n# \xc3\x28\n", b"\x80"]))
    elif damage == "duplicate-key":
        data = data + b'\ntitle = "again"\n'
    elif damage == "bom":
        data = b"\xef\xbb\xbf" + data
    elif damage == "crlf":
        data = data.replace(b"\n", b"\r\n")
    elif damage == "table":
        data = data + b"\n[[series]]\nname = \"extra\"\n"
    return data, done, damage


@fuzz_settings(20)
@given(scene=scenes(), how=st.sampled_from(["no-cache", "no-cache", "cache", "default-out", "two"]),
       file_name=st.sampled_from(["scene.toml"] * 6 + ["a b.toml", ".hidden.toml", "..toml", "x.TOML",
                                                       "\u00e9.toml", "-dash.toml"]),
       state=OUTPUT_STATES)
def test_scene_files(sandbox_factory, scene, how, file_name, state):
    data, _done, _damage = scene
    with sandbox_factory() as box:
        path = box.write_input(file_name, data)
        if how in ("no-cache", "cache"):
            prepare_output(box, box.out / "run", state)
        if how == "no-cache":
            argv = ["run", str(path), "--out", str(box.out / "run"), "--no-cache", "--jobs", "1", "--quiet"]
        elif how == "cache":
            argv = ["run", str(path), "--out", str(box.out / "run"), "--cache", str(box.cache / "dfwb-here"),
                    "--jobs", "1", "--quiet"]
        elif how == "default-out":  # out/scenes/<stem> under the working folder, which is the output folder
            argv = ["run", file_name, "--jobs", "1", "--quiet", "--no-cache"]
        else:  # a second scene: every scene is checked before the first runs
            other = box.write_input("other.toml", harness.toml_document(BASE_SCENES[0]).encode())
            argv = ["run", str(other), str(path), "--out", str(box.out), "--jobs", "1", "--quiet"]
        judge(run_dfwb(box, argv))


# ----------------------------------------------------------------------------------------------------------
# Explicit cases: inputs known to fail on main at the time of issue 10.

LONG_MINUS = "-" * 100_000 + "s"
REFUSED = [
    pytest.param(["df", "backlash", "--F", "1e30", "--omega", "1"], {}, id="df-backlash-F-1e30"),
    pytest.param(["df", "friction", "--F", "10", "--omega", "1", "--set", "v0=1e300"], {}, id="df-v0-1e300"),
    pytest.param(["df", "backlash", "--F", "10", "--omega", "1", "--set", "h=1e-300"], {}, id="df-h-1e-300"),
    pytest.param(["df", "friction", "--F", "10", "--omega", "1e300"], {}, id="df-omega-1e300"),
    pytest.param(["df", "friction", "--F", "10", "--omega", "1e-300"], {}, id="df-omega-1e-300"),
    pytest.param(["limit-cycle", "static-backlash", "--G", "s**(1e309)"], {}, id="G-power-1e309"),
    pytest.param(["limit-cycle", "static-backlash", f"--G={LONG_MINUS}"], {}, id="G-100000-minus"),
    pytest.param(["limit-cycle", "friction", "--G", "1/s", "--omega-range", "1e-300", "1"], {},
                 id="limit-cycle-omega-1e-300"),
    pytest.param(["limit-cycle", "friction", "--G", "10/s", "--verify", "--samples-per-period", "0"], {},
                 id="verify-samples-0"),
    pytest.param(["sweep", "friction", "--F", "10", "--omega-log", "1", "10", "1e9", "--out", "{out}"],
                 {"not_in_message": "MemoryError"}, id="sweep-omega-log-1e9"),
    pytest.param(["run", "/dev/zero"], {"not_in_message": "MemoryError", "seconds": 20}, id="run-dev-zero"),
    pytest.param(["sweep", "friction", "--F", "10", "--omega", "1", "--out", "{out}", "--jobs", "-3"], {},
                 id="sweep-jobs-minus-3"),
]


# A figure path that names a folder must not put the figure next to the folder; a figure that cannot be
# written must be refused before the search runs (not after its progress bar, naming a temporary file).
LEAD = ["limit-cycle", "static-backlash", "--G=20*(s+2)/(s+20)", "--F-range", "1", "10", "--omega-range", "1", "3"]
FIGURES = [
    pytest.param(LEAD + ["--json", "--plot", "{out}/"], None, id="plot-into-folder"),
    pytest.param(LEAD + ["--json", "--plot", "{out}/."], None, id="plot-into-folder-dot"),
    pytest.param(LEAD + ["--plot", "{out}/missing/cycle.png"], 2, id="plot-into-missing-folder"),
]


# A trace of few samples over a long time: 1e4 samples (the limit is 2e6), but 1.6e8 forcing periods.
LONG_TRACE = harness.toml_document({"title": "long", "trace": [{
    "name": "t", "plant": "friction", "F": 10.0, "omega": 1.0, "stop": 1e9, "step": 1e5, "outputs": ["x"]}]})


def test_long_trace_with_few_samples(sandbox_factory):
    with sandbox_factory() as box:
        path = box.write_input("long.toml", LONG_TRACE.encode())
        check(run_dfwb(box, ["run", str(path), "--out", str(box.out), "--no-cache", "--jobs", "1", "--quiet"]))


@pytest.mark.parametrize("argv, expect", FIGURES)
def test_figure_paths(sandbox_factory, argv, expect):
    with sandbox_factory() as box:
        box.out.mkdir()
        check(run_dfwb(box, [word.replace("{out}", str(box.out)) for word in argv]), expect=expect)


@pytest.mark.parametrize("argv, extra", REFUSED)
def test_refused_inputs(sandbox_factory, argv, extra):
    with sandbox_factory() as box:
        argv = [word.replace("{out}", str(box.out)) for word in argv]
        result = run_dfwb(box, argv)
        check(result, expect=2)
        if "not_in_message" in extra:
            assert extra["not_in_message"] not in result.stderr, result.explain(
                f"refused only after running out of memory (the limit is {harness.ADDRESS_SPACE >> 30} GiB)")
        if "seconds" in extra:
            assert result.seconds < extra["seconds"], result.explain(f"took {result.seconds:.1f} s to refuse")


def test_position_does_not_change_the_describing_function(sandbox_factory):
    """x0 = 1e20 translates the plant, which the DF ignores: N must equal the x0 = 0 value (to 1e-12)."""
    values = {}
    for x0 in ("0", "1e20"):
        with sandbox_factory() as box:
            result = run_dfwb(box, ["df", "friction", "--F", "10", "--omega", "1", "--set", f"x0={x0}", "--json"])
            check(result, expect=0)
            (point,) = json.loads(result.stdout)
            values[x0] = complex(point["N_re"], point["N_im"])
    assert abs(values["1e20"] - values["0"]) <= 1e-12 * abs(values["0"]), \
        f"N at x0 = 1e20 is {values['1e20']}, at x0 = 0 it is {values['0']}"


# ----------------------------------------------------------------------------------------------------------
# The harness itself: valid inputs pass under the same limits, and the names above are the plants' own.

VALID = [
    pytest.param(["df", "friction", "--F", "10", "50", "--omega", "1", "--json"], id="df"),
    pytest.param(["df", "static-backlash", "--F", "10", "--omega", "5"], id="df-table"),
    pytest.param(["sweep", "backlash", "--F", "50", "--omega-log", "10", "30", "3", "--set", "eps=0.2", "--out",
                  "{out}", "--jobs", "2", "--quiet"], id="sweep-2-jobs"),
    pytest.param(["limit-cycle", "static-backlash", "--G", "20*(s+2)/(s+20)", "--F-range", "0.01", "100",
                  "--omega-range", "0.1", "50", "--json"], id="limit-cycle"),
]


@pytest.mark.parametrize("argv", VALID)
def test_harness_passes_valid_input(sandbox_factory, argv):
    with sandbox_factory() as box:
        check(run_dfwb(box, [word.replace("{out}", str(box.out)) for word in argv]), expect=0)


@pytest.mark.parametrize("base", range(len(BASE_SCENES)))
def test_harness_passes_base_scenes(sandbox_factory, base):
    with sandbox_factory() as box:
        path = box.write_input("scene.toml", harness.toml_document(BASE_SCENES[base]).encode())
        check(run_dfwb(box, ["run", str(path), "--out", str(box.out), "--jobs", "1", "--quiet"]), expect=0)


def test_harness_catches_writes_outside_and_bad_errors(sandbox_factory):
    """The oracle is not vacuous: a stray file, a traceback, a multi-line error and a hang are failures."""
    with sandbox_factory() as box:
        stray = harness.run_python(box, "open('../stray', 'w').write('x')")
        with pytest.raises(AssertionError, match="outside the output folder"):
            check(stray)
    with sandbox_factory() as box:
        with pytest.raises(AssertionError, match="Traceback"):
            check(harness.run_python(box, "raise ValueError('x')"))
    with sandbox_factory() as box:
        with pytest.raises(AssertionError, match="one line"):
            check(harness.run_python(box, "import sys; sys.stderr.write('dfwb df: error: a\\nb\\n'); sys.exit(2)",
                                     command="df"))
    with sandbox_factory() as box:
        with pytest.raises(AssertionError, match="hang"):
            check(harness.run_python(box, "import time; time.sleep(60)", timeout=1))
    with sandbox_factory() as box:
        with pytest.raises(AssertionError, match="finite"):
            check(harness.run_python(box, "print('[{\"N_re\": NaN, \"N_im\": 0}]')", command="df",
                                     argv=["df", "friction", "--json"]))


def test_parameter_names_are_the_plants():
    from dfwb.plants.registry import PLANTS as REAL

    assert {name: sorted(REAL[name].defaults()) for name in KINDS} == \
        {name: sorted(names) for name, names in PARAMETERS.items()}


@pytest.fixture(scope="session")
def sandbox_factory(fmus, tmp_path_factory):
    """Sandbox() context managers: one fresh sandbox per case, removed when the case passes."""
    fmu_dir = Path(fmus["FrictionMass"]).parent
    base = tmp_path_factory.mktemp("fuzz")
    return lambda: Sandbox(base, fmu_dir)
