"""A user's FMU runs in a worker process with a time limit: a crash or a hang costs one point, never the run.

An FMU is native code dfwb did not write. :class:`Worker` keeps one child
process (``python -m dfwb.foreign.worker``: a fresh interpreter that
inherits nothing of the caller's threads and never re-imports the caller's
script) that loads the FMU and computes points on request. Requests go in on
its stdin and answers come back on a pipe of their own, so whatever the FMU
prints cannot corrupt them. If the child does not answer within the time
limit it is killed; if it dies (a segmentation fault in ``doStep``) its exit
is noticed; either way the point fails with :class:`PointFailed` naming the
FMU and the reason, and the next point starts a fresh child.
"""

import atexit
import contextlib
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
import threading
import weakref

from dfwb.base.errors import DfwbError

__all__ = ["Worker", "PointFailed", "PointTimedOut", "TIMEOUT", "borrowed"]

TIMEOUT = 120.0  # seconds a point may take by default, at least (see dfwb.foreign.engine.FMUEngine.limit)
_HEADER = struct.Struct("<Q")
MAX_ANSWER = 1 << 24  # bytes: an answer is a few hundred


class PointFailed(DfwbError, RuntimeError):
    """One point could not be computed: the FMU refused, crashed, hung or gave NaN."""


class PointTimedOut(PointFailed):
    """The point was cut by its time limit (its worker killed): it may only need more time."""


def _describe_exit(code):
    if code is not None and code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


def _send(stream, value):
    data = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(_HEADER.pack(len(data)) + data)
    stream.flush()


def _read_exactly(fd, size):
    chunks, left = [], size
    while left:
        chunk = os.read(fd, left)
        if not chunk:
            raise EOFError
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


class Worker:
    """One child process computing points of user FMUs, restarted after a crash or a time-out."""

    def __init__(self, timeout=TIMEOUT):
        self.timeout = timeout
        self._process = None
        self._answers = None
        _EVERY.add(self)

    def _start(self):
        read_end, write_end = os.pipe()
        # The child is born with SIGINT blocked (the mask crosses fork and exec) and ignores it before unblocking:
        # a Ctrl-C reaches the whole process group, and it is the parent's to handle (it ends its workers).
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            self._process = subprocess.Popen([sys.executable, "-m", "dfwb.foreign.worker", str(write_end)],
                                             stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                             pass_fds=(write_end,))
        except OSError:
            os.close(read_end)
            raise
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
            os.close(write_end)
        self._answers = read_end

    def call(self, request, what, timeout=None):
        """The child's answer to ``request`` (see :func:`_serve`), or PointFailed naming ``what`` and why.

        ``timeout``: seconds for this call (default: the worker's)."""
        timeout = self.timeout if timeout is None else timeout
        if self._process is None or self._process.poll() is not None:
            self.close()
            self._start()
        try:
            _send(self._process.stdin, request)
            ready, _, _ = select.select([self._answers], [], [], timeout)
            if not ready:
                self.close()
                raise PointTimedOut(f"{what}: no answer within {timeout:g} s (the FMU hangs, or the machine is busy)")
            size = _HEADER.unpack(_read_exactly(self._answers, _HEADER.size))[0]
            if size > MAX_ANSWER:
                raise EOFError
            status, value = pickle.loads(_read_exactly(self._answers, size))
        except (EOFError, OSError, pickle.UnpicklingError):
            try:
                code = self._process.wait(5)
            except subprocess.TimeoutExpired:
                code = None
            self.close()
            raise PointFailed(f"{what}: the FMU's process died ({_describe_exit(code)}); "
                              "the point is skipped") from None
        if status != "ok":
            raise PointFailed(f"{what}: {value}")
        return value

    def close(self):
        """Stop the child (killed if it does not stop at once)."""
        process, answers = self._process, self._answers
        self._process = self._answers = None
        if process is not None:
            if process.poll() is None:
                process.kill()
            try:
                process.wait(5)
            except subprocess.TimeoutExpired:
                pass
            try:
                process.stdin.close()
            except OSError:
                pass
        if answers is not None:
            os.close(answers)

    def __del__(self):
        try:
            self.close()
        except Exception:  # interpreter shutdown: nothing left to close with
            pass


_EVERY = weakref.WeakSet()  # every worker of this process: stopped when it exits (a hung FMU's too)


@atexit.register
def _stop_every_worker():
    for worker in list(_EVERY):
        worker.close()


_IDLE = []  # workers not in use, kept for the next call: a worker's start costs about 0.8 s
_IDLE_LOCK = threading.Lock()
MAX_IDLE = 8


@contextlib.contextmanager
def borrowed():
    """A worker for one call, taken from those this process keeps (or started), given back after.

    Every describing function, sweep or map of a user's FMU shares them, so
    that calls in a loop do not start a process each; a worker serves one
    call at a time, and one that was killed starts again on its next call.
    """
    with _IDLE_LOCK:
        worker = _IDLE.pop() if _IDLE else Worker()
    try:
        yield worker
    finally:
        with _IDLE_LOCK:
            keep = len(_IDLE) < MAX_IDLE
            if keep:
                _IDLE.append(worker)
        if not keep:
            worker.close()


def _serve(answer_fd):
    """The child's loop: requests in on stdin, ("ok", value) or ("error", one line) out, until stdin closes."""
    from dfwb.foreign import compute

    requests = sys.stdin.buffer
    answers = os.fdopen(answer_fd, "wb")
    instances = {}  # the instances of the FMUs this worker has run, the last few
    while True:
        header = requests.read(_HEADER.size)
        if len(header) < _HEADER.size:
            return
        request = pickle.loads(requests.read(_HEADER.unpack(header)[0]))
        if len(instances) > 8:  # a long-lived worker sees many FMUs: keep the recent ones
            instances.pop(next(iter(instances)))
        try:
            answer = ("ok", compute.run(request, instances))
        except Exception as error:  # reported to the parent as the point's failure
            instances.clear()  # an instance that failed is not trusted again
            message = " ".join(str(error).split()) or type(error).__name__
            answer = ("error", message[:600])
        _send(answers, answer)


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # blocked since birth (Worker._start): a Ctrl-C is the parent's
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    _serve(int(sys.argv[1]))
