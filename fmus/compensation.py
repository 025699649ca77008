"""Compensators in the exact closed loop: what is added to the controller's force before it reaches the plant.

:class:`Coulomb` is Coulomb friction feedforward, ``F_hat sign(signal)``
added to the controller's force -G(s) y (Armstrong-Helouvry, Dupont and
Canudas de Wit, Automatica 30(7), 1994, section 6.1). Its ``signal`` is

- ``"velocity"``: the sign of the sliding velocity; zero while the mass
  sticks. On a plant whose mode carries the slip direction (the friction
  mass, the Stribeck mass) this is exact with no event of its own: in a
  slide of direction s the plant sees ``F_hat s`` more, as if its Coulomb
  level were ``Fc - F_hat`` (over-compensation, ``F_hat > Fc``, included).
- ``"control"``: the sign of the controller's force. It acts while the mass
  sticks (the force it adds counts against the breakaway level Fs) and
  switches where the controller's force crosses zero: an event of the loop
  (:attr:`~.contract.EventKind.COULOMB`), located as exactly as the plant's.

The loop (:class:`~.loops.FeedbackLoop`) stays piecewise affine: the
compensator's force is constant between its switches, so every mode is still
integrated in closed form.

Plain Python only: this module runs inside the FMUs.
"""

import math

from .exact import PlantError

__all__ = ["Coulomb", "SIGNALS"]

SIGNALS = ("velocity", "control")


class Coulomb:
    """Coulomb friction feedforward: ``F_hat sign(signal)`` added to the controller's force.

    Parameters
    ----------
    F_hat : float
        The friction level compensated [N], at least 0 (0: none).
    signal : {"velocity", "control"}
        Whose sign it takes: the plant's sliding velocity, or the controller's force.
    """

    name = "coulomb"

    def __init__(self, F_hat, signal="velocity"):
        if isinstance(F_hat, bool) or not isinstance(F_hat, (int, float)) or not (math.isfinite(F_hat) and
                                                                                 F_hat >= 0.0):
            raise PlantError(f"F_hat = {F_hat!r} is out of range: a finite number of newtons, at least 0")
        if signal not in SIGNALS:
            raise PlantError(f"signal = {signal!r} is not a signal of the Coulomb feedforward (allowed: "
                             f"{', '.join(SIGNALS)})")
        self.F_hat, self.signal = float(F_hat), signal

    def __repr__(self):
        return f"Coulomb(F_hat={self.F_hat!r}, signal={self.signal!r})"
