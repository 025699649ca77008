"""Mass + static backlash: the output is the play operator of x, and its DF is eq. 6-7."""

import math

import numpy as np
import pytest

from dfwb.fmus import PlantError, StaticBacklash


def play(xs, k, h, y0):
    """The backlash (play) operator on a sampled input: exact when x is monotone between samples."""
    y, out = y0, []
    for x in xs:
        y = min(max(y, k * (x - h / 2)), k * (x + h / 2))
        out.append(y)
    return np.array(out)


def backlash_df(X, k, h):
    """Phillips-Harbor describing function of the backlash element (docs/models.md eq. 6-7)."""
    if X <= h / 2:
        return 0j
    d = 1 - h / X
    real = k / math.pi * (math.pi / 2 + math.asin(d) + d * math.sqrt(1 - d * d))
    imag = -2 * k * h * (X - h / 2) / (math.pi * X * X)
    return complex(real, imag)


@pytest.mark.parametrize("F, w, k", [(50.0, 20.0, 1.0), (50.0, 10.0, 2.5), (3.0, 5.0, 0.5)])
def test_output_is_the_play_operator_of_the_position(F, w, k):
    """With F cos(w t) from rest, x is monotone between t = n pi / w: sample exactly there."""
    plant = StaticBacklash(F=F, omega=w, k=k)
    xs, ys = [], []
    for t in np.arange(1, 200 * 16 + 1) * (math.pi / w) / 16:
        plant.advance(t)
        x, _v, y = plant.output()
        xs.append(x)
        ys.append(y)
    expected = play(xs, k, plant.h, 0.0)
    scale = k * max(abs(np.array(xs)).max(), plant.h)
    assert np.max(np.abs(np.array(ys) - expected)) <= 1e-12 * scale


@pytest.mark.parametrize("X_over_h", [0.5001, 0.6, 1.0, 3.0, 100.0])
def test_first_harmonic_of_y_is_the_closed_form_df(X_over_h):
    """x = X (1 - cos w t) from rest, so Y1 = -X N(X): exact from the second period on."""
    M, h, k, w = 2.0, 0.1, 1.0, 20.0
    X = X_over_h * h
    F = X * M * w * w
    plant = StaticBacklash(M=M, h=h, k=k, F=F, omega=w)
    T = 2 * math.pi / w
    plant.advance(2 * T)
    i1 = plant.integrals()[1]
    plant.advance(22 * T)
    Y1 = 2 * (plant.integrals()[1] - i1) / (20 * T)
    # 1e-10: near X = h/2 the output y keeps a mean 5000 times its swing, which costs digits
    assert Y1 / (-X) == pytest.approx(backlash_df(X, k, h), rel=1e-10)


def test_no_engagement_below_half_the_play():
    plant = StaticBacklash(F=0.99 * 0.05 * 2.0 * 400.0 / 2, omega=20.0)  # 2X = 0.99 h/2 peak to peak
    plant.advance(10.0)
    assert plant.output()[2] == 0.0 and plant.events == 0


@pytest.mark.parametrize("kwargs, name", [
    ({"M": 0.0}, "M"), ({"k": 0.0}, "k"), ({"h": 0.0}, "h"), ({"h": -1.0}, "h"), ({"x0": math.nan}, "x0"),
])
def test_bad_parameters_are_refused_with_their_name(kwargs, name):
    with pytest.raises(PlantError, match=rf"^{name} = .* is out of range"):
        StaticBacklash(**kwargs)
