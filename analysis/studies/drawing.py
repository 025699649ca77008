"""Figures drawn in worker processes, while the next scene computes.

``dfwb paper`` runs nine scenes, each ending in a figure (PNG and SVG).
Drawn in the run's own process, one after the other, the figures take longer
than the points, and one of the two cores idles. A :class:`Drawing` hands
each figure to a small pool of processes forked from a server that has
matplotlib and dfwb's plots loaded already (multiprocessing's
``forkserver`` with preloaded modules), so a figure costs only its drawing,
and the next scene's points are computed meanwhile. A figure that cannot be
drawn raises its error where the run waits for it (:meth:`Future.result`).
"""

import concurrent.futures as futures
import multiprocessing
import os
import signal
from multiprocessing import forkserver

from dfwb.studies.executor import orphan_watch

PRELOAD = ["dfwb.plotting.plots", "dfwb.studies.paper"]  # what every figure needs: imported once, in the server


def _drawing_process(run):
    """A drawing process's start: Ctrl-C is the run's to handle (it stops the pool), and the process ends
    when the run does, however it ends."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    orphan_watch(run)


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
            forkserver.ensure_running()  # returns at once; the server imports PRELOAD on its own
            self._pool = futures.ProcessPoolExecutor(self.jobs, context, initializer=_drawing_process,
                                                     initargs=(os.getpid(),))

    def submit(self, function, *args):
        """``function(*args)`` in a drawing process: a Future of its result."""
        self.prepare()
        return self._pool.submit(function, *args)

    def __enter__(self):
        return self

    def __exit__(self, kind, *exc):
        if self._pool is not None:
            self._pool.shutdown(wait=kind is None, cancel_futures=kind is not None)
            self._pool = None
