"""A model-exchange FMU integrated by dfwb, with an input law and states of dfwb's own riding along.

The state is ``z = [x, w]``: x the FMU's continuous states, w dfwb's (the
Fourier integrals of a DF point, or a controller's states in a closed loop).
The input is a law ``u = law(t, w, y)``, evaluated exactly at every
right-hand side: a sine, or ``-G`` of the output. When the output depends on
the input directly (feedthrough) and the law on the output, the algebraic
loop is solved by a fixed-point round and secant steps (bounded). The
integrator is scipy's DOP853 (or, for a
:class:`~dfwb.foreign.native_flow.Drive`, the same method in C:
:mod:`dfwb.foreign.native_flow`), stepped by hand: after each accepted step the event
indicators are compared with the step's start; a change of domain is
located on the dense output (brentq) and the FMU, put just past it, handles
the event; time events and ``completedIntegratorStep`` requests likewise.
A run can also stop where a section function of (t, w, y) crosses zero
upwards (a closed loop's Poincare section). Every loop is bounded.
"""

import math

import numpy as np
from scipy.integrate import DOP853
from scipy.optimize import brentq

from dfwb.fmi.simulation import FMUError
from dfwb.foreign.native_flow import ALGEBRAIC_TOLERANCE, MAX_ALGEBRAIC, Stepper, not_finite, unsolved

__all__ = ["Flow", "MAX_STEPS", "MAX_EVENTS"]

MAX_STEPS = 200_000  # integrator steps per run
MAX_EVENTS = 10_000  # events per run
RTOL_ROOT = 4 * np.finfo(float).eps  # brentq's finest
_SUM = np.add.reduce  # np.sum without its Python wrapper: a right-hand side is hot


class Flow:
    """Integrate an FMU instance (started, in continuous-time mode) with an input law and extra states.

    Parameters
    ----------
    instance : Instance
    law : callable
        ``law(t, w, y) -> u``, the input.
    rate : callable
        ``rate(t, w, y, u) -> dw/dt`` (an array of the extra states' length).
    extra : int
        The number of extra states w.
    reads_output : bool
        Whether the law reads y (then an output that depends on the input directly is an algebraic loop,
        solved at every evaluation); a law that does not is evaluated once.
    drive : Drive, optional
        Instead of the four above: a law and rates that C evaluates too (:mod:`dfwb.foreign.native_flow`),
        so that the steps run in C where the library and the FMU allow.
    """

    def __init__(self, instance, law=None, rate=None, extra=0, reads_output=True, drive=None):
        if drive is not None:  # a law C knows: stepped in C where it can be (dfwb.foreign.native_flow)
            law, rate, extra, reads_output = drive.law, drive.rate, drive.extra, drive.reads_output
        self.inst, self.law, self.rate, self.extra, self.drive = instance, law, rate, extra, drive
        self.reads_output = reads_output
        self.next_event = None
        self.scale = np.zeros(instance.nx + extra)  # the largest |z_i| seen
        self.y_max = 0.0  # the largest |y| seen
        self._y = 0.0  # the last output: the first guess of the next evaluation's
        self.steps = self.evaluations = 0  # accepted integrator steps, right-hand sides evaluated
        self.last_step = None  # the step size a run ended with: a following piece's first step
        self._at = None  # (t, z) of the last evaluation, the very array: the FMU is still there
        self.native = None  # the drive's model in C (dfwb.foreign.native_flow), made on the first step there

    def atol(self, rtol):
        """Absolute tolerances from the scales seen, so that rtol rules (1e-6 of the largest for a part at 0)."""
        scale = self.scale
        return np.maximum(rtol * np.maximum(scale, 1e-6 * max(float(np.max(scale, initial=0.0)), 1e-300)), 1e-300)

    # -- evaluation ------------------------------------------------------------------------------
    def evaluate(self, t, z):
        """Put the FMU at (t, z) with its input; returns (y, u)."""
        inst, nx = self.inst, self.inst.nx
        self._at = (t, z)
        w = z[nx:]
        u = self.law(t, w, self._y)
        inst.set_continuous(t, z[:nx], u)
        y = inst.output()
        if self.reads_output:
            u, y = self._algebraic(t, w, u, y)
        self._y = y
        return y, u

    def _algebraic(self, t, w, u, y):
        """(u, y(u)) with u = law(t, w, y(u)) to ALGEBRAIC_ULPS ulps: a fixed-point round, then secant steps on
        law - u (a loop of slope -1/2 took some 50 rounds to repeat exactly, where a secant step solves a linear
        stretch at once). Bounded by MAX_ALGEBRAIC rounds (both in :mod:`dfwb.foreign.native_flow`)."""
        inst, before = self.inst, None
        for _ in range(MAX_ALGEBRAIC):
            following = self.law(t, w, y)
            g = following - u
            if abs(g) <= ALGEBRAIC_TOLERANCE * max(abs(u), abs(following)):
                return u, y
            ahead = following if before is None or g == before[1] else u - g * (u - before[0]) / (g - before[1])
            before = (u, g)
            u = ahead
            inst.set_input(u)
            y = inst.output()
        raise unsolved(inst.info.path, t)

    def rhs(self, t, z):
        self.evaluations += 1
        y, u = self.evaluate(t, z)
        dx = self.inst.derivatives()
        if not math.isfinite(y + u + float(_SUM(dx))):  # one test for all (an overflowing sum is one too)
            raise not_finite(self.inst.info.path, t)
        return np.concatenate((dx, self.rate(t, z[self.inst.nx:], y, u)))

    def _indicators(self, t, z):
        """The event indicators at (t, z); not evaluated again where the last right-hand side was (the end of
        an accepted step is its last stage's point: the same array)."""
        at = self._at
        if at is None or at[1] is not z or at[0] != t:
            self.evaluate(t, z)
        return self.inst.indicators().copy()

    def _domains(self, t, z):
        return self._indicators(t, z) > 0.0

    def _aim(self, solver, t_prev, previous, values):
        """Shorten the solver's next step to end just past the first crossing of an event indicator, predicted
        on the last step's dense output extrapolated (no further than that step's length). A step across a
        kink of the right-hand side is rejected again and again (about 14 times at a saturation's edge at
        rtol 1e-9) until it is tiny; one that ends just past the kink is accepted."""
        t, h = solver.t, solver.h_abs
        span = t - t_prev
        if not (span > 0.0 and h > 0.0):
            return
        slope = (values - previous) / span
        with np.errstate(divide="ignore", invalid="ignore"):
            eta = -values / slope  # linear: when each indicator would reach 0
        near = (eta > 0.0) & (eta <= 2.0 * h)
        if not near.any():
            return
        window = min(h, 2.0 * span)
        dense = solver.dense_output()
        signs = values > 0.0

        end = t + window
        later = self._indicators(end, dense(end))
        moved = np.flatnonzero(near & ((later > 0.0) != signs))
        if not len(moved):
            solver.h_abs = window  # not within the window: step there and look again
            return
        roots = []
        for i in moved:
            sign = 1.0 if signs[i] else -1.0
            roots.append(brentq(lambda s: sign * self._indicators(s, dense(s))[i], t, end,
                                xtol=1e-12 * max(1.0, abs(t)), rtol=1e-10))
        reach = min(roots) - t
        solver.h_abs = min(h, reach * (1.0 + 1e-6) + 8 * np.spacing(abs(t) + reach))

    def _first_crossing(self, dense, t0, t1, before):
        """The first time in (t0, t1] where an indicator leaves its domain, and a point just past it there."""
        def indicator(i):
            def f(t):
                self.evaluate(t, dense(t))
                value = self.inst.indicators()[i]
                return value if before[i] else -value  # > 0 in the old domain
            return f

        after = self._domains(t1, dense(t1))
        roots = []
        for i in np.flatnonzero(after != before):
            f = indicator(i)
            roots.append(t0 if f(t0) <= 0 else brentq(f, t0, t1, xtol=1e-15 * max(1.0, abs(t1)), rtol=RTOL_ROOT))
        root = min(roots)
        t = root
        for _ in range(64):  # just past the root: a domain has changed there
            if t >= t1 or np.any(self._domains(t, dense(t)) != before):
                break
            t = t + max(t - root, abs(t) * 2.2e-16, 1e-300)
        return root, min(t, t1)

    # -- a run -------------------------------------------------------------------------------------
    def run(self, t0, z, end, rtol, atol, section=None, first_step=None):
        """(t, z, events, crossed): from z at t0 to ``end``, or to the first upward zero of
        ``section(t, w, y)`` after t0 when one is given (``crossed`` True); a run that starts on the
        section, or below it, counts the first upward crossing after the section function has been
        negative during the run. The first step is ``first_step``, or a 64th of the run (a run's steps
        depend on its arguments only, so that runs from nearby states can be differenced)."""
        inst = self.inst
        nx = inst.nx
        t, z = t0, np.array(z, dtype=float)
        self._at = None  # the FMU may have been moved since
        events = 0
        level = max(self._section(section, t, z), 0.0)  # started on the section: the next crossing, not this one
        step = first_step or (end - t0) / 64  # then the last step's size, carried across events
        while t < end:
            bound = end if self.next_event is None or self.next_event >= end else max(self.next_event, t)
            solver = self._solver(t, z, bound, rtol, atol, min(bound - t, step) or None)
            values = self._indicators(t, z)
            before = values > 0.0
            handled, natural = False, 0.0  # natural: the step the solver proposed before it was aimed
            for _ in range(MAX_STEPS):
                if solver.status != "running":
                    break
                t_prev, z_prev = solver.t, solver.y.copy()
                message = solver.step()
                if solver.status == "failed":
                    raise FMUError(f"{inst.info.path}: the integrator failed at t = {float(solver.t)!r}: {message}")
                step = max(solver.h_abs, natural)  # an aimed step's successor may only grow tenfold
                self.steps += 1
                now_values = self._indicators(solver.t, solver.y)
                now = now_values > 0.0
                changed = bool(np.any(now != before))
                dense = solver.dense_output() if changed else None  # (3 more right-hand sides: when needed)
                root, past = self._first_crossing(dense, t_prev, solver.t, before) if changed else (None, None)
                if section is not None:
                    after = self._section(section, solver.t, solver.y)
                    if level < 0.0 <= after:  # the section, upwards: stop there if before any event
                        dense = solver.dense_output() if dense is None else dense
                        crossing = brentq(lambda s: self._section(section, s, dense(s)), t_prev, solver.t,
                                          xtol=1e-15 * max(1.0, abs(solver.t)), rtol=RTOL_ROOT)
                        if root is None or crossing <= root:
                            z = dense(crossing)
                            self.evaluate(crossing, z)
                            return crossing, z, events, True
                    level = after
                if changed:  # integrated again up to the event: the step's stages past it saw the other domain
                    (t, z), handled = self._past(t_prev, z_prev, root, past, solver.t, before, rtol, atol), True
                    break
                if inst.completed_step():  # the FMU is at the step's end (its indicators were read there)
                    t, z, handled = solver.t, solver.y.copy(), True
                    break
                self.scale = np.maximum(self.scale, np.abs(solver.y))
                self.y_max = max(self.y_max, abs(self._y))
                natural = solver.h_abs
                self._aim(solver, t_prev, values, now_values)
                natural = natural if solver.h_abs < natural else 0.0
                before, values = now, now_values
            else:
                raise FMUError(f"{inst.info.path}: more than {MAX_STEPS} integrator steps in one run")
            if not handled:
                t, z = solver.t, solver.y.copy()
                if self.next_event is None or t < self.next_event:
                    continue  # the run's end
            self.evaluate(t, z)
            self.next_event = inst.event()
            z = np.concatenate((inst.states(), z[nx:]))
            level = self._section(section, t, z)
            events += 1
            if events > MAX_EVENTS:
                raise FMUError(f"{inst.info.path}: more than {MAX_EVENTS} events in one run (chattering?)")
        self.last_step = step
        return t, z, events, False

    def _past(self, t0, z0, root, past, t1, before, rtol, atol):
        """(t, z) just past the event at ``root``, integrated cleanly from (t0, z0): where the domains have
        changed for the clean state too (the dense output's point may be a rounding short of it; the FMU
        would then handle an event before it, and meet it again two ulps on)."""
        z = self._clean(t0, z0, past, rtol, atol)
        for _ in range(8):
            if past >= t1 or np.any(self._domains(past, z) != before):
                break
            past = min(past + max(past - root, abs(past) * 2.2e-16, 1e-300), t1)
            z = self._clean(t0, z0, past, rtol, atol)
        return past, z

    def _clean(self, t0, z0, t1, rtol, atol):
        """The state at t1 integrated from z0 at t0 inside one domain: a step across an event mixes both
        sides in its stages, so its dense output is no better than the jump times the step (a kink's error
        varied a thousandfold with where it fell in the step); this run ends at the event."""
        if not t1 > t0:
            return z0
        solver = self._solver(t0, z0, t1, rtol, atol, t1 - t0)
        for _ in range(MAX_STEPS):
            if solver.status != "running":
                break
            message = solver.step()
            if solver.status == "failed":
                raise FMUError(f"{self.inst.info.path}: the integrator failed at t = {float(solver.t)!r}: {message}")
            self.steps += 1
        return solver.y.copy()

    def _solver(self, t0, z, bound, rtol, atol, first_step):
        """DOP853 from z at t0 towards ``bound``: stepped in C where the drive allows, else scipy's."""
        stepper = Stepper.for_flow(self, t0, z, bound, rtol, atol, first_step)
        if stepper is not None:
            return stepper
        return DOP853(self.rhs, t0, z, bound, rtol=rtol, atol=atol, first_step=first_step)

    def _section(self, section, t, z):
        if section is None:
            return 0.0
        y, _u = self.evaluate(t, z)
        return section(t, z[self.inst.nx:], y)
