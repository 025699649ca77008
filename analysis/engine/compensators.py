"""The compensators of the exact loop by name, with their parameters: what ``--compensate``, scenes and the API name.

A study names its compensators (``compensate=["coulomb", "deadband"]``); their
parameters are then set, continued and mapped like G's (``F_hat``, ``d``), and
:class:`Compensation` builds the loop's compensators of
:mod:`dfwb.fmus.compensation` at each setting. One parameter is a choice, not a
number: the Coulomb feedforward's ``signal``.

Examples
--------
>>> compensation = Compensation(["coulomb", "reset"])
>>> compensation.names, compensation.defaults
(('F_hat', 'signal'), {'signal': 'velocity'})
>>> compensation.build({"F_hat": 3.0, "signal": "control"})
[Coulomb(F_hat=3.0, signal='control'), Reset()]
>>> Compensation("dither").build({"a": 2.0, "w_d": 20.0})
[Dither(a=2.0, w_d=20.0)]
>>> Compensation("backlash-inverse").build({"h_hat": 0.1})
[BacklashInverse(h_hat=0.1)]
"""

from dataclasses import dataclass, field

from dfwb.base.errors import InputError, PlantError
from dfwb.fmus.compensation import SIGNALS, BacklashInverse, Coulomb, Deadband, Dither, Reset, check_estimate

__all__ = ["KINDS", "CHOICES", "Compensation", "choice", "check_judged"]


@dataclass(frozen=True)
class Kind:
    """A compensator: its numeric parameters (each needs a value), how it is built from its values, and its
    choices (name: allowed values, the first the default)."""

    parameters: tuple
    build: object
    choices: dict = field(default_factory=dict)


KINDS = {
    "coulomb": Kind(("F_hat",), lambda v: Coulomb(v["F_hat"], v["signal"]), {"signal": SIGNALS}),  # F_hat sgn(signal)
    "deadband": Kind(("d",), lambda v: Deadband(v["d"])),  # the integrator holds while |y| < d
    "reset": Kind((), lambda v: Reset()),  # the integrator cleared when the mass comes to rest
    "dither": Kind(("a", "w_d"), lambda v: Dither(v["a"], v["w_d"])),  # a sin(w_d t) added to the force
    # the controller sees y + k h_hat/2 s, s the side of the play's last contact (the static backlash)
    "backlash-inverse": Kind(("h_hat",), lambda v: BacklashInverse(v["h_hat"])),
}
CHOICES = {name: allowed for kind in KINDS.values() for name, allowed in kind.choices.items()}


def choice(name, value):
    """The value of a choice parameter (``signal``), refused in one line unless it is one of the allowed."""
    allowed = CHOICES[name]
    if value not in allowed:
        raise InputError(f"{name} = {value!r:.60}: one of {', '.join(allowed)}")
    return value


def check_judged(compensation, exact, verify):
    """Refuse a limit-cycle study of a compensated loop that is not judged by its exact loop (most compensated
    loops have no DF; dfwb's closed-loop FMUs, which ``verify`` co-simulates, have no compensators)."""
    if compensation and not exact:
        raise InputError("compensate: a compensated loop is judged by its exact loop: add exact (--exact)")
    if compensation and verify:
        raise InputError("compensate: verify co-simulates dfwb's closed-loop FMUs, which have no compensators: "
                         "leave verify out")


class Compensation:
    """The compensators a study names, in the loop at every setting of their parameters.

    Parameters
    ----------
    compensate : str or list of str, optional
        Names among ``coulomb``, ``deadband``, ``reset``, ``dither`` and ``backlash-inverse``, each at most once.
    """

    def __init__(self, compensate=None):
        given = [] if compensate is None else [compensate] if isinstance(compensate, str) else compensate
        try:
            given = list(given)
        except TypeError:
            raise InputError(f"compensate = {compensate!r:.60}: give a compensator's name or a list of them") from None
        for name in given:
            if not isinstance(name, str) or name not in KINDS:
                known = ", ".join(KINDS)
                raise InputError(f"compensate = {name!r:.60}: not a compensator (allowed: {known})")
        repeated = [name for name in given if given.count(name) > 1]
        if repeated:
            raise InputError(f"compensate = {repeated[0]!r} is named twice: name each compensator once")
        self.kinds = tuple(given)
        self.names = tuple(p for name in given for p in (*KINDS[name].parameters, *KINDS[name].choices))
        self.defaults = {p: allowed[0] for name in given for p, allowed in KINDS[name].choices.items()}

    def __bool__(self):
        return bool(self.kinds)

    def numeric(self, name):
        """Whether ``name`` is one of the compensators' numeric parameters (a choice is set, never swept)."""
        return name in self.names and name not in CHOICES

    def build(self, values):
        """The compensators at ``values`` (their parameters' values; choices at their defaults unless given), or
        None without any; a value a compensator refuses raises its one-line error."""
        if not self.kinds:
            return None
        merged = dict(self.defaults, **{k: v for k, v in values.items() if k in self.names})
        return [KINDS[name].build(merged) for name in self.kinds]

    def check(self, name, value):
        """Refuse ``value`` of the compensator parameter ``name`` in one line (InputError) as its compensator does,
        whatever the compensator's other parameters (they are set to 1 here, a value each accepts): what a
        range's ends are held to before anything runs."""
        kind = next(kind for kind in KINDS.values() if name in kind.parameters)
        values = dict({p: 1.0 for p in kind.parameters}, **{p: allowed[0] for p, allowed in kind.choices.items()})
        try:
            kind.build(dict(values, **{name: value}))
        except PlantError as error:
            raise InputError(str(error)) from None

    def fit(self, spec):
        """Refuse, in one line (InputError), a compensator that cannot act on the plant ``spec``: the backlash
        inverse on a plant without a play (whatever h_hat, 0 included)."""
        if "backlash-inverse" in self.kinds and not getattr(spec.loop, "CONTACTS", None):
            from dfwb.plants import names, plant

            played = [name for name in names() if getattr(plant(name).loop, "CONTACTS", None)]
            raise InputError(f"compensate = 'backlash-inverse': the backlash inverse needs a plant with a play "
                             f"({', '.join(played)}); {spec.name} has none")

    def check_estimate(self, spec, params, values):
        """Refuse a backlash inverse's h_hat too far from the play h of the plant ``spec`` at ``params`` (its
        defaults for the others) in one line (:func:`dfwb.fmus.compensation.check_estimate`)."""
        if "backlash-inverse" in self.kinds:
            try:
                check_estimate(dict(self.defaults, **values)["h_hat"], dict(spec.defaults(), **params)["h"])
            except PlantError as error:
                raise InputError(str(error)) from None

    def _own_df(self, spec):
        """The engine class of the compensated plant's DF where it is one of its own, else None: the static
        backlash seen through its inverse (a closed form, :mod:`dfwb.engine.inverse_df`), the friction mass with a
        dither alone (the dual-input DF, :mod:`dfwb.engine.dither_df`)."""
        if self.kinds == ("backlash-inverse",) and spec.name == "static-backlash":
            from dfwb.engine.inverse_df import InverseDFEngine

            return InverseDFEngine
        if self.kinds == ("dither",):
            from dfwb.engine.dither_df import PLANTS, DitherDFEngine

            return DitherDFEngine if spec.name in PLANTS else None
        return None

    def equivalent(self, spec, params, values):
        """The parameters of the compensated plant's DF (its engine :meth:`df_engine`'s), or None where there is
        none.

        Three cases. The Coulomb feedforward of the velocity alone on the friction mass, at most its Coulomb level
        (F_hat <= Fc): a slide then sees F_hat less friction and a stuck mass nothing (the velocity is 0), the
        friction mass with Fc - F_hat, Fs kept, its DF computed as any plant's. The backlash inverse alone on the
        static backlash: the plant's parameters and h_hat, its DF a closed form (:mod:`dfwb.engine.inverse_df`).
        The dither alone on the friction mass: the plant's parameters with a and w_d, its DF the dual-input DF
        (:mod:`dfwb.engine.dither_df`). Over-compensation (a negative Coulomb level), the controller's sign (a
        nonlinear controller), the integrator's management (the controller's state), compensators together, a
        dither on a free mass (it drifts) and the inverse of a play between two masses (impacts) have none.
        """
        if self._own_df(spec) is not None:
            merged = dict(self.defaults, **values)
            return dict(params, **{name: merged[name] for kind in self.kinds for name in KINDS[kind].parameters})
        if self.kinds != ("coulomb",) or spec.name != "friction":
            return None
        merged, Fc = dict(self.defaults, **values), dict(spec.defaults(), **params)["Fc"]
        if merged["signal"] != "velocity" or not 0.0 <= merged["F_hat"] <= Fc:
            return None
        return dict(params, Fc=Fc - merged["F_hat"])

    def df_engine(self, spec, engine):
        """The engine of the compensated plant ``spec``'s DF: ``engine`` (the plant's), or the compensated
        plant's own (:meth:`_own_df`)."""
        own = self._own_df(spec)
        return engine if own is None else own(spec)

    def df_text(self, spec):
        """What the compensated plant's own DF is, in words (a summary's), or None where it is the plant's with
        other parameters."""
        own = self._own_df(spec)
        return None if own is None else own.described

    def describe(self, values):
        """The compensators and their values as one short text: ``coulomb (F_hat = 3, signal = control), reset``."""
        merged = dict(self.defaults, **values)
        parts = []
        for name in self.kinds:
            kind = KINDS[name]
            own = [f"{p} = {merged[p]:.6g}" if p in kind.parameters else f"{p} = {merged[p]}"
                   for p in (*kind.parameters, *kind.choices) if p in merged]
            parts.append(name + (f" ({', '.join(own)})" if own else ""))
        return ", ".join(parts)
