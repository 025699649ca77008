"""Where DF points (and a hunting map's cells) are computed: in this process, in local processes, or on Dask.

Work goes out in chunks of points of one plant with one engine setting;
results come back as each chunk finishes, in any order, so the caller can
record them at once. The three backends give identical results (the
computation is deterministic; only the ``seconds`` field differs):

- ``jobs=1``: this process (no start-up cost, easiest to debug);
- default: this process first; a pool of spawned local processes (one engine
  per plant each) takes over only once the work left, estimated from the
  chunks done here, exceeds :data:`POOL_WORTH` seconds: two spawned workers
  cost about 1.5 s to start (imports), more than a thousand DF points on the
  native FMUs, so the paper's points never pay for them;
- ``jobs=N``: a pool of N spawned local processes from the start;
- ``dask="local"`` starts a ``distributed.LocalCluster``; ``dask="tcp://host:8786"``
  uses a running scheduler. The FMU files are shipped to the workers (scattered
  once, written to each worker's temporary directory under their SHA-256), so
  a worker needs dfwb installed but neither the FMUs nor a build.

One executor can serve several runs (``dfwb paper`` shares one between its
scenes), so a pool, once started, is started once. On Ctrl-C the terminal
signals every process of the group: the workers ignore SIGINT (blocked from
before they exist until they ignore it, so none prints a traceback while it
starts), and the run, which gets the KeyboardInterrupt, ends them. A worker
so ended runs no exit handler: its temporary files (the FMUs it unpacked) are
kept in a folder of the pool's, which the run removes once its workers are
gone.
"""

import atexit
import contextlib
import hashlib
import os
import shutil
import signal
import socket
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from dfwb.base.errors import InputError, RunError
from dfwb.base.files import file_digest, write_atomic
from dfwb.studies.cache import code_revision

MAX_JOBS = 256  # worker processes: far beyond any useful count, short of exhausting the machine
_ENGINES = {}  # per worker thread: (thread, plant, settings, FMU file) -> DFEngine (FMU instances are not shared)


@dataclass(frozen=True)
class Chunk:
    """Points [(F, omega, params)] of one plant, one FMU and one engine setting."""

    plant: str
    fmu: str  # path of the FMU file where it was built
    settings: tuple  # sorted (name, value) pairs for DFEngine: drive, samples_per_period, max_periods, harmonics
    points: tuple


def cached_engine(plant, fmu, settings, fmu_data=None):
    """This thread's DF engine of a plant FMU, made once per thread, plant, settings and FMU (shipped FMU bytes
    written locally first). Not :func:`dfwb.foreign.engine.engine_for`, which chooses the engine of a plant."""
    from dfwb.engine.describing import DFEngine  # the engine (fmpy, numpy) loads where points are computed

    path = _materialize(fmu, fmu_data) if fmu_data is not None else fmu
    key = (threading.get_ident(), plant, settings, str(path))
    if key not in _ENGINES:
        _ENGINES[key] = DFEngine(plant, fmu=path, **dict(settings))
    return _ENGINES[key]


def compute(chunk, fmu_data=None):
    """(code revision, the as_dict() of every point of a chunk); ``fmu_data``: the FMU's bytes, shipped to a
    remote worker. The revision lets the client refuse results of a worker that runs other code."""
    engine = cached_engine(chunk.plant, chunk.fmu, chunk.settings, fmu_data)
    return code_revision(), [engine.point(F, omega, params).as_dict() for F, omega, params in chunk.points]


_SHIPPED_DIR = []  # this process's private folder for shipped FMUs (created once, mode 0700)


def _materialize(original, data):
    """A local copy of shipped FMU bytes, in a folder private to this process, verified before every use.

    The folder comes from ``tempfile.mkdtemp`` (created atomically, mode 0700, an unpredictable name), so
    nothing planted at a known path is ever loaded; the file is named by its full SHA-256 and its content is
    hashed again each time it is handed out."""
    expected = hashlib.sha256(data).hexdigest()
    if not _SHIPPED_DIR:
        _SHIPPED_DIR.append(Path(tempfile.mkdtemp(prefix="dfwb-fmus-")))
    path = _SHIPPED_DIR[0] / expected / Path(original).name
    if not (path.is_file() and not path.is_symlink() and file_digest(path) == expected):
        path.parent.mkdir(mode=0o700, exist_ok=True)
        write_atomic(path, data)
    return path


_POOL_DIRS = []  # (pid, folder): the temporary folders of this process's local pools, removed by its exit at the latest


@atexit.register
def _remove_shipped():
    for folder in _SHIPPED_DIR:
        shutil.rmtree(folder, ignore_errors=True)
    for pid, folder in _POOL_DIRS:
        if pid == os.getpid():  # (not a forked child's: its parent's pool may still run)
            shutil.rmtree(folder, ignore_errors=True)


@contextlib.contextmanager
def interrupts_held():
    """Ctrl-C (and ``kill``) held back while this (the main) thread starts processes, then delivered.

    A process being started when the run stops would be left half-way, unknown to its pool, and fail with a
    traceback once the run has gone (its pool's semaphores unlinked): here the signal waits until it has
    started. SIGINT is also blocked in this thread, and the processes started meanwhile inherit the mask, so
    a Ctrl-C stays pending in them until they ignore it (:func:`point_worker`; a fork server ignores it
    once its modules are imported) instead of raising a KeyboardInterrupt while they start. The resource
    tracker of multiprocessing is started first: starting it unblocks SIGINT in the thread that does."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()  # (it ignores Ctrl-C itself)
    arrived = []
    handlers = {number: signal.getsignal(number) for number in (signal.SIGINT, signal.SIGTERM)}
    handlers = {number: handler for number, handler in handlers.items() if handler is not None}  # None: not Python's
    for number in handlers:
        signal.signal(number, lambda number, frame: arrived.append(number))
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # a SIGINT pending here trips the holding handler
        for number in sorted(handlers, key=lambda number: number == signal.SIGINT):  # SIGINT's last (Ctrl-C)
            signal.signal(number, handlers[number])
        for number in arrived[:1]:  # the first is delivered as it would have been
            if callable(handlers[number]):
                handlers[number](number, None)
            elif handlers[number] == signal.SIG_DFL:
                signal.raise_signal(number)


def point_worker(parent, temporary=None):
    """A spawned worker's start: Ctrl-C is the run's to handle (it ends the workers), and the worker exits
    when the run is gone. SIGINT arrives blocked (:func:`interrupts_held`): ignored before it is unblocked,
    a Ctrl-C that came meanwhile is discarded. ``temporary``: the pool's folder, where the worker (and any
    process it starts) keeps its temporary files, such as the FMUs it unpacks: the run removes it, whole, once
    the workers are gone, also what a worker ended by SIGTERM (no exit handler of its own runs) has left."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    if temporary is not None:
        os.environ["TMPDIR"] = tempfile.tempdir = temporary
    orphan_watch(parent, temporary)


def stop_pool(pool, abort):
    """Shut a process pool down: once its queue is empty, or (``abort``: an error or Ctrl-C) at once, its
    processes ended by SIGTERM (their default action: no traceback, also from one that is starting) and
    waited for, so none is left running, or starting, when the run has gone."""
    if abort:  # (the pool forgets its processes when it shuts down: ended first; it then sees them gone)
        for process in list((getattr(pool, "_processes", None) or {}).values()):
            process.terminate()
    pool.shutdown(wait=True, cancel_futures=True)


def orphan_watch(parent, folder=None):
    """In a worker process: exit as soon as the dfwb run (process ``parent``) is gone, even after a ``kill -9``,
    removing the run's ``folder`` of temporary files (a run killed so cannot remove it; its workers, all
    leaving, each try: what one has loaded stays mapped while its files go).

    A pool's worker is the run's child; a fork server's is the server's, and the server outlives the run
    while its children live: so a worker whose parent is not the run checks that the run still exists."""

    def gone():
        if os.getppid() == parent:
            return False
        try:
            os.kill(parent, 0)
        except ProcessLookupError:
            return True
        except PermissionError:  # a process of another user took its number: the run is gone
            return True
        return False

    def watch():
        while not gone():
            time.sleep(0.5)
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)
        os._exit(1)

    threading.Thread(target=watch, name="dfwb-orphan-watch", daemon=True).start()


def chunked(points, jobs, largest=16):
    """Chunks small enough to balance ``jobs`` workers, large enough to amortise a round trip
    (one point each in this process: nothing finished waits to be recorded)."""
    size = 1 if jobs <= 1 else max(1, min(largest, len(points) // (jobs * 4)))
    return [tuple(points[i:i + size]) for i in range(0, len(points), size)]


POOL_AFTER = 0.2
"""CPU seconds of computing in this process before the default executor estimates the work left (the mean
CPU time of a chunk so far, times the chunks left). CPU time, not wall time: a busy machine slows the points
and the workers' start alike, and the estimate should not call for workers because others load the cores."""
POOL_WORTH = 4.0
"""CPU seconds of estimated work left for which the default executor starts its pool: a spawned worker takes
0.6 to 0.8 CPU seconds to start (it imports numpy and fmpy), two take about 1.5 s of wall time on a 2-core
machine, so a pool pays only beyond about twice that."""


def _probe(address):
    """Connect once to a TCP scheduler's address (``tcp://host:port`` or ``host:port``): a refused or unknown
    address is an OSError at once, where dask's client would retry for its whole timeout."""
    scheme, _, rest = address.rpartition("://")
    host, _, port = rest.rpartition(":")
    if scheme not in ("", "tcp") or not port.isdigit():
        return  # another protocol (tls, ucx, ...): dask's client decides
    with socket.create_connection((host.strip("[]") or "127.0.0.1", int(port)), timeout=5.0):
        pass


class Executor:
    """Runs chunks; use as a context manager. ``jobs``: workers (default: all cores, once the work has shown
    it is worth starting them)."""

    def __init__(self, jobs=None, dask=None):
        if jobs is not None and not (isinstance(jobs, int) and 1 <= jobs <= MAX_JOBS):
            raise InputError(f"jobs = {jobs!r} is out of range: an integer from 1 to {MAX_JOBS}")
        self.jobs = jobs or os.cpu_count() or 1
        self._local_first = jobs is None and self.jobs > 1  # the pool starts only when the work is long
        if dask:
            try:
                import distributed  # noqa: F401  (checked before anything runs)
            except ImportError:
                raise RunError("--dask needs dask.distributed: pip install -e '.[dask]'") from None
        self.dask = dask
        self._pool = self._client = self._cluster = self._temporary = None
        self._shipped = {}

    @property
    def name(self):
        if self.dask:
            return f"dask ({self.dask})"
        if self.jobs == 1:
            return "this process"
        pool = f"{self.jobs} local processes"
        return f"this process, then {pool}" if self._local_first else pool

    def __enter__(self):
        return self

    def __exit__(self, kind, *exc):
        self.close(abort=kind is not None)

    def close(self, abort=False):
        """Stop the workers: at once on an error or interruption (``abort``: the chunks in flight are lost
        anyway), else once their queue is empty."""
        if self._pool is not None:
            stop_pool(self._pool, abort)
        if self._temporary is not None:  # the workers are gone: what they left goes, a killed one's too
            shutil.rmtree(self._temporary, ignore_errors=True)
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()
        self._pool = self._client = self._cluster = self._temporary = None

    def run(self, chunks, function=None):
        """Yield (chunk, results) as chunks finish; on an error or interruption, the rest are given up (the pool ends).

        ``function(chunk, fmu_data=None)`` computes a chunk and returns (code revision, results): DF points
        (:func:`compute`) by default; a module-level function, so that workers can import it."""
        function = function or compute
        for chunk, (revision, results) in self._run(list(chunks), function):
            if revision != code_revision():
                raise RunError(f"a worker ran dfwb code revision {revision}, this process has {code_revision()}: "
                                   "install the same dfwb on every worker")
            yield chunk, results

    def _run(self, chunks, function):
        if not chunks:
            return
        if self.dask:
            yield from self._run_dask(chunks, function)
        elif self.jobs == 1 or len(chunks) == 1:
            for chunk in chunks:
                yield chunk, function(chunk)
        else:
            done, seconds = 0, 0.0  # seconds: CPU time of the chunks done here but the first (imports, engines)
            while self._pool is None and self._local_first and done < len(chunks) and not (
                    done > 1 and seconds >= POOL_AFTER and seconds / (done - 1) * (len(chunks) - done) > POOL_WORTH):
                started = time.thread_time()
                result = function(chunks[done])
                seconds += (time.thread_time() - started) if done else 0.0
                yield chunks[done], result
                done += 1
            chunks = chunks[done:]
            if not chunks:
                return
            import concurrent.futures as futures  # a pool only when there is work for one

            with interrupts_held():
                if self._pool is None:
                    import multiprocessing

                    self._temporary = tempfile.mkdtemp(prefix="dfwb_run_")  # the workers' temporary files
                    _POOL_DIRS.append((os.getpid(), self._temporary))
                    self._pool = futures.ProcessPoolExecutor(self.jobs,  # spawned as chunks need them
                                                             multiprocessing.get_context("spawn"),
                                                             initializer=point_worker,
                                                             initargs=(os.getpid(), self._temporary))
                waiting = {self._pool.submit(function, chunk): chunk for chunk in chunks}  # spawns the workers
            finished = False
            try:
                for future in futures.as_completed(waiting):
                    yield waiting[future], future.result()
                finished = True
            finally:
                if not finished:  # the rest given up: the pool ends, its own thread cancelling what waits (a
                    self.close(abort=True)  # Future cancelled here may meet a broken pool: InvalidStateError, 3.11)

    # -- Dask ------------------------------------------------------------------------
    def client(self):
        """The dask.distributed client (a LocalCluster of ``jobs`` single-threaded workers for "local")."""
        if self._client is None:
            from distributed import Client, LocalCluster

            if self.dask == "local":
                self._cluster = LocalCluster(n_workers=self.jobs, threads_per_worker=1, processes=True,
                                             dashboard_address=None)
                self._client = Client(self._cluster)
            else:
                try:
                    _probe(self.dask)
                    self._client = Client(self.dask, timeout="20s")
                except (OSError, TimeoutError, ValueError) as error:
                    raise RunError(f"cannot reach the Dask scheduler {self.dask!r}: {error}") from None
        return self._client

    def _run_dask(self, chunks, function):
        from distributed import as_completed

        client = self.client()
        for path in {chunk.fmu for chunk in chunks}:
            if path not in self._shipped:
                self._shipped[path] = client.scatter(Path(path).read_bytes(), broadcast=True)
        waiting = {client.submit(function, chunk, self._shipped[chunk.fmu], pure=False): chunk for chunk in chunks}
        try:
            for future in as_completed(waiting):
                yield waiting[future], future.result()
        finally:
            for future in waiting:
                future.cancel()
