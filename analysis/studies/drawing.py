"""Figures drawn in worker processes, while the next scene computes.

``dfwb paper`` runs nine scenes, each ending in a figure (PNG and SVG).
Drawn in the run's own process, one after the other, the figures take longer
than the points, and one of the two cores idles. A :class:`Drawing` hands
each figure to a small pool of processes forked from a server that has
matplotlib and dfwb's plots loaded already (multiprocessing's
``forkserver`` with preloaded modules), so a figure costs only its drawing,
and the next scene's points are computed meanwhile, first (the drawing runs
at a lower priority: :data:`NICENESS`). A figure that cannot be
drawn raises its error where the run waits for it (:meth:`Future.result`).
"""

import concurrent.futures as futures
import multiprocessing
import os
import signal
from multiprocessing import forkserver

from dfwb.studies.executor import interrupts_held, orphan_watch, stop_pool

PRELOAD = ["dfwb.plotting.plots", "dfwb.studies.paper"]  # what every figure needs: imported once, in the server


def _drawing_process(run):
    """A drawing process's start: Ctrl-C is the run's to handle (it stops the pool), and the process ends
    when the run does, however it ends. SIGINT arrives blocked (from the fork server): ignored first."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    orphan_watch(run)


NICENESS = 10
"""The drawing processes' niceness (and the fork server's, which they inherit): on a busy machine the run's
points, which every later scene waits for, go first; on an idle one each side has its core anyway."""


def _lower_priority(pid):
    """Lower the fork server's priority (the run's own process keeps its own); nothing if it cannot."""
    if pid:
        try:
            os.setpriority(os.PRIO_PROCESS, pid, max(os.getpriority(os.PRIO_PROCESS, pid), NICENESS))
        except (OSError, AttributeError):  # gone already, not permitted, or no such call here
            pass


class Drawing:
    """A pool of ``jobs`` drawing processes, started on the first figure; use as a context manager."""

    def __init__(self, jobs=None):
        self.jobs = max(1, jobs or os.cpu_count() or 1)
        self._pool = None

    def prepare(self):
        """Start the fork server, which loads matplotlib and the plots meanwhile: call it when a figure is
        sure to come, before the computing that precedes it (a run that draws nothing never starts it)."""
        if self._pool is None:
            os.environ["MPLBACKEND"] = "Agg"  # the server, and the processes it forks, draw into files
            context = multiprocessing.get_context("forkserver")
            context.set_forkserver_preload(PRELOAD)
            with interrupts_held():  # the server ignores Ctrl-C only after its imports: held back until then
                forkserver.ensure_running()  # returns at once; the server imports PRELOAD on its own
            _lower_priority(getattr(getattr(forkserver, "_forkserver", None), "_forkserver_pid", None))
            self._pool = futures.ProcessPoolExecutor(self.jobs, context, initializer=_drawing_process,
                                                     initargs=(os.getpid(),))

    def submit(self, function, *args):
        """``function(*args)`` in a drawing process: a Future of its result."""
        self.prepare()
        with interrupts_held():  # a process started here is known to the pool (to end it) before a Ctrl-C
            return self._pool.submit(function, *args)

    def __enter__(self):
        return self

    def __exit__(self, kind, *exc):
        if self._pool is not None:
            stop_pool(self._pool, abort=kind is not None)  # on Ctrl-C the figures in flight are given up
            self._pool = None
