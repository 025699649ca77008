"""A user's FMU's time response to ``F cos(w t)`` from rest, sampled every ``step`` (a scene's ``[[trace]]``).

Model exchange: integrated by dfwb with the sine exact (:class:`~dfwb.foreign.flow.Flow`), the outputs
read at each sample time. Co-simulation: one communication step per sample, the step's mean of the sine
held over it (or the sine itself inside the step where the FMU asks for it, FMI 3.0 intermediate
update). Runs in the worker process.
"""

import math

import numpy as np

from dfwb.foreign.flow import Flow

__all__ = ["response"]

RTOL = 1e-8


def response(instance, F, omega, params, stop, step, outputs):
    """{"time": [...], output: [...] for each of ``outputs``} on t = 0, step, ..., stop."""
    count = int(math.floor(stop / step + 1e-9))
    times = step * np.arange(count + 1)
    values = np.empty((count + 1, len(outputs)))

    def law(t):
        return F * math.cos(omega * t)

    if instance.kind == "model-exchange":
        next_event = instance.start(params, F)
        flow = Flow(instance, lambda t, w, y: law(t), lambda t, w, y, u: np.zeros(0), 0, reads_output=False)
        flow.next_event = next_event
        z = instance.states()
        flow.scale[:] = np.maximum(np.abs(z), 1e-300)
        flow.evaluate(0.0, z)
        values[0] = instance.read(outputs)
        for i in range(count):
            _t, z, _events, _crossed = flow.run(times[i], z, times[i + 1], RTOL, flow.atol(RTOL),
                                                first_step=times[i + 1] - times[i])
            flow.evaluate(times[i + 1], z)
            values[i + 1] = instance.read(outputs)
    else:
        a = omega * step / 2
        mean = math.sin(a) / a if a else 1.0  # the step's mean of the sine over its midpoint value
        instance.input_law = law if instance.intermediate else None
        instance.start(params, F if instance.intermediate else F * mean * math.cos(a))
        values[0] = instance.read(outputs)
        for i in range(count):
            instance.set_input(law(times[i]) if instance.intermediate else
                               F * mean * math.cos(omega * (times[i] + step / 2)))
            instance.do_step(step)
            values[i + 1] = instance.read(outputs)
    if not np.all(np.isfinite(values)):
        raise FloatingPointError("an output is not finite (NaN or overflow)")
    return {"time": times.tolist(), **{name: values[:, j].tolist() for j, name in enumerate(outputs)}}
