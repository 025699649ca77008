"""The dither's describing function (dfwb.engine.dither_df) against its oracles: the plant's own DF without a
dither, a linear plant's frequency response, an independent scipy simulation of the same segments, the long-time
average it stands for, and its refusals."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from dfwb.base.errors import PlantError
from dfwb.engine.describing import DFEngine
from dfwb.engine.dither_df import R_MAX, TRANSIENT_TOL, DitherDFEngine, _Measure
from dfwb.plants import plant

FRICTION = plant("friction")
DEFAULTS = {k: v for k, v in FRICTION.defaults().items() if k not in ("x0", "v0")}


@pytest.fixture(scope="module")
def engine():
    return DitherDFEngine(FRICTION)


@pytest.mark.parametrize("F, omega", [(10.0, 1.0), (4.0, 0.5), (30.0, 7.0)])
def test_without_dither_it_is_the_plants_own_df(engine, F, omega):
    own = DFEngine("friction").point(F, omega).N
    point = engine.point(F, omega, {"a": 0.0, "w_d": 5.0})
    # every phase is the same: what is left is the transient the runs forgot to TRANSIENT_TOL, within N_error
    assert abs(point.N - own) <= max(point.N_error, 1e-13 * abs(own))
    assert point.N_error <= 1e-10 * abs(own)


@pytest.mark.parametrize("F, omega, a, w_d", [(10.0, 1.0, 10.0, 5.0), (3.0, 0.3, 20.0, 2.0)])
def test_a_linear_plant_is_its_frequency_response_whatever_the_dither(engine, F, omega, a, w_d):
    # without friction the mass is linear: the dither's response adds, and X_1 / F is 1 / (-M w^2 + j B w)
    M, B = DEFAULTS["M"], DEFAULTS["B"]
    point = engine.point(F, omega, {"Fc": 0.0, "Fs": 0.0, "a": a, "w_d": w_d})
    linear = 1.0 / (-M * omega ** 2 + 1j * B * omega)
    assert abs(point.N - linear) <= 1e-10 * abs(linear)
    assert max(point.harmonics[2:]) <= 1e-10 * point.harmonics[1]


# -- an independent simulation of one segment: scipy between events, the two sines as functions of time --------
def _reference_segment(F, omega, a, w_d, theta, periods, M, B, Fc, Fs):
    """X_1 of x over the forcing period [periods T, (periods + 1) T] of the friction mass from rest at t = 0,
    driven by F cos(w t) + a sin(w_d t + theta): solve_ivp (DOP853, rtol 1e-12) between the velocity's zeros,
    breakaway where |f| reaches Fs (a scan and brentq), the Fourier integral an extra state."""
    T = 2.0 * math.pi / omega
    t0, t1 = periods * T, (periods + 1) * T

    def force(t):
        return F * math.cos(omega * t) + a * math.sin(w_d * t + theta)

    def rhs(s):
        def f(t, y):
            phase, weight = omega * (t - t0), 0.0 if t < t0 else 1.0
            return [y[1], (force(t) - s * Fc - B * y[1]) / M,
                    weight * y[0] * math.cos(phase), -weight * y[0] * math.sin(phase)]
        return f

    def stop(t, y):
        return y[1]

    t, y, s = 0.0, [0.0, 0.0, 0.0, 0.0], 0
    dt = min(T, 2.0 * math.pi / w_d) / 400.0
    for _ in range(100_000):
        if t >= t1:
            break
        if s == 0:  # stuck: x holds until |f| exceeds Fs
            if abs(force(t)) > Fs:
                s = 1 if force(t) > 0.0 else -1
                continue
            u = t
            while u < t1 and abs(force(min(u + dt, t1))) <= Fs:
                u = min(u + dt, t1)
            if u >= t1:
                end = t1
            else:
                end = brentq(lambda r: abs(force(r)) - Fs, u, min(u + dt, t1), xtol=1e-15, rtol=1e-15)
            lo, hi = max(t, t0), max(end, t0)
            if hi > lo:  # int x exp(-j w (t - t0)) dt at constant x
                c = y[0] * (np.exp(-1j * omega * (hi - t0)) - np.exp(-1j * omega * (lo - t0))) / (-1j * omega)
                y[2] += c.real
                y[3] += c.imag
            t = end
            if t < t1:
                s = 1 if force(t) > 0.0 else -1
            continue
        stop.terminal, stop.direction = True, -s
        edges = [t0] if t < t0 else []
        for end in edges + [t1]:
            sol = solve_ivp(rhs(s), (t, end), y, method="DOP853", rtol=1e-12, atol=1e-14, events=stop)
            t, y = float(sol.t[-1]), list(sol.y[:, -1])
            if sol.status == 1:
                break
        if sol.status == 1:
            y[1] = 0.0
            s = 0 if abs(force(t)) <= Fs else (1 if force(t) > 0.0 else -1)
    return 2.0 / T * complex(y[2], y[3])


@pytest.mark.parametrize("F, omega, a, w_d", [(10.0, 1.0, 10.0, 5.0), (10.0, 1.0, 3.0, 5.37), (20.0, 3.0, 10.0, 5.0)])
def test_a_segment_is_the_independent_simulations(F, omega, a, w_d):
    measure = _Measure(DitherDFEngine(FRICTION).cls, DEFAULTS, F, omega, a, w_d, 1, TRANSIENT_TOL)
    pullback, _ = measure.pullback()
    for i in (1, 2):
        ours = measure.runs([i], 4, pullback)[0][1]
        theirs = _reference_segment(F, omega, a, w_d, measure.phase(i, 4), pullback,
                                    *(DEFAULTS[name] for name in ("M", "B", "Fc", "Fs")))
        assert abs(ours - theirs) <= 1e-8 * abs(theirs), (i, ours, theirs)


def test_refusals_name_the_value_and_what_is_allowed(engine):
    with pytest.raises(PlantError, match=r"omega = 0\.01 rad/s: .* at most 100 dither periods, omega >= w_d / 100"):
        engine.point(10.0, 0.01, {"a": 10.0, "w_d": 5.0})
    assert 5.0 / R_MAX == 0.05
    with pytest.raises(PlantError, match="w_d: the dither's DF needs"):
        engine.point(10.0, 1.0, {"a": 10.0})
    with pytest.raises(PlantError, match="w_d"):
        engine.point(10.0, 1.0, {"a": 10.0, "w_d": 0.0})
    with pytest.raises(PlantError, match="static-backlash has none"):
        DitherDFEngine(plant("static-backlash"))
    # the map's ranges: forces down to (1 - a / Fs) of the range's end (a dither moves the mass at F + a > Fs),
    # frequencies where a forcing period spans at most R_MAX dither periods
    assert engine.domain((7.0, 100.0), (0.01, 10.0), {"a": 3.5, "w_d": 5.0}) == ((3.5, 100.0), (0.05, 10.0))
    assert engine.domain((7.0, 100.0), (0.01, 10.0), {"a": 10.0, "w_d": 5.0})[0] == (0.07, 100.0)
    assert engine.domain((7.0, 100.0), (0.01, 0.04), {"a": 1.0, "w_d": 5.0}) is None


def test_the_phase_average_is_the_long_time_average(engine):
    # the torus average that the runs compute is what one long run's harmonic tends to where w_d / w is irrational
    # (at w_d / w = 5/3 the long run repeats every 3 periods and sees 3 phases: 0.8 % off, as it should be)
    F, omega, a, w_d = 20.0, 3.0, 10.0, 5.0 * (1.0 + math.sqrt(5.0)) / 3.0
    point = engine.point(F, omega, {"a": a, "w_d": w_d})
    measure = _Measure(engine.cls, DEFAULTS, F, omega, a, w_d, 400, TRANSIENT_TOL)
    pullback, _ = measure.pullback()
    long = np.mean([segment[1] for segment in measure.runs([0], 1, pullback)]) / F
    assert abs(long - point.N) <= 1e-3 * abs(point.N)  # 1.4e-4 measured after 400 periods, 4.6e-6 after 3200
    assert point.periodic and point.N_error <= 1e-3 * abs(point.N)


def test_a_dithered_study_shows_the_dual_input_df_beside_the_truth():
    import dfwb

    response = dfwb.limit_cycles("friction", "20 + 100/s + 2*s/(0.1*s+1)", exact=True, compensate="dither", a=2.0,
                                 w_d=50.0, F_range=(10.0, 30.0), omega_range=(3.0, 8.0), n_F=3, n_omega=4,
                                 amplitudes=[0.3])
    assert response.N_grid.shape == (3, 4) and response.df_described.startswith("its dual-input DF")
    # the undithered DF's unstable cycle (15.56 N at 4.729 rad/s) survives a 2 N dither at 50 rad/s, moved a little
    [cycle] = response.predictions
    assert not cycle.stable and abs(cycle.omega - 4.7292) < 0.01 and abs(cycle.F - 15.56) < 0.05
    assert response.links == [None] and response.as_dict()["df_params"] == dict(response.params, a=2.0, w_d=50.0)
    assert "compensated by dither (a = 2, w_d = 50) (its dual-input DF" in response.summary()


def test_a_scene_maps_the_dithers_df_at_its_own_size_as_the_api_does(tmp_path, monkeypatch):
    # a scene's [[limit_cycle]] without n_F / n_omega takes the DF's own map size, as the API and the CLI do:
    # 4 x 12 for the dither's DF (16 x 48 without a dither)
    import dfwb
    from dfwb.studies import limit_cycles
    from dfwb.studies.scene import parse_scene

    seen, analyse = [], limit_cycles.analyse
    monkeypatch.setattr(limit_cycles, "analyse", lambda *args, **kwargs: seen.append(analyse(*args, **kwargs)) or
                        seen[-1])
    scene = parse_scene('title = "t"\n[[limit_cycle]]\nname = "d"\nplant = "friction"\nG = "10 + 2/s"\n'
                        'params = {a = 1, w_d = 5}\ncompensate = ["dither"]\nexact = true\nF_range = [1, 10]\n'
                        'omega_range = [5, 50]\n', "d.toml")
    assert scene.limit_cycle[0].map_size() == (16, 48)  # (the bound a scene's size is checked against)
    dfwb.run_scene(scene, tmp_path / "out", jobs=1, cache=False, progress=False)
    [response] = seen
    assert response.N_grid.shape == DitherDFEngine.map_size == (4, 12)
