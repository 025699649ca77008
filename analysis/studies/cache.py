"""A content-addressed cache of computed results (DF points, traces, limit cycles).

An entry's key is the SHA-256 of everything that determines its value: the
kind of result, the FMU's content hash, the engine's source revision, the
complete parameter set (defaults filled in, so ``eps = 0.5`` given or
defaulted is the same point), the point and the engine settings. A second
run of a scene, or another scene sharing points, finds them here; a changed
parameter gives new keys for exactly the affected points.

Each entry is one file, written atomically: a header line that repeats its
key document and carries a checksum of the value, then the value (JSON). An entry that does not parse,
whose format, key or checksum does not match, is counted as rejected and
recomputed: a corrupt cache, or one from another version, is never trusted.

The cache lives in ``$XDG_CACHE_HOME/dfwb``, else ``~/.cache/dfwb``.

Examples
--------
>>> import tempfile
>>> cache = Cache(tempfile.mkdtemp())
>>> cache.get({"kind": "demo", "x": 1.0}) is None
True
>>> cache.put({"kind": "demo", "x": 1.0}, {"y": 2.0})
>>> cache.get({"kind": "demo", "x": 1.0}), cache.hits, cache.rejected
({'y': 2.0}, 1, 0)
"""

import contextlib
import errno
import functools
import hashlib
import json
import math
import os
import stat
import threading
import warnings
from pathlib import Path

from dfwb.base.errors import InputError, RunError
from dfwb.base.files import ensure_folder, file_digest, user_cache_dir, write_atomic

FORMAT = 2
MAX_ENTRY = 64 << 20  # bytes: the largest entries (a figure's PNG and SVG) are a few hundred kB


def default_dir():
    """``$XDG_CACHE_HOME/dfwb``, else ``~/.cache/dfwb``."""
    return user_cache_dir()


# The layers whose code computes or shapes a cached value (the FMUs' own sources are covered
# by their build hash). The command line and the plots are not among them: editing a plot
# redraws figures (their keys add :func:`drawing_revision`) but keeps every computed point.
COMPUTING = ("base", "plants", "fmi", "foreign", "engine", "studies")
DRAWING = ("plotting",)


PACKAGE = Path(__file__).resolve().parent.parent


def sources_digest(paths, base):
    """Hash of source files: each one's path relative to ``base`` and its content, in the order given."""
    digest_ = hashlib.sha256()
    for path in paths:
        digest_.update(Path(path).relative_to(base).as_posix().encode() + b"\0" + Path(path).read_bytes())
    return digest_.hexdigest()[:16]


@functools.lru_cache(maxsize=None)
def revision(layers, root=PACKAGE):
    """Hash of the modules of the given dfwb layers (subpackages of ``root``)."""
    return sources_digest([path for layer in layers for path in sorted((root / layer).glob("*.py"))], root)


def code_revision():
    """Revision of the code that computes results: any change to it gives new keys."""
    return revision(COMPUTING)


def solver_revision():
    """Revision of the exact solvers that run in this process, not through an FMU (the exact closed loop)."""
    from dfwb import fmus

    return revision((".",), Path(fmus.__file__).resolve().parent)


def drawing_revision():
    """Revision of the code that draws figures (part of a cached figure's key)."""
    return revision(DRAWING)


def fmu_revision(path):
    """The source hash the FMU was built from (its content is a function of it)."""
    from dfwb.build_fmus.recorded import recorded_hash

    return recorded_hash(path) or file_digest(path)


def finite(document):
    """JSON-safe: infinities and NaN become None."""
    if isinstance(document, float):
        return document if math.isfinite(document) else None
    if isinstance(document, dict):
        return {k: finite(v) for k, v in document.items()}
    if isinstance(document, (list, tuple)):
        return [finite(v) for v in document]
    return document


def canonical(document):
    """The one JSON text of a document (sorted keys, floats as repr: they round-trip)."""
    return json.dumps(document, sort_keys=True, separators=(",", ":"), allow_nan=False)


def digest(document):
    return hashlib.sha256(canonical(document).encode()).hexdigest()


class Cache:
    """Entries under ``directory/v<FORMAT>/<2 hex>/<sha256>.json``; counts hits, misses and rejects.

    A lookup is one ``open`` on a plain string path (a miss costs little more: a run from an empty cache
    looks up every point, a scene that records N only twice). Within :meth:`writing`, an entry put is held
    in memory until the background thread has written it, and read from there meanwhile: a lookup never
    waits for the file system."""

    def __init__(self, directory=None):
        self.root = Path(directory) if directory is not None else default_dir()
        self.dir = self.root / f"v{FORMAT}"
        self.hits = self.misses = self.rejected = self.failed = 0
        self._writer = None  # within writing(): the thread that writes the entries
        self._pending = {}  # within writing(): {name: entry bytes} put and not written yet
        self._futures = []  # within writing(): of the writes, each giving the OSError that stopped it, or None
        self._folders = set()  # the entries' folders this cache made or found (made once per process)
        self._lock = threading.Lock()  # between put() and the writer's forgetting what it wrote

    def _path(self, name):
        return f"{self.dir}/{name[:2]}/{name}.json"

    def get(self, key):
        """The value stored under ``key``, or None (missing, corrupt or not this version's)."""
        text = canonical(key)
        name = hashlib.sha256(text.encode()).hexdigest()
        data = self._pending.get(name)
        try:
            if data is None:
                data = _read_entry(self._path(name))
            head, _, body = data.partition(b"\n")
            entry = json.loads(head)
            valid = (isinstance(entry, dict) and entry.get("format") == FORMAT
                     and entry.get("key") == text and entry.get("sha256") == hashlib.sha256(body).hexdigest())
            value = json.loads(body) if valid else None
        except FileNotFoundError:
            self.misses += 1
            return None
        except (OSError, ValueError, TypeError, RecursionError):
            valid = False
        if not valid:
            self.rejected += 1
            return None
        self.hits += 1
        return value

    def put(self, key, value):
        """Store ``value`` (JSON-able, finite floats) under ``key``, atomically; never raises.

        The file is one header line (format, the key's canonical text, the SHA-256 of the value's text)
        and the value's text: a reader checks all three without serialising anything again. A cache that
        cannot be written (read-only, full, a folder where an entry belongs) costs a warning, not a result.
        Within :meth:`writing`, the file is written by a background thread."""
        text, body = canonical(key), canonical(value).encode()
        head = json.dumps({"format": FORMAT, "key": text, "sha256": hashlib.sha256(body).hexdigest()})
        name, data = hashlib.sha256(text.encode()).hexdigest(), head.encode() + b"\n" + body
        if self._writer is None:
            self._warn(self._write(name, data))
        else:
            with self._lock:
                self._pending[name] = data
            self._futures.append(self._writer.submit(self._write_pending, name, data))

    @contextlib.contextmanager
    def writing(self):
        """Within: entries are written by one background thread, so that computing goes on while the file
        system creates their files (slow on some); every entry is written when it ends, and a failure
        warns then."""
        if self._writer is not None:  # already within
            yield self
            return
        from concurrent.futures import ThreadPoolExecutor

        self._writer = ThreadPoolExecutor(1, thread_name_prefix="dfwb-cache")
        try:
            yield self
        finally:
            writer, self._writer = self._writer, None
            writer.shutdown(wait=True)
            futures, self._futures, self._pending = self._futures, [], {}
            for future in futures:
                self._warn(future.result())

    def _write_pending(self, name, data):
        """Write a pending entry, then forget it (unless put again meanwhile: that one is written next)."""
        error = self._write(name, data)
        with self._lock:
            if self._pending.get(name) is data:
                del self._pending[name]
        return error

    def _write(self, name, data):
        """Write one entry; the OSError that stopped it, or None. Its folder is made (a link in its place
        replaced) the first time, and again if it has gone since."""
        folder = f"{self.dir}/{name[:2]}"
        try:
            for attempt in range(2):
                if folder not in self._folders:
                    ensure_folder(folder)
                    self._folders.add(folder)
                try:
                    write_atomic(Path(folder, f"{name}.json"), data)
                    break
                except FileNotFoundError:
                    self._folders.discard(folder)  # removed meanwhile: made again, once
                    if attempt:
                        raise
        except OSError as error:
            return error
        return None

    def _warn(self, error):
        if error is not None:
            self.failed += 1
            if self.failed == 1:
                warnings.warn(f"the cache {self.root} cannot be written ({error.filename}: "
                              f"{error.strerror or error}); results are kept, not cached", CacheWarning,
                              stacklevel=3)


def _read_entry(path):
    """The bytes of the entry file ``path`` (a string): a regular file of at most MAX_ENTRY bytes, read in one
    call (its size from fstat), never a device or a FIFO (opened non-blocking) nor more than it claims."""
    descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    try:
        status = os.fstat(descriptor)
        if not stat.S_ISREG(status.st_mode):
            raise OSError(errno.EINVAL, "not a regular file (a cache entry is a file)", path)
        if status.st_size > MAX_ENTRY:
            raise OSError(errno.EFBIG, f"larger than {MAX_ENTRY} bytes (too large for a cache entry)", path)
        data = os.read(descriptor, status.st_size + 1)
        while len(data) < status.st_size:  # a short read (not on a local disk): the rest of what it claims
            more = os.read(descriptor, status.st_size - len(data))
            if not more:
                break
            data += more
    finally:
        os.close(descriptor)
    return data  # at most MAX_ENTRY + 1 bytes: one more than it claimed is a changed file, which fails its checks


class CacheWarning(UserWarning):
    """The cache could not store an entry: the run goes on without it."""


class NoCache:
    """``--no-cache``: remembers nothing, finds nothing."""

    root = None
    hits = misses = rejected = failed = 0

    def get(self, key):
        self.misses += 1
        return None

    def put(self, key, value):
        pass

    def writing(self):
        return contextlib.nullcontext(self)


def open_cache(cache):
    """``cache``: True (the user's cache directory), a path, or False/None (off)."""
    if not cache:
        return NoCache()
    if isinstance(cache, (Cache, NoCache)):
        return cache
    if cache is not True and not isinstance(cache, (str, os.PathLike)):
        raise InputError(f"cache = {cache!r:.60}: give True, False or a folder")
    store = Cache() if cache is True else Cache(cache)
    if store.root.exists() and not store.root.is_dir():
        if cache is not True:  # the user named it: a mistake to say at once
            raise RunError(f"--cache {store.root} is a file, not a folder")
        warnings.warn(f"the cache {store.root} is a file, not a folder: results are not cached", CacheWarning)
        return NoCache()
    return store
