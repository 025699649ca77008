"""A user's FMU as one live :class:`dfwb.fmi.instance.Instance`, its force input and position output bound.

The drivers (:mod:`dfwb.foreign.model_exchange`, :mod:`dfwb.foreign.held`)
speak only to this; the FMI calls are :mod:`dfwb.fmi.instance`'s, the one
stack that runs FMUs. Runs only inside a worker process
(:mod:`dfwb.foreign.worker`): this is where the FMU's native code is loaded.
"""

from dfwb.fmi import instance
from dfwb.foreign.description import MAX_EVENT_INDICATORS

__all__ = ["Instance"]


class Instance(instance.Instance):
    """The FMU ``info`` describes, run through its interface ``kind``; errors name its path.

    Parameters
    ----------
    info : FMUInfo
    kind : {"model-exchange", "co-simulation"}
    input, output : str
        The force input and the position output.
    """

    def __init__(self, info, kind, input, output):
        # FMI 3.0 co-simulation that asks for the force inside its steps: given there, from the input law
        intermediate = info.major == "3" and kind == "co-simulation" and input in info.intermediate_inputs
        super().__init__(info.folder, kind, label=str(info.path), identifier=info.identifiers[kind], input=input,
                         output=output, intermediate=intermediate, sizes=(info.states, info.event_indicators),
                         max_size=MAX_EVENT_INDICATORS)
        self.info = info
