"""FMI status in one place: which status fails a call, and the FMU's own messages for the error it raises.

fmpy raises ``FMICallException`` for a status worse than fmi2Warning. dfwb's
hot paths call the FMU's functions directly, without fmpy's wrappers; they
apply the same rule with :func:`check`. Every FMU instance dfwb makes (its
own FMUs' sessions, fmpy's whole simulations, a user's FMU) collects what
the FMU logs with a :class:`Messages`, whose callbacks fit FMI 2.0 and 3.0,
and names those messages in the error a refused call raises.

Examples
--------
>>> from dfwb.fmi.status import Messages, check
>>> check("fmi2DoStep", 1)
1
>>> messages = Messages()
>>> log = messages.fmi2()
>>> log(None, None, 3, b"logStatusError", b"FrictionMass: M = -1 is out of range")
>>> log(None, None, 3, b"logStatusError", b"Fatal py exception encountered")
>>> messages.reasons()
'FrictionMass: M = -1 is out of range'
>>> check("fmi2DoStep", 3)
Traceback (most recent call last):
...
fmpy.fmi1.FMICallException: fmi2DoStep failed with status 3 (error).
"""

from fmpy.fmi1 import FMICallException

__all__ = ["check", "Messages", "WARNING", "ERROR", "STATUS"]

WARNING, ERROR = 1, 3  # fmi2Warning, fmi2Error (the same numbers in FMI 3.0)
STATUS = {1: "warning", 2: "discard", 3: "error", 4: "fatal"}
NOISE = "Fatal py exception"  # pythonfmu's generic line after an FMU's own message: never a reason


def check(function, status):
    """``status``, or FMICallException naming ``function`` for a status worse than a warning (fmpy's rule)."""
    if status > WARNING:
        raise FMICallException(function=function, status=status)
    return status


class Messages:
    """What an FMU logs with status warning or worse, kept for the error of its next refused call.

    ``labelled``: each message says its status ("error: ...").
    """

    def __init__(self, labelled=False):
        self.labelled = labelled
        self._held = []

    def add(self, status, message):
        """Keep ``message`` (bytes, as FMI passes it) when ``status`` is a warning or worse."""
        if status >= WARNING:
            text = message.decode(errors="replace").strip() if isinstance(message, bytes) else str(message).strip()
            if text and NOISE not in text:
                self._held.append(f"{STATUS.get(status, status)}: {text}" if self.labelled else text)

    def fmi2(self):
        """The FMI 2.0 logger function: ``(env, instance, status, category, message)``."""
        return lambda _env, _instance, status, _category, message: self.add(status, message)

    def fmi3(self):
        """The FMI 3.0 logMessage function: ``(env, status, category, message)``."""
        return lambda _env, status, _category, message: self.add(status, message)

    def reasons(self, otherwise=""):
        """The messages held, joined with "; " (``otherwise`` when there are none); then none are held."""
        held, self._held = self._held, []
        return "; ".join(held) or otherwise

    def __bool__(self):
        return bool(self._held)
