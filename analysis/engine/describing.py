"""Describing functions N(F, w) of the plant FMUs, by the convention of docs/models.md.

The plant starts at rest and is driven by ``F cos(w t)``. Instead of a long
fixed transient, the engine reads the plant's state at whole periods (the
Poincare section) and stops as soon as it repeats, with a period of 1 to 4
forcing periods; N is then exact from one orbit, ``N = X1 / F`` with
``X1 = (2 / T) int x exp(-j w t) dt`` taken from the FMU's exactly integrated
Fourier outputs (two reads per period, no sampling). When the section
converges geometrically but slowly (a lightly damped linear mode), an
Aitken-Steffensen step extrapolates the fixed point (a degree-2 minimal
polynomial extrapolation where it converges at two rates) and one shooting
period from it confirms the orbit; a shot that lands farther from its return
than the run's last period moved is dropped and the run goes on. A response
that does not repeat within ``max_periods`` (quasi-periodic or chaotic) gets
the average over its last 20 periods, flagged ``periodic = False``.

The engine accepts F in F_RANGE and omega in OMEGA_RANGE (and the plant
parameters in :data:`dfwb.plants.registry.RANGES`), checked before anything runs. The
plants are invariant under a translation, so the DF does not depend on the
initial position: the engine runs the plant at the origin and adds the
translation to the mean X_0 only (:meth:`DFEngine.point`).

Examples
--------
>>> from dfwb.engine.describing import DFEngine
>>> engine = DFEngine("friction")
>>> result = engine.point(F=10.0, omega=1.0)
>>> result.periodic, result.periods, round(result.N.real, 9), round(result.N.imag, 9)
(True, 2, -0.235053392, -0.297987542)
"""

import cmath
import dataclasses
import json
import math
import time
from dataclasses import dataclass, field

from dfwb.base.defaults import DF_PERIODS, HARMONICS, SAMPLES_PER_PERIOD
from dfwb.base.values import real, short
from dfwb.fmi.location import fmu_path
from dfwb.fmus.piecewise import PlantError
from dfwb.plants import check_range
from dfwb.plants import plant as find_plant

# The points the engine computes (N, rad/s): the edges dfwb stress covers and beyond,
# checked at the corners with every plant's default parameters.
F_RANGE = (1e-6, 1e9)
OMEGA_RANGE = (1e-4, 1e5)
MAX_PERIODS = 100_000  # the most max_periods may be: a point's run is bounded
AVERAGE_PERIODS = 20
MAX_LAG = 4
SECTION_RTOL = 1e-11
# An integrated plant's sections carry its tolerance rtol: they are closed to a tenth of it (asking rounding
# of them only adds periods: 21 instead of 11 for stribeck at F 20 N, omega 20 rad/s, N moving by 2e-13)
INTEGRATED_SECTION = 0.1
DRIVES = ("internal", "input")


@dataclass
class DFResult:
    """One describing-function point."""

    plant: str
    F: float
    omega: float
    params: dict
    N: complex
    harmonics: list  # |X_k|, k = 0..10 (0..1 for an engine with harmonics=1)
    periodic: bool
    periods: int  # forcing periods simulated, shooting included
    seconds: float
    drive: str = "internal"
    note: str = ""
    orbit_periods: int = 1  # the orbit's period in forcing periods (1: harmonic response)
    X: list = field(default_factory=list, repr=False)  # complex X_k, k = 0..10
    N_error: object = None  # estimated |error| of N [m/N]; None: exact (this engine, to its 1e-11 section); an
    # integrated plant's (PlantTable.integrated): a bound from its FMU's I_error
    output: object = None  # the plant output's first harmonic where N is another signal's (what the controller
    # of a compensated loop sees: dfwb.engine.inverse_df); None: N F

    @property
    def amplitude_x(self):
        """The plant output's first-harmonic amplitude [m]: |N| F, or the output's where N is another signal's."""
        return abs(self.N) * self.F if self.output is None else abs(self.output)

    @property
    def minus_inverse(self):
        """-1/N, or None where N = 0 (no engagement)."""
        return None if self.N == 0 else -1.0 / self.N

    def as_dict(self):
        """The point's record: the one shape of a DF point in CSV, JSON and the API.

        A flat dict of plain values (see :data:`RECORD`); complex numbers are
        split into ``_re`` / ``_im`` parts, -1/N is None where N = 0, and
        ``harmonics`` lists |X_k| for k = 0, 1, ... CSV flattens it further
        (:func:`to_row`), JSON holds it as it is.
        """
        inverse = self.minus_inverse
        return {
            "plant": self.plant, "F": self.F, "omega": self.omega, "params": dict(self.params),
            "drive": self.drive, "N_re": self.N.real, "N_im": self.N.imag, "N_error": self.N_error,
            "minus_inv_N_re": None if inverse is None else inverse.real,
            "minus_inv_N_im": None if inverse is None else inverse.imag,
            "periodic": self.periodic, "periods": self.periods, "orbit_periods": self.orbit_periods,
            "harmonics": list(self.harmonics), "seconds": self.seconds, "note": self.note,
        }

    @classmethod
    def from_dict(cls, data):
        """The result back from its record :meth:`as_dict` (complex X_k are not kept there)."""
        return cls(plant=data["plant"], F=data["F"], omega=data["omega"], params=dict(data["params"]),
                   N=complex(data["N_re"], data["N_im"]), harmonics=list(data["harmonics"]),
                   periodic=data["periodic"], periods=data["periods"], seconds=data["seconds"],
                   drive=data["drive"], note=data["note"], orbit_periods=data["orbit_periods"],
                   N_error=data.get("N_error"))


# -- the record of a DF point, and its CSV row -------------------------------------------------
#: The record's keys (:meth:`DFResult.as_dict`) in order, with their units ("" where none).
#: ``harmonics`` is a list: CSV spreads it over the columns ``X0 [m]`` .. ``X10 [m]``.
RECORD = {
    "plant": "", "F": "N", "omega": "rad/s", "params": "", "drive": "",
    "N_re": "m/N", "N_im": "m/N", "N_error": "m/N", "minus_inv_N_re": "N/m", "minus_inv_N_im": "N/m",
    "periodic": "", "periods": "", "orbit_periods": "", "harmonics": "m", "seconds": "s", "note": "",
}
_INTEGERS = {"periods", "orbit_periods"}
_TEXTS = {"plant", "drive", "note"}


def column(key, k=None):
    """The CSV column of a record key (``k``: the harmonic of ``harmonics``), its unit in brackets.

    >>> column("F"), column("N_re"), column("harmonics", 3), column("periodic")
    ('F [N]', 'N_re [m/N]', 'X3 [m]', 'periodic')
    """
    name = f"X{k}" if key == "harmonics" else key
    return f"{name} [{RECORD[key]}]" if RECORD[key] else name


#: The CSV columns of a record, in order: its flattened keys with their units.
COLUMNS = [column(key, k) for key in RECORD for k in (range(HARMONICS + 1) if key == "harmonics" else [None])]


def to_row(record):
    """A record's CSV row ``{column: text}``, floats as round-trip text, None as "".

    Examples
    --------
    >>> row = to_row({"plant": "friction", "F": 10.0, "omega": 1.0, "params": {"M": 2.0}, "drive": "internal",
    ...               "N_re": -0.25, "N_im": -0.3, "minus_inv_N_re": None, "minus_inv_N_im": None,
    ...               "periodic": True, "periods": 2, "orbit_periods": 1, "harmonics": [0.0, 0.1],
    ...               "seconds": 0.001, "note": ""})
    >>> row["F [N]"], row["params"], row["minus_inv_N_re [N/m]"], row["X1 [m]"], row["X2 [m]"]
    ('10.0', '{"M": 2.0}', '', '0.1', '')
    >>> from_row(row)["harmonics"], from_row(row)["params"]
    ([0.0, 0.1], {'M': 2.0})
    """
    row = {}
    for key in RECORD:
        value = record.get(key)
        if key == "harmonics":
            for k, x in enumerate(value):
                row[column(key, k)] = str(x)
        elif key == "params":
            row[key] = json.dumps(value, sort_keys=True)
        else:
            row[column(key)] = "" if value is None else str(value)
    return {name: row.get(name, "") for name in COLUMNS}


def from_row(row):
    """The record back from its CSV row (:func:`to_row`); ValueError, KeyError or TypeError if it is not one."""
    record = {}
    for key in RECORD:
        if key == "harmonics":
            cells = [row[column(key, k)] for k in range(HARMONICS + 1)]
            record[key] = [float(cell) for cell in cells if cell != ""]
            continue
        text = row[column(key)]
        if key == "params":
            record[key] = json.loads(text)
        elif key in _TEXTS:
            record[key] = text
        elif key == "periodic":
            record[key] = text == "True"
        elif key in _INTEGERS:
            record[key] = int(text)
        else:
            record[key] = None if text == "" else float(text)
    return record


def check_force(F):
    """Raise PlantError naming the value unless F is in F_RANGE."""
    check_range("F", F, *F_RANGE, "N")


def check_frequency(omega):
    """Raise PlantError naming the value unless omega is in OMEGA_RANGE."""
    check_range("omega", omega, *OMEGA_RANGE, "rad/s")


def check_point(F, omega):
    """(F, omega) as floats: PlantError naming the value unless each is a real number (a numpy scalar too; no
    text) and F is in F_RANGE and omega in OMEGA_RANGE."""
    numbers = []
    for name, value, check in (("F", F, check_force), ("omega", omega, check_frequency)):
        number = None if isinstance(value, str) else real(value)
        if number is None:
            raise PlantError(f"{name} = {short(value)} is not a real number")
        check(number)
        numbers.append(number)
    return tuple(numbers)


class DFEngine:
    """DF points of one plant, computed through its FMU with fmpy.

    Parameters
    ----------
    plant : {"friction", "backlash", "static-backlash"}
    fmu_dir : path, optional
        Where the FMUs are (built there if missing or stale).
    drive : {"internal", "input"}
        ``internal``: the FMU's built-in excitation, exact. ``input``: the
        sine is sampled at the start of each communication step and fed into
        the input ``f``, held over the step, as any FMI master would.
    samples_per_period : int
        Communication steps per period with ``drive="input"``.
    max_periods : int
        Periods simulated before a response is declared not periodic.
    model : str, optional
        Another FMI facade of the same plant interface, by class name (the
        benchmark's fixed-step baselines).
    harmonics : int
        Harmonics X_0..X_harmonics recorded (1 to 10). The FMU integrates only
        those, so a DF-only study (1) does less work per event.
    fmu : path, optional
        The FMU file itself, used as given (e.g. one shipped to a Dask worker);
        by default the plant's FMU in ``fmu_dir``.
    """

    def __init__(self, plant, fmu_dir=None, drive="internal", samples_per_period=SAMPLES_PER_PERIOD,
                 max_periods=DF_PERIODS, model=None, harmonics=HARMONICS, fmu=None):
        self.plant = find_plant(plant)
        if model is not None:  # the plant's other FMU of the same interface (its fixed-step twin)
            variants = [m for m in (self.plant.model, self.plant.naive) if m is not None]
            chosen = [m for m in variants if m.__name__ == model]
            if not chosen:
                raise PlantError(f"model {model!r} is not an FMU of plant {plant} "
                                 f"(allowed: {', '.join(m.__name__ for m in variants)})")
            self.plant = dataclasses.replace(self.plant, model=chosen[0])
        if drive not in DRIVES:
            raise PlantError(f"drive {drive!r} is not allowed (allowed: {', '.join(DRIVES)})")
        if not (isinstance(samples_per_period, int) and samples_per_period >= 4):
            raise PlantError(f"samples_per_period = {samples_per_period!r} is out of range: an integer >= 4")
        if not (isinstance(harmonics, int) and 1 <= harmonics <= HARMONICS):
            raise PlantError(f"harmonics = {harmonics!r} is out of range: an integer from 1 to {HARMONICS}")
        if not (isinstance(max_periods, int) and 1 <= max_periods <= MAX_PERIODS):
            raise PlantError(f"max_periods = {max_periods!r} is out of range: an integer from 1 to {MAX_PERIODS}")
        self.drive = drive
        self.harmonics = harmonics
        self.samples = samples_per_period if drive == "input" else 1
        self.max_periods = max_periods
        from dfwb.fmi.session import FMUSession  # fmpy and numpy: only for an engine that runs (not for its records)

        path = fmu if fmu is not None else fmu_path(self.plant, fmu_dir)
        self._sessions = [FMUSession(path), FMUSession(path)]  # the run from rest, and shooting
        fourier = [f"I{part}{k}" for k in range(harmonics + 1) for part in "cs"]
        # an integrated plant's FMU bounds its integrals' error (read last); an exact one has no such output
        self._error = getattr(getattr(self.plant.model, "table", None), "integrated", False)
        self._real_names = list(self.plant.section) + fourier + (["I_error"] if self._error else [])
        self._integer_names = list(self.plant.modes) + [self.plant.counter]
        self._readers = {session: session.reader(self._real_names, self._integer_names) for session in self._sessions}
        self._setups = {}

    # -- one point ----------------------------------------------------------------
    def point(self, F, omega, params=None):
        """The DFResult of the plant at force amplitude F and frequency omega.

        The plant runs translated to the origin (its position parameter at 0):
        N and every X_k, k >= 1, are bit-identical whatever the position, and
        the translation is added to the mean X_0 (harmonics[0]) only.
        """
        started = time.perf_counter()
        F, omega = check_point(F, omega)
        params = self.plant.checked(params or {})
        at_origin, offset, mass, h, shifts = self._setup(params)
        scales = [F / (mass * omega) if name.startswith("v") else F / (mass * omega ** 2) + h
                  for name in self.plant.section]
        base = dict(at_origin, F=F if self.drive == "internal" else 0.0, omega=omega, phi=0.0,
                    harmonics=self.harmonics)
        tolerance = SECTION_RTOL
        if self._error:
            tolerance = max(SECTION_RTOL, INTEGRATED_SECTION * dict(self.plant.defaults(), **params)["rtol"])
        result = _Search(self, F, omega, base, scales, shifts, offset, tolerance).run()
        result.plant, result.params, result.drive = self.plant.name, params, self.drive
        result.seconds = time.perf_counter() - started
        return result

    def _setup(self, params):
        """(parameters at the origin, the translation, the mass, h, the section's shifts) of checked params:
        the same for every point of a sweep, so kept for the last few parameter sets."""
        key = tuple(sorted(params.items()))
        found = self._setups.get(key)
        if found is None:
            at_origin, offset = self.plant.at_origin(params)
            found = (at_origin, offset, self.plant.mass(params), dict(self.plant.defaults(), **params).get("h", 0.0),
                     self.plant.translation(params))
            if len(self._setups) >= 16:
                self._setups.clear()
            self._setups[key] = found
        return found

    # -- periods of one run ------------------------------------------------------------
    def _run(self, session, F, omega, values):
        """Yield ((section, modes), window, engagement count): at t = 0 (window None), then each period.

        A window is (integrals at its start, integrals at its end, its length): :meth:`spectrum` makes
        its X_k, only for the periods a result uses.
        """
        session.start(values)
        read = self._readers[session]
        period = 2 * math.pi / omega
        step = period / self.samples
        section, previous, count = self._read(read)
        yield section, None, count
        while True:
            t0 = session.time
            for i in range(self.samples):
                inputs = {"f": F * math.cos(omega * (t0 + i * step))} if self.drive == "input" else None
                session.step(step, inputs)
            section, current, count = self._read(read)
            yield section, (previous, current, session.time - t0), count
            previous = current

    def spectrum(self, window):
        """X_k, k = 0..harmonics, of one window: X_0 = dI_0 / T, X_k = 2 dI_k / T with I_k = Ic_k - j Is_k."""
        previous, current, width = window
        n = len(self.plant.section)
        dI = [complex(current[n + 2 * k], -current[n + 2 * k + 1]) - complex(previous[n + 2 * k],
                                                                             -previous[n + 2 * k + 1])
              for k in range(self.harmonics + 1)]
        return [dI[0] / width] + [2.0 * dI[k] / width for k in range(1, self.harmonics + 1)]

    def spectrum_error(self, window):
        """A bound on the error of each X_k, k >= 1, of one window (None for an exact plant): twice the bound
        on the integrals' error accumulated over the window, over its length (the FMU's I_error is the
        integral of a bound on the output's error, so the window's part is its increase)."""
        if not self._error:
            return None
        previous, current, width = window
        return 2.0 * abs(current[-1] - previous[-1]) / width

    def _read(self, read):
        """((section, modes), the reals read (section, then Ic_k, Is_k), engagement count): two FMI calls."""
        n = len(self.plant.section)
        reals, integers = read()
        return (tuple(reals[:n]), tuple(integers[:-1])), reals, integers[-1]


def _dot(a, b):
    return sum(x * y for x, y in zip(a, b))


class _Search:
    """The search for the periodic steady state of one point."""

    def __init__(self, engine, F, omega, base, scales, shifts, offset=0.0, tolerance=SECTION_RTOL):
        self.engine, self.F, self.omega, self.base, self.scales = engine, F, omega, base, scales
        self.tolerance = tolerance  # relative: two sections within it are the same
        self.shifts = shifts
        self.offset = offset  # the output's translation, removed from the run and added back to X_0
        self.periods = 0

    def drift(self, a, b):
        """The translation taking section b to section a, or None if they differ otherwise.

        A repeat up to a translation is a periodic orbit of the plant (its
        forces ignore absolute position); a steady drift arises when a sampled
        input gives a free mass a mean velocity.
        """
        (sa, ma), (sb, mb) = a, b
        if ma != mb:
            return None
        d = sa[0] - sb[0]  # the first component is a position that moves by 1 m per metre
        for x, y, s, shift in zip(sa, sb, self.scales, self.shifts):
            if abs(x - shift * d - y) > self.tolerance * (abs(x) + s):
                return None
        return d if abs(d) > self.tolerance * (abs(sa[0]) + self.scales[0]) else 0.0

    def step(self, a, b):
        """How far section b is from section a, relative to the scales (inf in other modes)."""
        (sa, ma), (sb, mb) = a, b
        if ma != mb:
            return math.inf
        return max(abs(x - y) / s for x, y, s in zip(sa, sb, self.scales))

    def close(self, a, b):
        return self.drift(a, b) == 0.0

    def orbit(self, sections, lag):
        """The drift per orbit if the last section closes an orbit of ``lag`` periods, else None.

        A multi-period orbit must differ from one period to the next (a period-1
        orbit approached with alternating steps would repeat every 2 periods
        first); a drift must be steady (the same over the previous orbit), or be
        below 1e-9 of the scale (a position still converging, not drifting).
        """
        if len(sections) <= lag:
            return None
        d = self.drift(sections[-1], sections[-1 - lag])
        if d is None:
            return None
        if lag > 1:
            (now, _), (before, _) = sections[-1], sections[-2]
            if all(abs(x - y) <= 1e-6 * (abs(x) + s) for x, y, s in zip(now, before, self.scales)):
                return None
        if d == 0.0 or abs(d) <= 1e-9 * (abs(sections[-1][0][0]) + self.scales[0]):
            return 0.0
        previous = self.drift(sections[-2], sections[-2 - lag]) if len(sections) > lag + 1 else None
        return d if previous is not None and abs(previous - d) <= 1e-6 * abs(d) else None

    def result(self, X, periodic, orbit, note="", X_error=None):
        X = [X[0] + self.offset] + X[1:]
        N = X[1] / self.F
        return DFResult(plant="", F=self.F, omega=self.omega, params={}, N=N, harmonics=[abs(x) for x in X],
                        periodic=periodic, periods=self.periods, seconds=0.0, note=note, orbit_periods=orbit, X=X,
                        N_error=None if X_error is None else X_error / self.F)

    def run(self):
        engine = self.engine
        runs = engine._run(engine._sessions[0], self.F, self.omega, self.base)
        origin, _, count = next(runs)
        sections, windows, counts = [origin], [], [count]
        shots = 0
        while True:
            section, window, count = next(runs)
            self.periods += 1
            sections.append(section)
            windows.append(window)
            counts.append(count)
            for lag in range(1, MAX_LAG + 1):
                d = self.orbit(sections, lag)
                if d is not None:
                    return self.finish(windows[-lag:], True, lag, count - counts[-1 - lag], drift=d / lag)
            if self.periods >= engine.max_periods:
                n = min(AVERAGE_PERIODS, len(windows))
                return self.finish(windows[-n:], False, 1, count - counts[-1 - n],
                                   f"not periodic after {self.periods} periods: average of the last {n}")
            start = self.extrapolate(sections, counts)
            if start is not None and shots < 5:
                shots += 1
                shot_runs = engine._run(engine._sessions[1], self.F, self.omega, dict(self.base, **start))
                origin = next(shot_runs)[0]
                returned, shot_window, shot_count = next(shot_runs)
                self.periods += 1
                if self.close(returned, origin):
                    return self.finish([shot_window], True, 1, shot_count, "periodic orbit confirmed by shooting")
                if self.step(origin, returned) < self.step(sections[-2], sections[-1]):
                    # not yet: the shooting run, closer to the orbit, becomes the trajectory
                    runs = shot_runs
                    engine._sessions.reverse()
                    sections, windows, counts = [origin, returned], [shot_window], [0, shot_count]
                # else the extrapolation missed (a tail that only looked linear, chaos): the run goes on

    def finish(self, windows, periodic, orbit, engagements, note="", drift=0.0):
        """The result from the orbit's periods (windows); ``engagements``: impacts or events within the orbit."""
        spectra = [self.engine.spectrum(window) for window in windows]
        X = [sum(column) / len(spectra) for column in zip(*spectra)]
        errors = [self.engine.spectrum_error(window) for window in windows]
        X_error = None if errors[0] is None else max(errors)  # an average's error is at most the largest
        if drift:
            # remove the ramp drift * t / T of each window: (2/T) int_0^T (c s) exp(-j k w s) ds = 2 j c / (k w)
            c = drift * self.omega / (2 * math.pi)
            X = [X[0] - drift / 2] + [X[k] - 2j * c / (k * self.omega) for k in range(1, len(X))]
            note = f"periodic up to a steady drift of {drift:.3g} m per period (removed from the harmonics)"
        never = self.engine.plant.never_engaged
        # No engagement in the orbit, or only grazes (x touching the edge at its extremum)
        # that move the output by rounding: the output is constant, its harmonics are 0.
        if never and (engagements == 0 or abs(X[1]) <= 1e-12 * self.scales[0]):
            X, note = [X[0]] + [0j] * (len(X) - 1), never
        return self.result(X, periodic, orbit, note, X_error)

    def extrapolate(self, sections, counts):
        """Start parameters at the fixed point a tail of sections converges to, or None.

        Aitken-Steffensen where the tail is geometric (one slow direction), else a degree-2 minimal polynomial
        extrapolation where it converges at two rates (a gear's rattle and its load's creep, which Aitken
        cannot take: 68 periods for drivetrain at F 50 N, omega 20 rad/s, then 19).
        """
        initial = self.engine.plant.initial
        if not initial or len(sections) < 4:
            return None
        target = self._aitken(sections)
        if target is None and len(sections) >= 5 and len(self.scales) > 2:  # 2 of 2 dimensions: any tail fits
            target = self._two_rates(sections, counts)
        if target is None:
            return None
        values = dict(zip(self.engine.plant.section, target))
        params = {initial[name]: values[name] for name in self.engine.plant.section if name in initial}
        if "gap0" in params:
            h = dict(self.engine.plant.defaults(), **self.base).get("h")
            params["gap0"] = min(max(params["gap0"], 0.0), h)
        return params

    def _aitken(self, sections):
        """Aitken-Steffensen's fixed point of a geometric tail of the last three sections, or None."""
        (s0, m0), (s1, m1), (s2, m2) = sections[-3:]
        if not m0 == m1 == m2:
            return None
        d1 = [(b - a) / s for a, b, s in zip(s0, s1, self.scales)]
        d2 = [(b - a) / s for a, b, s in zip(s1, s2, self.scales)]
        norm1 = sum(x * x for x in d1)
        norm2 = sum(x * x for x in d2)
        if norm1 == 0.0 or norm2 == 0.0:
            return None
        r = sum(x * y for x, y in zip(d1, d2)) / norm1
        residual = sum((y - r * x) ** 2 for x, y in zip(d1, d2))
        if not (-0.999 < r < 0.999) or residual > 1e-6 * norm2:
            return None  # not (yet) a clean geometric tail
        if math.log(self.tolerance / math.sqrt(norm2)) / math.log(abs(r)) < 3:
            return None  # plain iteration converges within a few periods anyway
        return tuple(b + (b - a) * r / (1.0 - r) for a, b in zip(s1, s2))

    def _two_rates(self, sections, counts):
        """The fixed point of a tail converging in two directions at two rates (the last four sections), or
        None: minimal polynomial extrapolation of degree 2.

        With u_0, u_1, u_2 the scaled differences, the c_0, c_1 that make c_0 u_0 + c_1 u_1 + u_2 least (zero
        for a linear map with two slow directions) give the fixed point (c_0 s_1 + c_1 s_2 + s_3) / (c_0 + c_1
        + 1); the rates are the roots of z^2 + c_1 z + c_0. Refused where the periods of the tail differ in
        their modes or their engagements (impacts, sticks: the map is not one smooth map there), the fit is
        not clean (residual above 1e-6 of the last difference), a rate is not below 0.999 in magnitude, or
        plain iteration converges within a few periods anyway. Plain Python: it is tried at every period.
        """
        tail = sections[-4:]
        if any(modes != tail[0][1] for _s, modes in tail):
            return None
        engagements = [b - a for a, b in zip(counts[-4:], counts[-3:])]
        if any(n != engagements[0] for n in engagements):
            return None
        states = [[x / s for x, s in zip(state, self.scales)] for state, _m in tail]
        u0, u1, u2 = ([b - a for a, b in zip(s0, s1)] for s0, s1 in zip(states, states[1:]))
        g00, g01, g11 = _dot(u0, u0), _dot(u0, u1), _dot(u1, u1)
        b0, b1, last = -_dot(u0, u2), -_dot(u1, u2), _dot(u2, u2)
        det = g00 * g11 - g01 * g01
        if not det > 1e-12 * g00 * g11 or last == 0.0:
            return None  # the two differences are parallel (one direction: Aitken's case) or the tail is still
        c0, c1 = (b0 * g11 - b1 * g01) / det, (b1 * g00 - b0 * g01) / det
        residual = [c0 * x + c1 * y + z for x, y, z in zip(u0, u1, u2)]
        total = c0 + c1 + 1.0
        if _dot(residual, residual) > 1e-6 * last or abs(total) < 1e-3:
            return None
        root = cmath.sqrt(c1 * c1 - 4.0 * c0)
        rate = max(abs((-c1 + root) / 2.0), abs((-c1 - root) / 2.0))
        if not rate < 0.999 or math.log(self.tolerance / math.sqrt(last)) / math.log(rate) < 3:
            return None
        return tuple((c0 * x + c1 * y + z) / total * s for x, y, z, s in zip(states[1], states[2], states[3],
                                                                                self.scales))
