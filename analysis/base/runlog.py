"""The run log: ``results.csv`` of a sweep or a scene, appended point by point, read back verified.

Every computed point is appended at once and flushed, so a killed run (even
``kill -9``) loses only the points in flight; the log is synced to the disk at
most every :data:`SYNC_SECONDS` and when it is closed, so a power cut loses at
most that much more (a sync per point cost more than the points: 4 ms each here). Every row carries a checksum of its
other fields, so the next run resumes a row only as it was written: a row
edited by hand, cut short by a kill or written by another program is
recomputed, never trusted. A file whose header is not this log's (a user's
table, an older format) or that holds more rows than the run can have is
set aside as ``results.csv.unrecognised``. A symbolic link in the log's place
is removed, never read or written through.

Examples
--------
>>> import tempfile
>>> log = RunLog(Path(tempfile.mkdtemp()) / "results.csv", ["F", "N"], max_rows=10)
>>> with log:
...     log.append([{"F": "1.0", "N": "0.5"}, {"F": "2.0", "N": "0.25"}])
>>> [row["N"] for row in log.read()]
['0.5', '0.25']
>>> text = log.path.read_text().replace("0.25", "0.26")  # an edit by hand
>>> _ = log.path.write_text(text)
>>> [row["N"] for row in log.read()], log.rejected
(['0.5'], 1)
"""

import csv
import hashlib
import io
import os
import time
from pathlib import Path

from dfwb.base.files import CHUNK, named, open_append

CHECKSUM = "checksum"
SYNC_SECONDS = 1.0  # the most time between an appended row and its sync to the disk (if the run goes on)


def checksum(row, columns):
    """SHA-256 (first 32 hex digits) of a row's fields other than the checksum, in column order."""
    text = "\x1f".join(str(row.get(name, "")) for name in columns if name != CHECKSUM)
    return hashlib.sha256(text.encode()).hexdigest()[:32]


class RunLog:
    """``path``: the CSV; ``columns``: its fields (a checksum column is added); ``max_rows``: more is foreign.

    Use as a context manager to append; :meth:`read` returns the verified rows of an earlier run.
    """

    def __init__(self, path, columns, max_rows):
        self.path = Path(path)
        self.columns = list(columns) + [CHECKSUM]
        self.max_rows = max_rows
        self.rejected = 0  # rows whose checksum or shape did not match
        self._stream = self._writer = None
        self._synced = 0.0  # time.monotonic() of the last sync

    # -- reading ------------------------------------------------------------------------------------
    def read(self):
        """The verified rows ({column: text}) an earlier run left; [] when there is no such log."""
        path = self.path
        if path.is_symlink():
            path.unlink()
            return []
        if not path.exists():
            return []
        self._drop_partial_line()
        rows = []
        try:
            with named(path), open(path, newline="") as stream:
                reader = csv.reader(stream)
                if next(reader, None) != self.columns:
                    return self._set_aside()
                for fields in reader:
                    if len(rows) >= self.max_rows:
                        return self._set_aside()
                    row = dict(zip(self.columns, fields))
                    if len(fields) != len(self.columns) or row[CHECKSUM] != checksum(row, self.columns):
                        self.rejected += 1
                        continue
                    rows.append(row)
        except (csv.Error, UnicodeDecodeError):  # a field beyond csv's size limit, bytes that are not text
            return self._set_aside()
        return rows

    def _set_aside(self):
        self.path.replace(self.path.with_name(self.path.name + ".unrecognised"))
        return []

    def _drop_partial_line(self):
        """Cut a last line left without its newline by a kill (searched backwards in pieces)."""
        with named(self.path), open(self.path, "rb+") as stream:
            end = stream.seek(0, os.SEEK_END)
            if end == 0:
                return
            stream.seek(end - 1)
            if stream.read(1) == b"\n":
                return
            while end > 0:
                start = max(0, end - CHUNK)
                stream.seek(start)
                newline = stream.read(end - start).rfind(b"\n")
                if newline >= 0:
                    stream.truncate(start + newline + 1)
                    return
                end = start
            stream.truncate(0)

    # -- writing ------------------------------------------------------------------------------------
    def __enter__(self):
        self._stream = open_append(self.path)
        self._writer = csv.DictWriter(self._stream, fieldnames=self.columns, lineterminator="\n")
        if self._stream.tell() == 0:
            with named(self.path):
                self._writer.writeheader()
        self._synced = time.monotonic()
        return self

    def __exit__(self, *exc):
        stream, self._stream, self._writer = self._stream, None, None
        with named(self.path), stream:
            stream.flush()
            os.fsync(stream.fileno())

    def append(self, rows):
        """Append rows ({column: text}, no checksum) and flush them (the file has them, a kill loses none);
        sync them to the disk if the last sync is :data:`SYNC_SECONDS` old."""
        with named(self.path):
            for row in rows:
                self._writer.writerow(self.signed(row))
            self._stream.flush()
            if time.monotonic() - self._synced >= SYNC_SECONDS:
                os.fsync(self._stream.fileno())
                self._synced = time.monotonic()

    def signed(self, row):
        """The row with its checksum."""
        row = {name: row.get(name, "") for name in self.columns[:-1]}
        row[CHECKSUM] = checksum(row, self.columns)
        return row

    def text(self, rows):
        """The whole log of ``rows`` as CSV text (for an atomic rewrite at the end of a run)."""
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, fieldnames=self.columns, lineterminator="\n")
        writer.writeheader()
        writer.writerows(self.signed(row) for row in rows)
        return buffer.getvalue()
