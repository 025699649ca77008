"""The describing function of the static backlash seen through its backlash inverse, in closed form.

The controller of a loop with the backlash inverse (:class:`dfwb.fmus.compensation.BacklashInverse`) sees
``y + k h_hat/2 s``, s the side of the play's last touch. Driven by ``F cos(w t)`` the mass moves as
``x = -X cos(w t)``, ``X = F / (M w^2)`` (its periodic response; a free mass has no other), so what the
controller sees is a function of x's history alone, and its harmonics have a closed form. With x = X cos(theta)
falling from X (theta from 0 to pi; the other half is the same with the sign turned), d = (h_hat - h)/2 and
theta_1 = arccos(1 - h/X):

- the play opens at the top: y holds k (X - h/2), the controller sees ``k (X + d)``, until x has crossed the
  play (theta_1);
- engaged below: y = k (x + h/2), the controller sees ``k (x - d)``.

Its k-th harmonic (odd k; even ones vanish) is ``(2 k_s / pi) [(X + d) E_k(0, theta_1) + X/2 (E_(k-1) + E_(k+1))
(theta_1, pi) - d E_k(theta_1, pi)]``, ``E_m(a, b) = int_a^b exp(-i m theta) d theta``, k_s the slope. Without
the inverse (h_hat = 0, d = -h/2) it is the backlash's own DF (Phillips and Harbor; ``closed_forms.backlash_df``),
and for X <= h/2 the mass swings inside the play: nothing moves, N = 0. ``tests/test_backlash_inverse.py``
checks it against the exact plant's own harmonic integrals, the side taken from its engagements.

:class:`InverseDFEngine` serves it as a DF engine serves a plant (``point(F, omega, params)`` gives a
:class:`~dfwb.engine.describing.DFResult`), its parameters the static backlash's and ``h_hat``: the DF side of a
study of the static backlash with its inverse.
"""

import cmath
import math
import time
from collections.abc import Mapping

from dfwb.base.errors import PlantError
from dfwb.engine.describing import DFResult, check_point
from dfwb.fmus.compensation import BacklashInverse, check_estimate

__all__ = ["harmonics", "InverseDFEngine"]

HARMONICS = 10  # |X_k|, k = 0..10, as the DF engine gives them


def _E(m, a, b):
    """int_a^b exp(-i m theta) d theta."""
    return complex(b - a) if m == 0 else 1j / m * (cmath.exp(-1j * m * b) - cmath.exp(-1j * m * a))


def harmonics(X, k=1.0, h=0.1, h_hat=0.1, n=HARMONICS):
    """The complex harmonics Y_0..Y_n of what the controller sees, ``k y + k h_hat/2 s``, for x = X cos(theta):
    ``sum Re(Y_j exp(i j theta))``; all 0 for X <= h/2 (the play never closes)."""
    Y = [0j] * (n + 1)
    if not X > 0.5 * h:
        return Y
    d, t1 = 0.5 * (h_hat - h), math.acos(1.0 - h / X)
    for j in range(1, n + 1, 2):
        Y[j] = 2.0 * k / math.pi * ((X + d) * _E(j, 0.0, t1) + 0.5 * X * (_E(j - 1, t1, math.pi)
                                                                           + _E(j + 1, t1, math.pi))
                                    - d * _E(j, t1, math.pi))
    return Y


class _Plant:
    """The static backlash with its inverse, as a DF engine's plant: its parameters and ``h_hat`` (required)."""

    def __init__(self, spec):
        self.spec, self.name = spec, spec.name

    def check(self, params):
        if not isinstance(params, Mapping) or "h_hat" not in params:
            self.spec.check(params)  # not a mapping: refused as the plant refuses it
            raise PlantError("h_hat: the backlash inverse's estimated play needs a value")
        params = dict(params)
        h_hat = BacklashInverse(params.pop("h_hat")).h_hat  # its checks, their messages
        checked = self.spec.check(params)
        check_estimate(h_hat, dict(self.spec.defaults(), **checked)["h"])
        return dict(checked, h_hat=h_hat)

    checked = check


class InverseDFEngine:
    """DF points of the static backlash seen through its backlash inverse, in closed form (see the module).

    Parameters
    ----------
    spec : PlantSpec
        The static backlash's (``dfwb.plants.plant("static-backlash")``).

    Examples
    --------
    >>> from dfwb.plants import plant
    >>> engine = InverseDFEngine(plant("static-backlash"))
    >>> none, same = (engine.point(50.0, 20.0, {"h_hat": h_hat}).N for h_hat in (0.0, 0.1))
    >>> none  # X = 0.0625 m behind M = 2 kg: the backlash's own DF
    (-0.00017797311241580873+0.0002546479089470325j)
    >>> round(abs(same.imag / same.real), 4), round(abs(none.imag / none.real), 4)  # the lag the inverse leaves
    (0.8513, 1.4308)
    """

    drive = "closed form"
    described = "the play seen through the inverse, in closed form"

    def __init__(self, spec):
        if spec.name != "static-backlash":
            raise PlantError(f"the backlash inverse's DF is the static backlash's; {spec.name} has none")
        self.plant = _Plant(spec)

    def point(self, F, omega, params=None):
        """The :class:`~dfwb.engine.describing.DFResult` at force amplitude F [N] and frequency omega [rad/s]."""
        started = time.perf_counter()
        F, omega = check_point(F, omega)
        params = self.plant.checked(params or {})
        values = dict(self.plant.spec.defaults(), **params)
        M, k, h, h_hat = (values[name] for name in ("M", "k", "h", "h_hat"))
        X = F / (M * omega * omega)
        # x = -X cos(omega t) = X cos(theta), theta = omega t + pi: harmonic j turns by (-1)^j against the force
        Y = [value * (-1) ** j for j, value in enumerate(harmonics(X, k, h, h_hat))]
        output = -harmonics(X, k, h, 0.0, 1)[1]  # the plant's y: the same without the inverse
        return DFResult(plant=self.plant.name, F=F, omega=omega, params=params, N=Y[1] / F,
                        harmonics=[abs(value) for value in Y], periodic=True, periods=0,
                        seconds=time.perf_counter() - started, drive=self.drive, X=Y, output=output)
