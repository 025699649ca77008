"""Open a user's FMU file as hostile input: checked before a byte of it is unpacked or parsed.

An FMU is a zip archive, and a zip archive can lie: entries that leave their
folder (``../../x``, ``/etc/x``, a symlink), a decompressed size thousands of
times its own (a zip bomb), a model description of megabytes or nested a
thousand deep, entity declarations that expand without end. :func:`unpack`
refuses each with one line naming the file and the reason
(:class:`~dfwb.base.errors.PlantError`, exit code 2 on the command line), and
otherwise extracts the archive into a private temporary folder, removed when
the process exits, keyed by the file's content so that an FMU changed on disk
is read anew.
"""

import atexit
import shutil
import stat
import tempfile
import xml.parsers.expat
import zipfile
from pathlib import Path, PurePosixPath

from dfwb.base.errors import PlantError
from dfwb.base.files import file_digest

__all__ = ["unpack", "MAX_UNPACKED", "MAX_RATIO", "MAX_DESCRIPTION", "MAX_DEPTH"]

MAX_FILE = 2 << 30  # bytes of the FMU file itself
MAX_UNPACKED = 4 << 30  # bytes of all its entries, decompressed
MAX_RATIO = 1000  # decompressed size over compressed size, per entry (a zip bomb is far above)
MAX_ENTRIES = 100_000
MAX_DESCRIPTION = 16 << 20  # bytes of modelDescription.xml (a large Modelica model has a few MB)
MAX_DEPTH = 32  # element nesting of modelDescription.xml (the schema needs 6)
_UNPACKED = {}  # content digest -> the folder it is unpacked in (this process)


def _refuse(path, reason):
    raise PlantError(f"{path}: {reason}")


def _entries(path, archive):
    """The archive's entries, each checked to stay inside its folder and to decompress to a sane size."""
    infos = archive.infolist()
    if len(infos) > MAX_ENTRIES:
        _refuse(path, f"not accepted: {len(infos)} entries in the archive (at most {MAX_ENTRIES})")
    total = 0
    for info in infos:
        name = info.filename
        parts = PurePosixPath(name.replace("\\", "/")).parts
        if name.startswith(("/", "\\")) or ".." in parts or (parts and ":" in parts[0]):
            _refuse(path, f"not accepted: the entry {name!r} leaves the FMU's folder")
        if stat.S_ISLNK(info.external_attr >> 16):
            _refuse(path, f"not accepted: the entry {name!r} is a symbolic link")
        if info.file_size > MAX_RATIO * max(info.compress_size, 1024):
            _refuse(path, f"not accepted: the entry {name!r} decompresses to {info.file_size} bytes from "
                          f"{info.compress_size} (a zip bomb?)")
        total += info.file_size
    if total > MAX_UNPACKED:
        _refuse(path, f"not accepted: {total} bytes decompressed (at most {MAX_UNPACKED})")
    return infos


def _check_description(path, text):
    """Refuse a model description that is too large, too deep, or declares entities (expat, streamed)."""
    if len(text) > MAX_DESCRIPTION:
        _refuse(path, f"not accepted: modelDescription.xml has {len(text)} bytes (at most {MAX_DESCRIPTION})")
    parser = xml.parsers.expat.ParserCreate()
    depth = [0, 0]  # now, deepest

    def start(_name, _attributes):
        depth[0] += 1
        depth[1] = max(depth)
        if depth[0] > MAX_DEPTH:
            raise ValueError(f"elements nested deeper than {MAX_DEPTH}")

    def end(_name):
        depth[0] -= 1

    def doctype(*_args):
        raise ValueError("a document type declaration (entities are not accepted)")

    parser.StartElementHandler, parser.EndElementHandler = start, end
    parser.StartDoctypeDeclHandler = doctype
    parser.EntityDeclHandler = doctype
    try:
        parser.Parse(text, True)
    except (ValueError, xml.parsers.expat.ExpatError) as error:
        _refuse(path, f"modelDescription.xml is not accepted: {error}")


def unpack(path):
    """(folder, digest) of an FMU file, checked and extracted once per content in this process.

    Raises PlantError naming the file and the reason for anything that is not
    a sane FMU archive; the model description is checked here as bytes
    (:func:`dfwb.foreign.description.describe` reads what it says).
    """
    path = Path(path)
    try:
        if not path.is_file():
            _refuse(path, "no such FMU file" if not path.exists() else "is not a file")
        size = path.stat().st_size
        if size > MAX_FILE:
            _refuse(path, f"not accepted: {size} bytes (at most {MAX_FILE})")
        key = file_digest(path)
        if key in _UNPACKED and _UNPACKED[key].is_dir():
            return _UNPACKED[key], key
        if not zipfile.is_zipfile(path):
            _refuse(path, "is not an FMU (not a zip archive)")
        with zipfile.ZipFile(path) as archive:
            infos = _entries(path, archive)
            names = {info.filename for info in infos}
            if "modelDescription.xml" not in names:
                _refuse(path, "is not an FMU (no modelDescription.xml at the top of the archive)")
            description = archive.getinfo("modelDescription.xml")
            if description.file_size > MAX_DESCRIPTION:
                _refuse(path, f"not accepted: modelDescription.xml has {description.file_size} bytes "
                              f"(at most {MAX_DESCRIPTION})")
            _check_description(path, archive.read("modelDescription.xml"))
            folder = Path(tempfile.mkdtemp(prefix="dfwb_fmu_"))
            atexit.register(shutil.rmtree, folder, True)
            for info in infos:
                target = folder.joinpath(*PurePosixPath(info.filename.replace("\\", "/")).parts)
                if info.is_dir():
                    target.mkdir(parents=True, exist_ok=True)
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                with archive.open(info) as source, open(target, "wb") as sink:
                    shutil.copyfileobj(source, sink, 1 << 20)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, EOFError) as error:
        _refuse(path, f"is not a readable FMU archive ({error})")
    except OSError as error:
        _refuse(path, f"cannot be read ({error.strerror or error})")
    _UNPACKED[key] = folder
    return folder, key
