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

:class:`Deadband` holds the controller's integrator while the error is
within ``d`` of the target (|y| < d): its mode of the pole at 0 stops, the
others go on; an event where |y| reaches d. :class:`Reset` clears the
controller's integrator when the mass comes to rest, before it sticks or breaks away (integrator management, the same
survey's section 6.3; Olsson and Astrom, 2001). The integrator is the
controller's mode of its pole at 0: in the controllable canonical form
(:mod:`.linear_system`) its coordinate is ``xi = w . z`` with
``w = (a_(n-1), ..., a_1, 1)`` (``xi' = y``), and the reset removes it along
its direction ``e_1``, leaving the controller's other modes as they are
(:func:`integrator`).

The loop (:class:`~.loops.FeedbackLoop`) stays piecewise affine: the
compensator's force is constant between its switches, so every mode is still
integrated in closed form.

:class:`Dither` adds ``a sin(w_d t)`` to the force, t from the loop's start.
The loop stays autonomous and affine with the sine as the state of a harmonic
oscillator, (s, c)' = w_d (c, -s) from (0, a): two coordinates appended to
the loop's state, integrated exactly with the rest, so every event (a
breakaway that the dither triggers) is located as exactly as the plant's.
The loop is then periodically forced: its responses are studied at the
dither's period (:mod:`dfwb.engine.dither`).

:class:`BacklashInverse` undoes a play that follows the mass (the static
backlash: x drives y through a play of width h, slope k). Tao and
Kokotovic's inverse (IEEE TAC 38(3), 1993; Nordin and Gutman's survey,
Automatica 38, 2002, section 4) puts the play's two lines, ``x = y/k +- h/2``,
back into the signal, choosing the line by the direction of motion and
holding it while the direction is unknown. Here the play sits between the
mass and the sensor, so no command enters it: the inverse acts where the
play is seen, on the measurement. The controller gets ``y + k h_hat/2 s``,
``s`` the side of the play's last touch (+1 after the mass last reached the
play's upper edge, -1 the lower, 0 before any): with ``h_hat = h`` that is
``k x`` whenever the play is closed. Equivalently the commanded position is
moved by ``-k h_hat/2 s``. The side changes where the play is touched, an
event of the plant (of the two-mass backlash and the drivetrain too, at M2's
walls): the correction is a coordinate of the loop's state, constant between
touches and set at them, so the loop stays affine and exact.

Plain Python only: this module runs inside the FMUs.
"""

from .exact import PlantError
from .piecewise import check

__all__ = ["Coulomb", "Reset", "Deadband", "Dither", "BacklashInverse", "SIGNALS", "compensators", "dither_of",
           "inverse_of", "check_estimate", "follows_control", "integrator"]

SIGNALS = ("velocity", "control")
MAX_PLAY = 1e3  # [m] a backlash inverse's h_hat at most (the largest play h of the plants)


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
        check("F_hat", F_hat, lambda: F_hat >= 0.0, "a finite number of newtons, at least 0")
        if signal not in SIGNALS:
            raise PlantError(f"signal = {signal!r} is not a signal of the Coulomb feedforward (allowed: "
                             f"{', '.join(SIGNALS)})")
        self.F_hat, self.signal = float(F_hat), signal

    def __repr__(self):
        return f"Coulomb(F_hat={self.F_hat!r}, signal={self.signal!r})"


class Reset:
    """The integrator reset: the controller's integrator cleared when the mass comes to rest."""

    name = "reset"

    def __repr__(self):
        return "Reset()"


class Deadband:
    """The integrator deadband: the controller's integrator holds while |y| < d.

    Parameters
    ----------
    d : float
        The error band [m, the output's unit], at least 0 (0: none).
    """

    name = "deadband"

    def __init__(self, d):
        check("d", d, lambda: d >= 0.0, "the error band of the integrator deadband, a finite number at least 0")
        self.d = float(d)

    def __repr__(self):
        return f"Deadband(d={self.d!r})"


class Dither:
    """Dither: ``a sin(w_d t)`` added to the force on the plant, t from the loop's start.

    Parameters
    ----------
    a : float
        Its amplitude [N], at least 0 (0: none).
    w_d : float
        Its angular frequency [rad/s], positive and finite.
    """

    name = "dither"

    def __init__(self, a, w_d):
        check("a", a, lambda: a >= 0.0, "the dither's amplitude, a finite number of newtons, at least 0")
        check("w_d", w_d, lambda: w_d > 0.0, "the dither's angular frequency, a finite number of rad/s above 0")
        self.a, self.w_d = float(a), float(w_d)

    def __repr__(self):
        return f"Dither(a={self.a!r}, w_d={self.w_d!r})"


class BacklashInverse:
    """The backlash inverse: the controller sees ``y + k h_hat/2 s``, s the side of the play's last touch.

    Parameters
    ----------
    h_hat : float
        The estimated total width of the play [m, the plant's h], at least 0 (0: none).
    """

    name = "backlash-inverse"

    def __init__(self, h_hat):
        check("h_hat", h_hat, lambda: 0.0 <= h_hat <= MAX_PLAY,
              "the backlash inverse's estimated play, a number of metres from 0 to 1000")
        self.h_hat = float(h_hat) + 0.0  # (-0.0 is 0)

    def __repr__(self):
        return f"BacklashInverse(h_hat={self.h_hat!r})"


_TYPES = (Coulomb, Reset, Deadband, Dither, BacklashInverse)
MAX_ESTIMATE = 10.0  # a backlash inverse's h_hat at most this many times the plant's play (analysis refuses more)


def check_estimate(h_hat, h):
    """Refuse a backlash inverse's ``h_hat`` beyond MAX_ESTIMATE times the plant's play ``h`` (PlantError, one
    line): an estimate that far off is no estimate."""
    if not h_hat <= MAX_ESTIMATE * h:
        raise PlantError(f"h_hat = {h_hat!r} is out of range: the backlash inverse's estimate of the play h = "
                         f"{h!r} m, at most {MAX_ESTIMATE:g} times it")


def _given(compensation):
    """The compensators of ``compensation`` (None, one, or a list of them, each kind once); PlantError otherwise."""
    given = [] if compensation is None else list(compensation) if isinstance(compensation, (list, tuple)) \
        else [compensation]
    kinds = [type(c) for c in given]
    if any(kind not in _TYPES for kind in kinds) or len(set(kinds)) != len(kinds):
        raise PlantError(f"compensation = {compensation!r:.120} is not a compensator of the loop (a Coulomb, a "
                         "Reset, a Deadband, a Dither, a BacklashInverse, or a list of them, each once)")
    return given


def compensators(compensation):
    """(the Coulomb or None, whether to reset, the deadband's d or None) of ``compensation``: None, a
    compensator, or a list of them (each kind at most once); PlantError otherwise."""
    given = _given(compensation)
    kinds = [type(c) for c in given]
    coulomb = next((c for c in given if isinstance(c, Coulomb)), None)
    band = next((c.d for c in given if isinstance(c, Deadband) and c.d > 0.0), None)
    return coulomb, Reset in kinds, band


def dither_of(compensation):
    """The :class:`Dither` of ``compensation`` that acts (a > 0), or None."""
    return next((c for c in _given(compensation) if isinstance(c, Dither) and c.a > 0.0), None)


def inverse_of(compensation):
    """The :class:`BacklashInverse` of ``compensation`` that acts (h_hat > 0), or None."""
    return next((c for c in _given(compensation) if isinstance(c, BacklashInverse) and c.h_hat > 0.0), None)


def follows_control(compensation):
    """Whether ``compensation`` (as :func:`compensators` takes it) holds a Coulomb feedforward of the controller's
    sign that acts (F_hat > 0): a discrete state and an event of the loop that only the Python loop runs."""
    coulomb = compensators(compensation)[0]
    return coulomb is not None and coulomb.signal == "control" and coulomb.F_hat > 0.0


def integrator(a):
    """The integrator's coordinate ``w`` of a controller with denominator ``s^n + a_1 s^(n-1) + ... + a_n``
    (``a``): ``xi = w . z``, ``w = (a_(n-1), ..., a_1, 1)``; PlantError unless it has one integrator (a_n = 0,
    a_(n-1) != 0; a_0 = 1)."""
    a = list(a)
    if not a or a[-1] != 0.0 or (len(a) > 1 and a[-2] == 0.0):
        has = "none" if not a or a[-1] != 0.0 else "a double one"
        raise PlantError("integrator management (reset, deadband) needs a controller with one integrator, a "
                         f"simple pole at s = 0: this G(s) has {has} (its denominator's coefficients after s^n: "
                         f"{a!r})")
    w = list(reversed(a[:-1])) + [1.0]
    if not abs(1.0 / w[0]) < float("inf"):  # the held integrator's column has 1 / w_1
        raise PlantError(f"a{len(a) - 1} = {w[0]!r} is out of range: integrator management (reset, deadband) needs "
                         f"1 / a{len(a) - 1} finite (the integrator's coordinate is a{len(a) - 1} z_1 + ...)")
    return w
