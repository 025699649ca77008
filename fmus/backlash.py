"""Two masses with a clearance and impacts, integrated exactly.

M2 carries the force u = f + F cos(omega t + phi); M1 is free. The gap
g = x2 - x1 stays in [0, h]. Between impacts M1 x1'' = 0, M2 x2'' = u, so the
gap is a closed-form :class:`~exact.Motion` and impacts are its first zeros
at 0 and h. An impact follows Newton's law with restitution eps (momentum
conserved). When u presses the masses together and the next bounce would
rise less than ``tol_h`` (a 1e-12 fraction of h), the accumulation of impacts
is complete for all purposes: the masses move together, (M1 + M2) x'' = u,
until u turns to pull them apart (an analytic crossing of zero).

The state is (x1, v1, g, w = g'), so the gap never suffers the cancellation
of x2 - x1 when the masses have drifted far.
"""

from .exact import Motion
from .piecewise import PiecewisePlant, Search, check

FREE, LOWER, UPPER = 0, 1, 2  # the ``contact`` output: free, at gap 0, at gap h
SIDE = {LOWER: -1, UPPER: 1}  # sigma: pressing into the boundary means sigma * u > 0


class TwoMassBacklash(PiecewisePlant):
    """Exact solver of the two-mass backlash; the output is x1."""

    def __init__(self, M1=1.0, M2=1.0, h=0.1, eps=0.5, F=0.0, omega=1.0, phi=0.0,
                 x1_0=0.0, v1_0=0.0, v2_0=0.0, gap0=None, f=0.0, harmonics=10):
        check("M1", M1, M1 > 0.0, "M1 must be > 0 (kg)")
        check("M2", M2, M2 > 0.0, "M2 must be > 0 (kg)")
        check("h", h, h > 0.0, "h must be > 0 (m)")
        check("eps", eps, 0.0 <= eps <= 1.0, "eps must be in [0, 1]")
        if gap0 is None:
            gap0 = 0.5 * h
        check("gap0", gap0, 0.0 <= gap0 <= h, f"gap0 must be in [0, h] = [0, {h!r}] (m)")
        for name, value in (("x1_0", x1_0), ("v1_0", v1_0), ("v2_0", v2_0)):
            check(name, value, True, f"{name} must be a finite number")
        super().__init__(F, omega, phi, f, harmonics)
        self.M1, self.M2, self.h, self.eps = M1, M2, h, eps
        self.tol_h = 1e-12 * h
        self.impacts = 0
        self.contact = FREE
        self._departing = 0
        self._start(0.0, x1_0, v1_0, gap0, v2_0 - v1_0)

    # -- state -------------------------------------------------------------
    def state(self, t=None):
        """(x1, v1, g, w) at t (default: the current time)."""
        t = self.t if t is None else t
        x1, v1 = self._output.state(t)
        if self.contact == FREE:
            g, w = self._gap.state(t)
        else:
            g, w = (0.0 if self.contact == LOWER else self.h), 0.0
        return x1, v1, g, w

    def output(self):
        """x1, v1, x2, v2, gap at self.t."""
        x1, v1, g, w = self.state()
        return x1, v1, x1 + g, v1 + w, g

    # -- pieces -------------------------------------------------------------
    def _start(self, t, x1, v1, g, w):
        if g <= 0.0:
            self._at_boundary(t, x1, v1, LOWER, w)
        elif g >= self.h:
            self._at_boundary(t, x1, v1, UPPER, w)
        else:
            self._free(t, x1, v1, g, w, departing=0)

    def _at_boundary(self, t, x1, v1, side, w):
        """Impact (if closing), then contact or a flight away from the boundary."""
        sigma = SIDE[side]
        if sigma * w > 0.0:
            v1 += self.M2 * (1.0 + self.eps) * w / (self.M1 + self.M2)
            w = -self.eps * w
            self.impacts += 1
        u = self.drive.u(t)
        pressing = self.drive.above(t, 0.0) if sigma > 0 else self.drive.below(t, 0.0)
        if pressing and (w == 0.0 or 0.5 * w * w * self.M2 <= self.tol_h * abs(u)):
            v_common = v1 + self.M2 * w / (self.M1 + self.M2)  # momentum kept
            self._contact(t, x1, v_common, side)
        else:
            self._free(t, x1, v1, 0.0 if side == LOWER else self.h, w, departing=sigma)

    def _free(self, t, x1, v1, g, w, departing):
        """Flight; ``departing`` = sigma of the boundary just left (0: none)."""
        d = self.drive
        self.contact = FREE
        self._departing = departing
        self._gap = gap = Motion(t, g, w, 0.0, d.f / self.M2, d.F / self.M2, d.omega, d.phi)
        output = Motion(t, x1, v1, 0.0, 0.0, 0.0, d.omega, d.phi)
        self._begin(t, output, searches=self._boundary_searches(t, skip=departing))
        if departing:
            # The gap cannot return to the boundary it left before the
            # separation speed -sigma*w falls to zero: search that apex first.
            def separation(tt):
                _, ww = gap.state(tt)
                return -departing * ww, -departing * gap.acceleration(tt, ww)

            sep = -departing * w
            t_from = t if sep > 0.0 else d.crossing(t, 0.0, rising=departing > 0)
            self._searches.append(Search(separation, gap.curvature_bound(), t_from, "apex"))

    def _boundary_searches(self, t, skip=0):
        gap, h = self._gap, self.h
        K = abs(gap.a) + abs(gap.b)

        def above_lower(tt):
            g, w = gap.state(tt)
            return g, w

        def below_upper(tt):
            g, w = gap.state(tt)
            return h - g, -w

        searches = []
        if skip != SIDE[LOWER]:
            searches.append(Search(above_lower, K, t, LOWER))
        if skip != SIDE[UPPER]:
            searches.append(Search(below_upper, K, t, UPPER))
        return searches

    def _contact(self, t, x1, v, side):
        """The masses move together until u stops pressing them into the boundary."""
        d = self.drive
        self.contact = side
        self._departing = 0
        total = self.M1 + self.M2
        output = Motion(t, x1, v, 0.0, d.f / total, d.F / total, d.omega, d.phi)
        t_release = d.crossing(t, 0.0, rising=SIDE[side] < 0)
        self._begin(t, output, t_release, "release")

    # -- events ---------------------------------------------------------------
    def _fire(self, t, kind):
        if kind == "apex":
            self._departing = 0
            self._set_searches(t, self._boundary_searches(t))
            return False
        x1, v1, g, w = self.state(t)
        self._close_piece(t)
        if kind == "release":
            side = self.contact
            self._free(t, x1, v1, 0.0 if side == LOWER else self.h, 0.0, departing=SIDE[side])
        else:
            self._at_boundary(t, x1, v1, kind, w)
        return True

    def _restart(self, t):
        x1, v1, g, w = self.state(t)
        if self.contact != FREE:
            self._at_boundary(t, x1, v1, self.contact, 0.0)
        elif self._departing:
            self._free(t, x1, v1, g, w, departing=self._departing)
        else:
            self._start(t, x1, v1, g, w)
