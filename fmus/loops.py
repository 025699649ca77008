"""A plant in feedback with a linear controller, as an exact hybrid system: :class:`FeedbackLoop`.

    f = -G(s) y,   G(s) = (b0 s^n + ... + bn) / (s^n + a1 s^(n-1) + ... + an),   n = 1..8

The plant's output y drives the controller; its output is the force on the
plant. The controller is realised as :class:`~.linear_system.LinearSystem`
realises it (controllable canonical form, state z), so the loop's state is
the plant's coordinates followed by z, and every mode of the plant makes the
loop an affine system X' = A X + c, integrated exactly by
:class:`~.hybrid.HybridSolver`. Each plant's loop (its modes, its events and
what happens at them) lives beside its solver, in its model module
(``LOOP`` of :mod:`.friction`, :mod:`.backlash`, :mod:`.static_backlash`).

Plain Python only: this module runs inside the FMUs.
"""

from .compensation import compensators, dither_of, follows_control, integrator, inverse_of
from .contract import EventKind
from .exact import PlantError
from .hybrid import HybridSolver
from .linear_system import LinearSystem
from .piecewise import check

MAX_SWITCHES = 1000  # the Coulomb feedforward chatters when it switches this many times in a row (no event of
CHATTER_CHUNKS = 10.0  # the plant between), or within a window of this many chunks of the loop's fastest mode

__all__ = ["FeedbackLoop", "STICK", "FREE"]

STICK = ("stick", 0)
FREE = ("free", 0)


def _controller(b, a):
    """(Ac, Bc, C, D) of -G(s): the force is -G(s) y (checked as LinearSystem checks it)."""
    system = LinearSystem(b, a)
    Ac, Bc, C, D = system.matrices()
    return Ac, Bc, [-value for value in C], -D


class FeedbackLoop(HybridSolver):
    """A plant whose coordinates are ``q`` (``coordinates``), y = q[OUTPUT], in feedback with -G(s).

    Subclasses describe each mode by the plant's part (:meth:`plant_mode`):
    q' = P q + p + phi f, and event functions Lq.q + Lf f + l0; this class
    couples them with the controller into the loop's A, c and L.

    ``state`` (the whole loop state) overrides the initial values; ``section``
    watches the output rising through that level (``crossings``); ``modes``
    (a dict) and ``budget`` (a :class:`~.hybrid.Budget`) are shared by the
    solvers of one study. ``compensation``: a compensator between the
    controller and the plant (:class:`~.compensation.Coulomb`,
    :class:`~.compensation.Reset`, :class:`~.compensation.Deadband`,
    :class:`~.compensation.Dither`, :class:`~.compensation.BacklashInverse`),
    a list of them, or None. A dither's oscillator is two more coordinates of
    the integrated state, after z, and the backlash inverse's correction one
    more after them; a state given, read or sampled (``state``,
    :meth:`state`) is the plant's coordinates and z alone, the dither at
    phase 0 when it starts and the correction from the play's contact then
    (0 inside the play).
    """

    coordinates = ()
    OUTPUT = 0
    initial_parameters = ()  # the plant parameters that set q at t = 0 (superseded by ``state``)
    plant = None  # the plant's open-loop solver (:mod:`.friction` ...): its orbits start a shooting
    KEYS = ()  # the mode keys, in the compiled core's order
    REST_EVENTS = ()  # the event kinds where the plant comes to rest (the integrator reset acts there)
    CONTACTS = {}  # {event kind: the side of the play it touches}: where the backlash inverse's side is set
    # The Poincare section every periodic orbit crosses: legs, each the (mode key, event kind) pairs that end it
    # (an event of the first leg, then one of the second: a lower turn, then an upper one). A point of the
    # section is the state the last leg's event leaves; there coordinate PIVOT is fixed by the others (pivot()).
    SECTION = ()
    PIVOT = 0
    # A second section, (legs, pivot) as SECTION and PIVOT, for motions that never cross the first (None: none);
    # there coordinate pivot is alternate_pivot()
    ALTERNATE = None
    # What the loop's FMU (:mod:`.loop_facade`) and the compiled twin (:mod:`.native_core`) read:
    MODE_VALUES = {}  # {mode key: the FMU's mode output}: every mode the loop can be in
    CONSTANTS = ()  # the constants a run never changes, in the C core's order (dfwb_loop_parameters)
    FMU_OUTPUTS = ()  # the FMU's continuous outputs (table.Output): fmu_values' keys, in order
    MODE_OUTPUT = None  # the FMU's mode output (table.Output)
    COUNTER = None  # what the loop counts (table.Output; an attribute of that name)
    FMU_RANGES = {}  # {parameter: (min, max)} of the loop's FMU beyond the plant's
    FMU_DESCRIPTIONS = {}  # {parameter: its description in the loop's FMU}, where the plant's does not fit

    @staticmethod
    def fmu_values(loop, X, f):
        """{name: value} of FMU_OUTPUTS for ``loop`` (this class or its compiled twin) at state X, force f."""
        raise NotImplementedError

    @staticmethod
    def coordinates_of(output):
        """The loop's plant coordinates q from the open-loop solver's ``output()``."""
        raise NotImplementedError

    def check_coordinates(self, q):
        """Refuse plant coordinates that are no state of the plant (PlantError naming them)."""

    def translate(self, q, d):
        """q with the plant moved so that its output moves by d (the plant is translation invariant)."""
        q = list(q)
        q[self.OUTPUT] += d
        return q

    def pivot(self, X):
        """The value of coordinate PIVOT on the section, given the state's other coordinates."""
        raise NotImplementedError

    def alternate_pivot(self, X):
        """The value of ALTERNATE's pivot coordinate on that section, given the state's other coordinates."""
        raise NotImplementedError

    def linear(self):
        """(num, den) of the plant with its nonlinearity removed, from the force to the output."""
        raise NotImplementedError

    def nonlinearity(self):
        """("force", F) or ("length", d): the size of the nonlinearity, as a force or in output units."""
        raise NotImplementedError

    def still(self, F, omega):
        """Whether F cos(omega t) leaves the output still (its describing function is 0 there)."""
        raise NotImplementedError

    def wall(self, X):
        """The side of the play whose wall the state X sits on (-1, +1; 0 within): the backlash inverse's side at
        t = 0."""
        return 0

    def half_play(self):
        """Half the play's width in the output's units per unit of h (the static backlash's k / 2): the backlash
        inverse's correction is this times h_hat times the side."""
        raise NotImplementedError

    def __init__(self, b, a, q0, z0=None, state=None, section=None, modes=None, budget=None, compensation=None):
        self.coulomb, reset, self.deadband = compensators(compensation)
        coulomb = self.coulomb
        # the Coulomb feedforward of the controller's sign: its current sign, a discrete state of the loop
        self._on_control = follows_control(coulomb)
        self.Ac, self.Bc, self.C, self.D = self.controller(b, a)
        # the integrator's coordinate xi = w . z: reset when the mass comes to rest, held within the deadband
        self._integrator = integrator(a) if reset or self.deadband is not None else None
        self._reset_at_rest = reset
        if reset and not self.REST_EVENTS:
            raise PlantError(f"the integrator reset needs a plant that comes to rest; {type(self).__name__} "
                             "has no such event")
        self.sigma = 0
        self._in_row, self._row_start = 0, 0.0  # the feedforward's switches since the plant's last event, from
        self._window = [0.0, 0]  # ... and in the current window of CHATTER_CHUNKS chunks: [its start, count]
        self.band = 1  # the deadband's side: -1 below -d, 0 within (the integrator holds), +1 above d
        self.dither = dither_of(compensation)  # a sin(w_d t): the oscillator (s, c) after z, from (0, a)
        oscillator = [] if self.dither is None else [0.0, self.dither.a]
        self.inverse = inverse_of(compensation)  # y + k h_hat/2 s seen by the controller: the correction after all
        if self.inverse is not None and not self.CONTACTS:
            raise PlantError(f"the backlash inverse needs a plant with a play between the mass and the output; "
                             f"{type(self).__name__} has none")
        oscillator += [] if self.inverse is None else [0.0]
        self._discrete = self._on_control or self.deadband is not None  # modes cached by (key, sigma, band)
        self.order = n = len(self.Ac)
        m = len(self.coordinates)
        if state is not None:  # the whole loop state: the plant's coordinates, then z
            check("length of state", len(state), len(state) == m + n,
                  f"the loop's state has {m} plant coordinates {self.coordinates} and {n} controller states")
            q0, z0 = list(state[:m]), list(state[m:])
            for name, value in zip(self.coordinates, q0):
                check(name, value, True, f"{name} must be a finite number")
            self.check_coordinates(q0)
        z0 = [0.0] * n if z0 is None else list(z0)
        check("length of z0", len(z0), len(z0) == n, f"z0 needs {n} components (the controller's order)")
        for i, value in enumerate(z0, start=1):
            check(f"z{i}_0", value, True, f"the controller state z{i}_0 must be a finite number")
        watch = None
        if section is not None:  # upward crossings of y through the level ``section``
            check("section", section, True, "the section level must be a finite number")
            L = [0.0] * (m + n + len(oscillator))
            L[self.OUTPUT] = 1.0
            watch = (L, -float(section))
        super().__init__(watch, modes, budget)
        X0 = list(q0) + z0 + oscillator
        if self.inverse is not None:  # a start on a wall of the play has touched it
            self._contact(self.wall(X0), X0)
        if self.deadband is not None:
            y = X0[self.OUTPUT] + (0.0 if self.inverse is None else X0[self._correction])
            self.band = 0 if abs(y) < self.deadband else 1 if y > 0.0 else -1
        if self._on_control:  # its sign at t = 0; where the force is 0 there, its trend in the plant's mode
            f = self.force(X0)
            self.sigma = (f > 0.0) - (f < 0.0)
        key, X0, departing = self.initial(X0)
        if self._on_control and self.sigma == 0:
            self.sigma = self._control_sign(key, X0)
        self.start(0.0, X0, key, departing)

    # -- the loop's equations --------------------------------------------------------
    def controller(self, b, a):
        """(Ac, Bc, C, D) of what drives the plant, z' = Ac z + Bc y and f = C z + D y: the controller -G(s)
        (a forced open loop, dfwb.engine.dither_df, drives it with an autonomous generator instead)."""
        return _controller(b, a)

    def force(self, X):
        """f = -G(s) y: D y + C z at the state X (y corrected by the backlash inverse in an integrated state)."""
        m, n = len(self.coordinates), self.order
        y = X[self.OUTPUT] + (X[self._correction] if self.inverse is not None and len(X) > m + n else 0.0)
        return self.D * y + sum(c * z for c, z in zip(self.C, X[m:m + n]))

    @property
    def _correction(self):
        """The index of the backlash inverse's correction in the integrated state (the last coordinate)."""
        return len(self.coordinates) + self.order + (0 if self.dither is None else 2)

    def _contact(self, side, X):
        """Set the backlash inverse's correction in X where the play touched its side ``side`` (0: none):
        whether it changed (the controller's force then jumps)."""
        if self.inverse is None or not side:
            return False
        correction = self.half_play() * self.inverse.h_hat * side
        changed, X[self._correction] = X[self._correction] != correction, correction
        return changed

    def applied(self, X):
        """The force on the plant at the integrated state X: the controller's, the compensator's (constant in the
        mode) and the dither's."""
        dither = 0.0 if self.dither is None else X[len(self.coordinates) + self.order]
        return self.force(X) + self.feedforward(self.key, self.sigma if self._on_control else None) + dither

    def visible(self, X):
        """The loop's state in the integrated state X: the plant's coordinates and z (a dither's oscillator and a
        backlash inverse's correction left out)."""
        return X if self.dither is None and self.inverse is None else X[:len(self.coordinates) + self.order]

    def readings(self, times):
        """(states, forces on the plant) at each of ``times`` (non-decreasing, from self.t), advancing to them in
        turn: what a step response is read from."""
        states, forces = [], []
        for t in times:
            self.advance(float(t))
            X = self._integrated()
            states.append(self.visible(X))
            forces.append(self.applied(X))
        return states, forces

    def feedforward(self, key, sign):
        """The Coulomb feedforward's force in plant mode ``key``: F_hat times the controller's sign ``sign``, or
        (None) the plant's slip there; 0 without a feedforward (or with F_hat = 0, whatever the plant)."""
        if self.coulomb is None or self.coulomb.F_hat == 0.0:
            return 0.0
        return self.coulomb.F_hat * (sign if sign is not None else self.slip(key))

    def mode(self, key):
        """The mode of plant key ``key``; with a compensator's discrete state (the controller's sign, the
        deadband's side), of ``key`` at the current one."""
        return super().mode((key, self.sigma, self.band) if self._discrete else key)

    def slip(self, key):
        """The plant's sliding direction in mode ``key`` (-1, 0 stuck, +1): the velocity's sign the Coulomb
        feedforward takes; a plant without friction has none (PlantError)."""
        raise PlantError(f"the Coulomb feedforward of the velocity needs a plant with friction; "
                         f"{type(self).__name__} has none (use the controller's signal)")

    def system(self, key):
        sign, band = None, 1
        if self._discrete:
            key, sign, band = key
            sign = sign if self._on_control else None
        P, p, phi, events, *nonlinear = self.plant_mode(key)
        m, n, out = len(self.coordinates), self.order, self.OUTPUT
        # the dither's oscillator (s, c): s = a sin(w_d t); the backlash inverse's correction w: y + w seen
        e = (0 if self.dither is None else 2) + (0 if self.inverse is None else 1)
        seen = [out] + ([] if self.inverse is None else [self._correction])  # the controller's input: y (+ w)
        # f = D y + C z: a row over the whole state; the plant sees f, the dither's s and k (below)
        f_row = [0.0] * (m + n + e)
        for i in seen:
            f_row[i] += self.D
        f_row[m:m + n] = list(self.C)
        on_plant = list(f_row)
        if self.dither is not None:
            on_plant[m + n] = 1.0
        A = []
        for i in range(m):
            row = list(P[i]) + [0.0] * (n + e)
            A.append([value + phi[i] * fv for value, fv in zip(row, on_plant)])
        Bc = self.Bc if band else self._held_Bc()  # within the deadband the integrator's mode holds
        for i in range(n):
            row = [0.0] * m + list(self.Ac[i]) + [0.0] * e
            for j in seen:
                row[j] += Bc[i]
            A.append(row)
        if self.dither is not None:  # s' = w_d c, c' = -w_d s
            w_d = self.dither.w_d
            A.append([0.0] * (m + n) + [0.0, w_d] + [0.0] * (e - 2))
            A.append([0.0] * (m + n) + [-w_d, 0.0] + [0.0] * (e - 2))
        if self.inverse is not None:  # w' = 0: set where the play makes contact
            A.append([0.0] * (m + n + e))
        # the compensator's force k, constant in the mode: the plant sees f + s + k
        k = self.feedforward(key, sign)
        c = [value + phi_i * k for value, phi_i in zip(p, phi)] + [0.0] * (n + e)
        full = []
        for kind, Lq, Lf, l0 in events:
            L = list(Lq) + [0.0] * (n + e)
            full.append((kind, [value + Lf * fv for value, fv in zip(L, on_plant)], l0 + Lf * k))
        if sign:  # the controller's force keeps its sign: sign * f > 0 until it reaches 0
            full.append((EventKind.COULOMB, [sign * fv for fv in f_row], 0.0))
        if self.deadband is not None:  # outside: band * y - d > 0; within: d - y > 0 and d + y > 0
            d = self.deadband
            for side, l0 in ([(band, -d)] if band else [(-1, d), (1, d)]):
                L = [0.0] * (m + n + e)
                for i in seen:
                    L[i] = float(side)
                full.append((EventKind.DEADBAND, L, l0))
        return (A, c, full) + tuple(nonlinear)  # (row, col, law) of a mode integrated: plant coordinates first

    def _control_sign(self, key, X):
        """The controller's force's sign just after X in plant mode ``key`` (its trend where it is 0), the
        feedforward of either sign tried: +1 or -1 where one keeps the force's sign, 0 where it stays 0."""
        held, found = self.sigma, []
        try:
            for sign in (1, -1):
                self.sigma = sign
                found.append(self.after(key, self.function_index(key, EventKind.COULOMB), X))
        finally:
            self.sigma = held
        if found[0] > 0:
            return 1
        if found[1] > 0:
            return -1
        if found == [0, 0]:
            return 0
        raise PlantError(f"the controller's force slides along 0 at t = {self.t!r} (the Coulomb feedforward of its "
                         "sign would chatter: a sliding mode, not solved)")

    def _held_Bc(self):
        """The controller's input column with its integrator held: Bc - e_1 / w_1 (then xi' = w . z' = 0, and
        the other modes move as before)."""
        return [self.Bc[0] - 1.0 / self._integrator[0]] + list(self.Bc[1:])

    def _switch(self, t, kind, X):
        if kind is EventKind.DEADBAND:
            return self._cross_edge(X)
        if kind is not EventKind.COULOMB:
            self._in_row = 0
            if self._reset_at_rest and kind in self.REST_EVENTS:
                self._reset(X)  # the controller's force jumps: the feedforward of its sign follows it
                if self._on_control:
                    self.sigma = self._control_sign(self.key, X)
            # the play's touch: the backlash inverse's correction jumps before the plant's logic, which sees its force
            touched = self._contact(self.CONTACTS.get(kind, 0), X)
            key, X, departing = self._fire(t, kind, X)
            if touched and self._on_control:  # the controller's force jumped: the feedforward of its sign follows
                self.sigma = self._control_sign(key, X)
            if self._on_control and self.sigma == 0:
                self.sigma = self._control_sign(key, X)
            return key, X, departing
        if self._in_row == 0:
            self._row_start = t
        self._in_row += 1
        width = CHATTER_CHUNKS * min(mode.resolution for mode in self._modes.values())
        if not self._window[1] or t - self._window[0] > width:
            self._window = [t, 0]  # a new window of switches, from this one
        self._window[1] += 1
        if self._in_row >= MAX_SWITCHES or self._window[1] >= MAX_SWITCHES:
            row = self._in_row >= MAX_SWITCHES
            raise PlantError(f"the Coulomb feedforward of the controller's sign switched {MAX_SWITCHES} times from "
                             f"t = {self._row_start if row else self._window[0]!r} to {t!r} s"
                             + (", with no event of the plant between" if row else "")
                             + ": it chatters (it over-compensates the friction); not solved")
        self.sigma = self._control_sign(self.key, X)
        return self.settle(self.key, X)

    def _cross_edge(self, X):
        """(key, X, departing) at a deadband edge: from outside, in through the edge of its side; from within,
        out where the motion goes (the edge function falling through zero, by its trend: y's sign cannot tell
        where the band is narrower than y's rounding). The edge crossed departs in the new mode (else its
        rounding fires it back and forth at one instant)."""
        first = self.function_index(self.key, EventKind.DEADBAND)  # within: d - y, then d + y
        if self.band:
            side, self.band = self.band, 0
            return self.key, X, first + (0 if side > 0 else 1)
        self.band = 1 if self.after(self.key, first, X) < 0 else -1
        return self.key, X, self.function_index(self.key, EventKind.DEADBAND)

    def _reset(self, X):
        """Clear the controller's integrator in X, its other modes kept: z -= (w . z / w_1) e_1."""
        m, w = len(self.coordinates), self._integrator
        X[m] -= sum(wi * zi for wi, zi in zip(w, X[m:])) / w[0]

    def settle(self, key, X):
        """(key, X, departing) after the force on the plant jumped at X in mode ``key`` (a compensator
        switched): a stuck plant may break away. Default: the mode goes on."""
        return key, X, None

    def plant_mode(self, key):
        """(P, p, phi, events) of mode ``key``: q' = P q + p + phi f, and event functions (kind, Lq, Lf, l0);
        or (P, p, phi, events, (row, col, law)) where law(q[col]) adds to q'[row] (a mode with no closed form,
        integrated: :class:`~.integrated.IntegratedMode`)."""
        raise NotImplementedError

    def initial(self, X):
        """(mode key, state, departing event index) at t = 0."""
        raise NotImplementedError

    # -- outputs -------------------------------------------------------------------------
    def output(self):
        """The plant's output y at self.t."""
        return self.state()[self.OUTPUT]

    def counts(self):
        """{COUNTER's name: what the loop counted} (stick phases, impacts, engagements)."""
        return {self.COUNTER.name: getattr(self, self.COUNTER.name)}
