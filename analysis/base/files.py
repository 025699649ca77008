"""Files that are never seen half-written, never written through a link, never outside their folder.

Every output and cache entry of dfwb is written to a fresh temporary name in
the same folder and renamed over the target, so a reader (or a run after a
kill) finds either the old file or the complete new one. A rename replaces a
symbolic link instead of following it, and the temporary file is created
exclusively: a link planted in an output folder never redirects a write.
Names that come from data (a cache entry, a run log, a manifest) pass
:func:`inside` before they become paths. Every error names its file.

Examples
--------
>>> import tempfile
>>> folder = Path(tempfile.mkdtemp())
>>> write_atomic(folder / "a.txt", "text")
>>> inside(folder, "a.txt") == folder / "a.txt"
True
>>> try:
...     inside(folder, "../outside.txt")
... except UnsafePath as error:
...     print(error)
'../outside.txt' is not a file name inside the folder
"""

import contextlib
import errno
import fcntl
import hashlib
import os
import re
import stat
import tempfile
from pathlib import Path

from dfwb.base.errors import DfwbError


def user_cache_dir():
    """The user's cache folder for dfwb: ``$XDG_CACHE_HOME/dfwb``, else ``~/.cache/dfwb``."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "dfwb"


CHUNK = 1 << 20  # files are hashed and read in pieces of this size, never whole


class UnsafePath(DfwbError, ValueError):
    """A name from data that would lead outside its folder (or is no plain name)."""


class FolderBusy(DfwbError, RuntimeError):
    """Another dfwb run is writing into the same folder."""


@contextlib.contextmanager
def named(path):
    """Give an OSError raised inside the block the file name it lacks (``write``/``fsync`` have none)."""
    try:
        yield
    except OSError as error:
        if error.filename is None:
            raise OSError(error.errno, error.strerror or str(error), str(path)) from None
        raise


_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.+-]*$")


def inside(folder, name):
    """``folder / name`` for a relative name of plain parts (no ``..``, no absolute path, no link on the way).

    Raises :class:`UnsafePath` otherwise: the caller treats the data that named it as damaged.
    """
    parts = str(name).split("/")
    if not all(_NAME.match(part) and part not in (".", "..") and len(part) <= 255 for part in parts):
        raise UnsafePath(f"{name!r} is not a file name inside the folder")
    folder = Path(folder)
    path = folder.joinpath(*parts)
    for parent in list(path.parents)[: len(parts) - 1]:
        if parent.is_symlink():
            raise UnsafePath(f"{name!r} leads through the link {parent}")
    return path


def _unlink_link(path):
    """A symbolic link where dfwb keeps a file or folder is not ours: it is removed, never followed."""
    if path.is_symlink():
        path.unlink()


def ensure_folder(path):
    """Create a folder (and parents); a link in its place is replaced by a real folder."""
    path = Path(path)
    with named(path):
        _unlink_link(path)
        path.mkdir(parents=True, exist_ok=True)
    return path


def write_atomic(path, content):
    """Write text or bytes so that ``path`` is either the old file or the complete new one."""
    path = Path(path)
    data = content if isinstance(content, bytes) else content.encode()
    with named(path):
        partial = None
        try:
            handle, partial = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".partial")
            with os.fdopen(handle, "wb") as stream:
                stream.write(data)
            os.chmod(partial, 0o644 & ~UMASK)
            os.replace(partial, path)
        except BaseException:
            if partial is not None:
                with contextlib.suppress(OSError):
                    os.unlink(partial)
            raise


def _umask():
    """The process's umask (reading it sets it for a moment: done once, at import, before any thread)."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


UMASK = _umask()


def open_append(path):
    """Open a log for appending in text mode; a symbolic link in its place is removed first."""
    path = Path(path)
    with named(path):
        _unlink_link(path)
        descriptor = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW, 0o644)
        return os.fdopen(descriptor, "a", newline="")


def read_bytes(path, limit, what="file", follow=True):
    """The bytes of a regular file of at most ``limit`` bytes (a device or a huge file is never read whole);
    ``follow=False``: a symbolic link is refused (ELOOP)."""
    path = Path(path)
    flags = os.O_RDONLY | os.O_NONBLOCK | (0 if follow else os.O_NOFOLLOW)  # a FIFO never blocks
    with named(path), os.fdopen(os.open(path, flags), "rb") as stream:
        if not stat.S_ISREG(os.fstat(stream.fileno()).st_mode):
            raise OSError(errno.EINVAL, f"not a regular file (a {what} is a file)", str(path))
        data = stream.read(limit + 1)
    if len(data) > limit:
        raise OSError(errno.EFBIG, f"larger than {limit} bytes (too large for a {what})", str(path))
    return data


def file_digest(path):
    """SHA-256 of a file's bytes, in hex, read in pieces (a huge file never fills the memory)."""
    digest = hashlib.sha256()
    with named(path), open(path, "rb") as stream:
        for block in iter(lambda: stream.read(CHUNK), b""):
            digest.update(block)
    return digest.hexdigest()


LOCK_ATTEMPTS = 100  # a lock file replaced between our open and our lock this many times in a row: busy


@contextlib.contextmanager
def folder_lock(folder):
    """Hold an exclusive lock on ``folder`` for one run; a second run into it is refused, not interleaved.

    The lock is ``folder/.dfwb.lock``, removed when the run ends (no stale file is left). Removing it is safe
    because a run that locked a file checks that the path still names that file, else it tries again.
    """
    folder = ensure_folder(folder)
    path = folder / ".dfwb.lock"
    for _attempt in range(LOCK_ATTEMPTS):
        with named(path):
            _unlink_link(path)
            descriptor = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(descriptor)
            raise FolderBusy(f"{folder} is in use by another dfwb run: wait for it or choose another folder") \
                from None
        mine = os.fstat(descriptor)
        try:
            current = os.stat(path, follow_symlinks=False)
        except FileNotFoundError:
            current = None
        if current is not None and (current.st_dev, current.st_ino) == (mine.st_dev, mine.st_ino):
            break
        os.close(descriptor)  # the run before us removed it between our open and our lock: again
    else:
        raise FolderBusy(f"{folder}: its lock file keeps being replaced: another dfwb run? choose another folder")
    try:
        yield folder
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)  # still locked: a run waiting on this file will see it gone and try again
        os.close(descriptor)
