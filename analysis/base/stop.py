"""A stop asked for by a signal (Ctrl-C, ``kill``), recognised even when it lands inside an FMU.

Python code of a pythonfmu FMU runs in this interpreter, so the
KeyboardInterrupt of a signal can be raised inside an FMU callback, where
the FMU reports it as a fatal error of the call. The handler here also
records that a stop was asked for, and :func:`requested` lets the FMU
session report such a failure as the interruption it is.
"""

import contextlib
import signal

_requested = []


def _handler(signum, frame):
    _requested.append(signum)
    raise KeyboardInterrupt


def requested():
    """Whether a SIGINT or SIGTERM arrived while :func:`handling_signals` was active."""
    return bool(_requested)


@contextlib.contextmanager
def handling_signals():
    """Turn SIGINT and SIGTERM into KeyboardInterrupt (workers are stopped, finished points kept)."""
    _requested.clear()
    previous = {number: signal.signal(number, _handler) for number in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
