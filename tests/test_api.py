"""The public API (``import dfwb``): shapes, agreement with the engine, plots, G three ways, errors."""

import control as ct
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import dfwb  # noqa: E402
from dfwb.engine.describing import COLUMNS, DFEngine, from_row, to_row  # noqa: E402

LEAD = "20*(s+2)/(s+20)"
RANGES = {"F_range": (0.01, 100.0), "omega_range": (0.1, 50.0), "n_F": 8, "n_omega": 16}


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def test_every_name_in_all_exists():
    assert dfwb.__version__ == "0.1.0"
    assert len(set(dfwb.__all__)) == len(dfwb.__all__)
    for name in dfwb.__all__:
        assert hasattr(dfwb, name), name
    assert issubclass(dfwb.PlantError, dfwb.DfwbError) and issubclass(dfwb.InputError, dfwb.DfwbError)
    assert dfwb.plant("friction") is dfwb.plants.PLANTS["friction"] and isinstance(dfwb.plant("friction"), dfwb.Plant)
    assert "friction" in dfwb.names()


def test_a_scalar_point_is_a_complex_scalar_equal_to_the_engine_to_the_bit(fmus):
    response = dfwb.describing_function("friction", 10.0, 1.0)
    direct = DFEngine("friction").point(10.0, 1.0)
    assert response.shape == () and isinstance(response.N, complex) and response.N == direct.N
    assert bool(response.periodic) is True and response.harmonics.shape == (11,)
    assert response.harmonics.tolist() == direct.harmonics
    record = direct.as_dict()
    assert [{k: v for k, v in p.items() if k != "seconds"} for p in response.points] == \
        [{k: v for k, v in record.items() if k != "seconds"}]


def test_one_dimensional_and_broadcast_grids(fmus):
    omega = np.array([0.5, 1.0, 2.0])
    line = dfwb.describing_function("backlash", 50.0, omega, eps=0.5)
    assert line.N.shape == line.periodic.shape == (3,) and line.harmonics.shape == (3, 11)
    assert line.periodic.dtype == bool and line.N.dtype == complex
    F = np.array([[30.0], [50.0]])
    grid = dfwb.describing_function("backlash", F, omega, eps=0.5, harmonics=3)
    assert grid.N.shape == (2, 3) and grid.harmonics.shape == (2, 3, 4) and len(grid.points) == 6
    assert grid.F.shape == grid.omega.shape == (2, 3)
    engine = DFEngine("backlash", harmonics=3)
    for (i, j), N in np.ndenumerate(grid.N):
        direct = engine.point(F[i, 0], omega[j], {"eps": 0.5})
        assert N == direct.N and grid.harmonics[i, j].tolist() == direct.harmonics
        assert grid.points[i * 3 + j]["F"] == F[i, 0] and grid.points[i * 3 + j]["omega"] == omega[j]
    assert grid.N[1].tolist() == line.N.tolist()  # F = 50 N: the same points as the 1-D call, to the bit


def test_a_record_round_trips_through_its_csv_row_with_units_in_the_columns(fmus):
    record = dfwb.describing_function("friction", 20.0, 2.0, M=2.0).points[0]
    row = to_row(record)
    assert list(row) == COLUMNS
    assert {"F [N]", "omega [rad/s]", "N_re [m/N]", "N_im [m/N]", "X0 [m]", "X10 [m]", "params"} <= set(COLUMNS)
    assert from_row(row) == record


def test_plots_draw_into_a_given_axes_or_a_new_figure(fmus):
    response = dfwb.describing_function("friction", [[10.0], [20.0]], [0.5, 1.0, 2.0])
    figure, ax = plt.subplots()
    lines = response.plot(ax=ax)
    assert len(lines) == 2 and all(line.axes is ax for line in lines)
    assert ax.get_xlabel() == "Re{-1/N} [N/m]" and ax.get_ylabel() == "Im{-1/N} [N/m]"
    assert np.allclose(lines[0].get_xdata(), (-1 / response.N[0]).real)
    before = plt.get_fignums()
    lines = dfwb.describing_function("friction", 10.0, 1.0).plot()
    assert len(lines) == 1 and len(plt.get_fignums()) == len(before) + 1
    cycles = dfwb.limit_cycles("static-backlash", LEAD, **RANGES)
    figure, ax = plt.subplots()
    lines = cycles.plot(ax=ax)
    assert lines[0].get_label() == "G(jw)" and all(line.axes is ax for line in lines)
    assert ax.get_xlabel() == "Re [N/m]"
    assert len(cycles.plot()) == len(lines)


def test_G_given_as_text_num_den_or_python_control_gives_the_same_predictions(fmus):
    tf = ct.tf([20.0, 40.0], [1.0, 20.0])
    found = [dfwb.limit_cycles("static-backlash", G, **RANGES).predictions
             for G in (LEAD, ([20.0, 40.0], [1.0, 20.0]), tf)]
    assert len(found[0]) == 1
    assert found[0] == found[1] == found[2]
    (cycle,) = dfwb.limit_cycles("static-backlash", ct.tf2ss(tf), **RANGES).predictions
    assert cycle.F == pytest.approx(found[0][0].F, rel=1e-8) and cycle.stable == found[0][0].stable
    assert cycle.omega == pytest.approx(found[0][0].omega, rel=1e-8)


@pytest.mark.parametrize("call, message", [
    (lambda: dfwb.describing_function("nope", 10.0, 1.0), "unknown plant 'nope'"),
    (lambda: dfwb.describing_function("friction", 10.0, 1.0, nope=1.0), "unknown parameter 'nope'"),
    (lambda: dfwb.describing_function("friction", 10.0, 1.0, M=-1.0), "M"),
    (lambda: dfwb.describing_function("friction", [10.0, -1.0], 1.0), "F"),
    (lambda: dfwb.describing_function("friction", [10.0, 20.0], [1.0, 2.0, 3.0]), "do not broadcast"),
    (lambda: dfwb.describing_function("friction", "ten", 1.0), "not a number"),
    (lambda: dfwb.limit_cycles("static-backlash", "s**2/(s+1)"), "improper"),
    (lambda: dfwb.limit_cycles("static-backlash", 42), "not a controller"),
    (lambda: dfwb.limit_cycles("static-backlash", LEAD, F_range=(10.0, 1.0)), "F range"),
    (lambda: dfwb.limit_cycles("friction", LEAD, Fc="x"), "not a number"),
])
def test_bad_input_raises_a_dfwb_error_of_one_line(call, message):
    with pytest.raises(dfwb.DfwbError) as error:
        call()
    text = str(error.value)
    assert message in text and "\n" not in text


def test_run_scene_and_sweep_write_the_same_records(fmus, tmp_path):
    from dfwb.studies.scene import parse_scene

    points = dfwb.grid([10.0], [1.0, 2.0])
    records = dfwb.sweep("friction", points, tmp_path / "sweep", jobs=1)
    response = dfwb.describing_function("friction", 10.0, [1.0, 2.0])
    assert [r["N_re"] for r in records] == response.N.real.tolist()
    scene = parse_scene('title = "t"\n[[series]]\nname = "s"\nplant = "friction"\nF = [10]\nomega = [1, 2]\n')
    outcome = dfwb.run_scene(scene, tmp_path / "scene", jobs=1, cache=False)
    assert outcome.points == 2
    import json

    series = json.loads((tmp_path / "scene" / "results.json").read_text())["series"]["s"]
    assert [(r["N_re"], r["N_im"]) for r in series] == [(r["N_re"], r["N_im"]) for r in records]
    assert set(series[0]) == set(records[0])  # one record shape in a scene's and a sweep's JSON


def test_responses_show_a_short_repr_a_summary_with_units_and_html():
    import dfwb

    df = dfwb.describing_function("friction", F=[10.0, 20.0], omega=1.0)
    cycles = dfwb.limit_cycles("friction", "Kp + Ki/s", exact=True, Kp=10, Ki=2)
    for response in (df, cycles):
        shown = repr(response)
        assert "\n" not in shown and len(shown) < 300 and "np.float64" not in shown, shown
        assert str(response) == response.summary() and "rad/s" in str(response) and " N" in str(response)
        assert response._repr_html_().startswith("<pre>") and "<" not in response._repr_html_()[5:-6]
    assert "F [N]" in str(df) and "-1/N [N/m]" in str(df) and str(df).count("\n") == 3
    assert "period 57.26" in str(cycles)
