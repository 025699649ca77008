"""Files that are never seen half-written, and their content hashes.

Every output and cache entry of dfwb is written to a temporary name in the
same folder and renamed over the target, so a reader (or a run after a kill)
finds either the old file or the complete new one.
"""

import hashlib
import os
from pathlib import Path


def write_atomic(path, content):
    """Write text or bytes so that ``path`` is either the old file or the complete new one."""
    path = Path(path)
    partial = path.with_name(f".{path.name}.{os.getpid()}.partial")
    if isinstance(content, bytes):
        partial.write_bytes(content)
    else:
        partial.write_text(content)
    partial.replace(path)


def file_digest(path):
    """SHA-256 of a file's bytes, in hex."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()
