"""Closed forms: the static backlash describing function and the backlash validity range.

These are the analytic results the simulated describing functions are
checked against (docs/models.md section 3).

Examples
--------
>>> from dfwb.plants.closed_forms import backlash_df, static_backlash_plant_df, validity_frequencies
>>> complex(backlash_df(0.1, k=1.0, h=0.1))  # X = h: the output moves half the time
(0.5-0.3183098861837907j)
>>> complex(static_backlash_plant_df(50.0, 20.0))  # X = 0.0625 m behind M = 2 kg
(-0.00017797311241580873+0.0002546479089470325j)
>>> {name: round(value, 2) for name, value in validity_frequencies(50.0, eps=0.5).items()}
{'w_C': 13.3, 'w_J': 22.36, 'w_L': 44.72}
"""

import numpy as np

from dfwb.base.errors import InputError
from dfwb.fmus.backlash import TABLE as BACKLASH
from dfwb.fmus.static_backlash import TABLE as STATIC_BACKLASH

_bl, _sb = BACKLASH.default, STATIC_BACKLASH.default  # the plants' defaults


def backlash_df(X, k=_sb.k, h=_sb.h):
    """Describing function N(X) of the backlash element (Phillips and Harbor; eq. 6-7).

    Slope ``k``, total dead band ``h`` (play +-h/2), input amplitude ``X``;
    N(X) = 0 for X <= h/2. Works on scalars and arrays.

    Parameters
    ----------
    X : float or array_like
        Amplitude of the sinusoidal input, > 0.
    k, h : float
        Slope and total width of the backlash.

    Returns
    -------
    complex or ndarray of complex
    """
    X = np.asarray(X, dtype=float)
    if np.any(~np.isfinite(X)) or np.any(X <= 0):
        raise InputError(f"X = {X!r} is out of range: amplitudes must be finite and > 0")
    engaged = X > h / 2
    Xe = np.where(engaged, X, h)  # placeholder where not engaged (the result is 0 there)
    d = 1.0 - h / Xe
    real = k / np.pi * (np.pi / 2 + np.arcsin(d) + d * np.sqrt(1.0 - d * d))
    imag = -2.0 * k * h * (Xe - h / 2) / (np.pi * Xe * Xe)
    N = np.where(engaged, real + 1j * imag, 0j)
    return N[()] if N.ndim == 0 else N


def static_backlash_plant_df(F, omega, M=_sb.M, k=_sb.k, h=_sb.h):
    """DF of the static-backlash plant: a mass M driven by F cos(w t), then the backlash.

    ``N_total = G_lin(jw) N(X)`` with ``G_lin = 1/(M s^2)`` and ``X = F/(M w^2)``,
    so ``-1/N_total = M w^2 / N(X)``.
    """
    F, omega = np.asarray(F, dtype=float), np.asarray(omega, dtype=float)
    X = F / (M * omega ** 2)
    return -backlash_df(X, k, h) / (M * omega ** 2)


def validity_frequencies(F, M2=_bl.M2, h=_bl.h, eps=_bl.eps):
    """The dynamic backlash's frequencies quoted by the paper (output within the clearance).

    ``w_C = [(2F/(M2 h))^2 (1 - eps)^5]^(1/4) < w < w_L = 2 (F/(M2 h))^(1/2)``,
    with a jump near ``w_J = (F/(M2 h))^(1/2)``.

    Returns
    -------
    dict with keys ``w_C``, ``w_J``, ``w_L`` (rad/s)
    """
    ratio = F / (M2 * h)
    return {
        "w_C": float(((2.0 * ratio) ** 2 * (1.0 - eps) ** 5) ** 0.25),
        "w_J": float(np.sqrt(ratio)),
        "w_L": float(2.0 * np.sqrt(ratio)),
    }
