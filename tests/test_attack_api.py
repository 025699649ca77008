"""Hostile input to the public API, the registry and the FMU location: a right result or one DfwbError line.

Each case was a finding: a Python error escaping (TypeError, AttributeError,
LinAlgError, MemoryError), a value silently changed (the imaginary part of a
complex number dropped, True taken as 1), or a write outside the place asked for.
"""

import dataclasses
import os
import time
import warnings

import control as ct
import numpy as np
import pytest

import dfwb
from dfwb.fmi.location import default_fmu_dir, fmu_path
from dfwb.plants import names, plant, register, unregister


def refused(call, *words):
    """``call()`` raises a DfwbError of one line naming ``words``, without a warning on the way."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(dfwb.DfwbError) as caught:
            call()
    message = str(caught.value)
    assert "\n" not in message, message
    for word in words:
        assert word in message, message
    return message


# -- describing_function -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("F", [np.array([10 + 5j]), True, np.array([True, False]), "10", np.array(["10"]),
                               [10, None], np.array([10.0, "x"], dtype=object), np.array([None], dtype=object)])
def test_F_that_is_not_real_numbers_is_refused_not_coerced(F):
    refused(lambda: dfwb.describing_function("friction", F, 1.0), "F")


def test_a_lazy_huge_F_is_refused_before_it_is_built():
    refused(lambda: dfwb.describing_function("friction", range(10**12), 1.0), "200000")
    refused(lambda: dfwb.describing_function("friction", [range(10**12)], 1.0), "200000")
    huge = np.broadcast_to(np.int64(10), (10**6, 10**6))  # 8 bytes held, 8 TB as floats
    refused(lambda: dfwb.describing_function("friction", huge, 1.0), "200000")


@pytest.mark.parametrize("options, word", [
    ({"harmonics": 10**9}, "harmonics"), ({"harmonics": "3"}, "harmonics"), ({"harmonics": 2.5}, "harmonics"),
    ({"harmonics": True}, "harmonics"), ({"max_periods": True}, "max_periods"),
    ({"drive": "bogus"}, "drive"), ({"fmu_dir": 5}, "fmu_dir")])
def test_options_are_checked_before_anything_is_allocated_even_for_no_point(options, word):
    refused(lambda: dfwb.describing_function("friction", np.full(1000, 10.0), 1.0, **options), word)
    refused(lambda: dfwb.describing_function("friction", [], 1.0, **options), word)


def test_a_numpy_integer_option_is_an_integer(fmus):
    response = dfwb.describing_function("friction", 10.0, 1.0, harmonics=np.int64(3))
    assert response.harmonics.shape == (4,)


@pytest.mark.parametrize("value", [[1, 2], np.array([1.0, 2.0]), {"a": 1}, np.complex128(2 + 1j), 2 + 1j, True,
                                   np.bool_(True), b"2", bytearray(b"2"), "1_0", "\uff12", " 2", "0x2"])
def test_a_parameter_that_is_not_one_real_number_is_refused(value):
    refused(lambda: dfwb.describing_function("friction", 10.0, 1.0, M=value), "M")
    refused(lambda: dfwb.limit_cycles("friction", "Kp + 2/s", Kp=value), "Kp")


def test_a_real_number_of_any_kind_is_taken_and_a_huge_integer_is_out_of_range():
    from decimal import Decimal
    from fractions import Fraction

    expected = dfwb.describing_function("friction", 10.0, 1.0, M=1.5).N
    for value in (Fraction(3, 2), Decimal("1.5"), "1.5", np.float32(1.5), "15e-1"):
        assert dfwb.describing_function("friction", 10.0, 1.0, M=value).N == expected
    refused(lambda: dfwb.describing_function("friction", 10.0, 1.0, M=10 ** 400), "M = inf is out of range")
    refused(lambda: dfwb.limit_cycles("friction", "Kp + 2/s", Kp=-10 ** 400), "give a finite number")


# -- transfer_function and limit_cycles ---------------------------------------------------------------------------
@pytest.mark.parametrize("G, word", [
    (ct.ss([[np.nan]], [[1]], [[1]], [[0]]), "finite"), (ct.ss([[np.inf]], [[1]], [[1]], [[0]]), "finite"),
    (ct.tf([[[1], [1]]], [[[1, 1], [1, 2]]]), "one input"), (ct.tf([1], [1, 0.5], 0.1), "continuous"),
    (ct.ss([[-0.5]], [[1]], [[1]], [[0]], 0.1), "continuous"), (ct.tf([1, 0, 0], [1, 1]), "improper"),
    (ct.rss(60), "degree"), (([1.0], [1.0] + [0.0] * 5000), "degree"),
    (([np.complex128(1 + 1j)], [1, 1]), "num"), (([True], [True, False]), "num"), ((["1"], [1, 1]), "num")])
def test_a_controller_that_is_not_a_small_real_continuous_siso_system_is_refused_in_one_line(G, word):
    refused(lambda: dfwb.transfer_function(G), word)


def test_limit_cycles_takes_numpy_integers_and_refuses_a_bad_fmu_dir():
    refused(lambda: dfwb.limit_cycles("static-backlash", "1/(s+1)", fmu_dir=3.5), "fmu_dir")
    refused(lambda: dfwb.limit_cycles("static-backlash", "1/(s+1)", n_F=np.int64(10**9)), "10")


# -- grid, sweep, run_scene ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("args", [(10.0, [1.0]), ((x for x in [1.0]), [1.0]), ([10.0], [1.0], "x"),
                                  ([10.0], [1.0], None, {"B": 1.0}), ([10.0], [1.0], None, [("B", [1])]),
                                  ([10.0], [1.0], None, {"B": "abc"})])
def test_grid_refuses_what_is_not_lists_and_mappings(args):
    refused(lambda: dfwb.grid(*args))


@pytest.mark.parametrize("points, options, word", [
    ((p for p in [(10.0, 1.0, {})]), {}, "points"), (5, {}, "points"), ([(10.0, 1.0)], {}, "point"),
    ([(10.0, 1.0, "x")], {}, "params"), ([(10j, 1.0, {})], {}, "F"), ([("abc", 1.0, {})], {}, "F"),
    ([(True, 1.0, {})], {}, "F"), ([(10.0, 1.0, {"M": [1]})], {}, "M"), ([(10.0, 1.0, {})], {"jobs": "2"}, "jobs"),
    ([(10.0, 1.0, {})], {"jobs": -3}, "jobs"), ([(10.0, 1.0, {})], {"jobs": 0}, "jobs"),
    ([(10.0, 1.0, {})], {"fmu_dir": 7}, "fmu_dir"), ([(10.0, 1.0, {})], {"drive": "bogus"}, "drive"),
    ([(10.0, 1.0, {})], {"drive": "input", "samples_per_period": "x"}, "samples_per_period")])
def test_sweep_refuses_bad_points_and_options_before_writing(tmp_path, points, options, word):
    out = tmp_path / "out"
    refused(lambda: dfwb.sweep("friction", points, out, **{"jobs": 1, **options}), word)
    assert not out.exists()


@pytest.mark.parametrize("out", [None, 5])
def test_sweep_refuses_an_out_dir_that_is_not_a_path(out):
    refused(lambda: dfwb.sweep("friction", [(10.0, 1.0, {})], out, jobs=1), "out_dir")


def test_sweep_takes_a_plant_entry(tmp_path, fmus):
    records = dfwb.sweep(dfwb.plant("friction"), [(10.0, 1.0, {})], tmp_path, jobs=1)
    assert records[0]["plant"] == "friction"


@pytest.mark.parametrize("scene, options", [(None, {}), (5, {}), ("scenes/fig03_friction_nyquist.toml", {"out_dir": 7}),
                                            ("scenes/fig03_friction_nyquist.toml", {"jobs": "x"}),
                                            ("scenes/fig03_friction_nyquist.toml", {"jobs": -2})])
def test_run_scene_refuses_what_is_not_a_scene_or_an_option(tmp_path, scene, options):
    os.chdir(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    refused(lambda: dfwb.run_scene(scene, **{"out_dir": tmp_path / "out", **options}))
    assert not (tmp_path / "out").exists()


# -- the registry --------------------------------------------------------------------------------------------------
FRICTION = plant("friction")


@pytest.mark.parametrize("change, word", [
    ({"model": int}, "model"), ({"model": object()}, "model"), ({"section": "xv"}, "section"),
    ({"name": 5}, "name"), ({"name": "../../evil"}, "name"), ({"name": ""}, "name"), ({"name": "a b"}, "name")])
def test_a_malformed_entry_is_refused_in_one_line(change, word):
    refused(lambda: dataclasses.replace(FRICTION, **{"name": "extra", **change}), word)


def test_register_and_unregister_refuse_what_would_break_the_registry():
    before = names()
    refused(lambda: register("friction"), "Plant")
    refused(lambda: register(dataclasses.replace(FRICTION, summary="mine")), "friction")
    refused(lambda: register(dataclasses.replace(plant("backlash"), name="friction")), "friction")
    refused(lambda: unregister("friction"), "friction")
    refused(lambda: unregister(["x"]), "x")
    assert names() == before and plant("friction") is FRICTION
    register(FRICTION)  # the same entry again (a module imported twice) is fine
    assert names() == before


# -- where the FMUs are --------------------------------------------------------------------------------------------
def test_a_user_folder_in_DFWB_FMU_DIR_is_expanded_and_made_absolute(monkeypatch, tmp_path):
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv("DFWB_FMU_DIR", "~/fmus")
    assert default_fmu_dir() == tmp_path / "fmus"
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("DFWB_FMU_DIR", "rel")
    assert default_fmu_dir() == tmp_path / "rel"


@pytest.mark.parametrize("where", [5, "", b"x"])
def test_fmu_path_refuses_a_folder_that_is_not_a_path(where):
    refused(lambda: fmu_path(FRICTION, where), "fmu_dir")


def test_the_command_line_coefficients_have_the_same_degree_limit(capsys):
    from dfwb.cli import main
    from dfwb.engine.transfer import MAX_DEGREE

    with pytest.raises(SystemExit) as stop:
        main(["limit-cycle", "friction", "--num", "1", "--den"] + ["1"] * (MAX_DEGREE + 2))
    assert stop.value.code == 2 and f"at most {MAX_DEGREE} is allowed" in capsys.readouterr().err


def test_the_parameter_check_cache_is_bounded():
    from dfwb.plants import plant, registry

    friction = plant("friction")
    for k in range(registry.MAX_CHECKED + 10):
        friction.checked({"M": 1.0 + k * 1e-6})
    assert len(registry._CHECKED) <= registry.MAX_CHECKED


def test_an_engines_point_takes_numpy_scalars_and_refuses_what_is_not_a_real_number():
    from dfwb.engine.describing import DFEngine

    engine = DFEngine("friction")
    assert engine.point(np.float32(10.0), np.float32(1.0)).N == engine.point(10.0, 1.0).N  # (was "out of range")
    for F in ("10", None, 10 + 0j, True):
        refused(lambda: engine.point(F, 1.0), f"F = {F!r} is not a real number")


@pytest.mark.parametrize("call, words", [
    # ranges and start amplitudes by the same rule as a parameter (float() read '1_0', bytes and True)
    (lambda: dfwb.limit_cycles("friction", "10 + 2/s", F_range=("1_0", 100)), ["F_range", "pair of numbers"]),
    (lambda: dfwb.limit_cycles("friction", "10 + 2/s", omega_range=(True, 50)), ["omega_range", "pair of numbers"]),
    (lambda: dfwb.limit_cycles("friction", "10 + 2/s", F_range=(10 ** 400, 10)), ["F range = [inf, 10.0]"]),
    (lambda: dfwb.limit_cycles("friction", "10 + 2/s", exact=True, amplitudes=["1_0", b"3", True]), ["amplitudes"]),
    (lambda: dfwb.limit_cycles("friction", "10 + 2/s", exact=True, amplitudes="123"), ["amplitudes"]),
    # numpy reads a bytearray's bytes and a bool in a list as numbers
    (lambda: dfwb.describing_function("friction", bytearray(b"2"), 10.0), ["F = bytearray"]),
    (lambda: dfwb.describing_function("friction", [True, 2.0], 10.0), ["F = [True, 2.0]"]),
    (lambda: dfwb.limit_cycles("friction", ([True, 2], [1, 0])), ["num = [True, 2]"]),
    # an integer Python will not print is named by its size; a long text is refused at once
    (lambda: dfwb.describing_function("friction", 10 ** 5000, 10.0), ["F = inf is out of range"]),
    (lambda: dfwb.limit_cycles("friction", "Kp + 2/s", Kp=10 ** 5000), ["Kp = an integer of 16610 bits"]),
    (lambda: dfwb.limit_cycles("friction", "10 + 2/s", n_F=10 ** 5000), ["an integer of 16610 bits x"]),
    (lambda: dfwb.limit_cycles("friction", "Kp + 2/s", Kp="1" * 100_000 + "x"), ["Kp = '111", "is not a number"]),
])
def test_every_number_is_read_by_one_rule_and_refused_in_one_short_line(call, words):
    started = time.perf_counter()
    refused(call, *words)
    assert time.perf_counter() - started < 5.0  # (the first pattern took minutes on 100,000 digits and a letter)


def test_fractions_and_decimals_are_numbers_wherever_numbers_are_given():
    from decimal import Decimal
    from fractions import Fraction

    assert dfwb.describing_function("friction", Fraction(5, 2), 10.0).N == \
        dfwb.describing_function("friction", [Decimal("2.5")], 10.0).N[0] == \
        dfwb.describing_function("friction", 2.5, 10.0).N == \
        dfwb.describing_function("friction", np.array([2.5], dtype=object), 10.0).N[0]  # (an object array's reals)
