"""What the worker process does with a request: one DF point of a user's FMU, by the best driver its kind allows.

Model exchange: :mod:`dfwb.foreign.model_exchange` (the exact sine, dfwb's
integrator). Co-simulation: :mod:`dfwb.foreign.held` (the held sine,
refined and extrapolated). Runs in the worker (:mod:`dfwb.foreign.worker`).
"""

import sys

from dfwb.fmi.simulation import FMUError
from dfwb.foreign import held, loop, model_exchange, trace
from dfwb.foreign.instance import Instance

__all__ = ["run", "DRIVERS"]

DRIVERS = {"model-exchange": model_exchange.point, "co-simulation": held.point}


def run(request, instances):
    """``{"X": [...], "error": ..., ...}`` for ``request`` (a dict made by :class:`dfwb.foreign.engine.FMUEngine`)."""
    info, kind = request["info"], request["kind"]
    key = (info.digest, kind, request["input"], request["output"])
    instance = instances.get(key)
    if instance is None:
        instance = instances[key] = Instance(info, kind, request["input"], request["output"])
    if request.get("task") == "cycles":
        return _cycles(instance, request)
    if request.get("task") == "trace":
        return trace.response(instance, request["F"], request["omega"], request["params"], request["stop"],
                              request["step"], request["outputs"])
    try:
        X, error, periodic, periods, lag, note = DRIVERS[kind](
            instance, request["F"], request["omega"], request["params"], harmonics=request["harmonics"],
            rtol=request["rtol"], max_periods=request["max_periods"])
    except (FMUError, FloatingPointError):
        raise
    except Exception as error:  # fmpy's refused call: add the FMU's own log lines
        raise instance.failed("the run", error) from None
    floor = 64 * sys.float_info.epsilon * abs(X[1])  # rounding: no estimate is below it
    return {"X": [complex(x) for x in X], "error": max(float(error), floor), "periodic": bool(periodic),
            "periods": int(periods), "lag": int(lag), "note": note}


def _cycles(instance, request):
    """The true cycles of the closed loop: ``{"cycles": [...], "outcomes": [...]}``."""
    found, outcomes = loop.cycles(instance, request["num"], request["den"], request["params"], request["starts"],
                                  request["omega_ref"], rtol=request["rtol"],
                                  seeds=request.get("seeds", ()))
    return {"cycles": found, "outcomes": outcomes}
