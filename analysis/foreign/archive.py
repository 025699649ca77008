"""Open a user's FMU file as hostile input: checked before a byte of it is unpacked or parsed.

An FMU is a zip archive, and a zip archive can lie: entries that leave their
folder (``../../x``, ``/etc/x``, a symlink), two entries that unpack to one
file (the checks read one, extraction writes the other), a decompressed size
thousands of times its own (a zip bomb), compressed sizes that add up to more
than the file (entries sharing one bomb, or a header that lies), a method
such as bzip2 that zipfile decompresses in one call however large the
output, a model description of megabytes, nested a thousand deep, declaring
entities that expand without end or an encoding Python does not know.
:func:`unpack` refuses each with one line naming the file and the reason
(:class:`~dfwb.base.errors.PlantError`, exit code 2 on the command line), and
otherwise extracts the archive, each entry streamed and cut at its declared
size, into a private temporary folder, removed when the process exits (a
Ctrl-C or SIGTERM of the command line ends it by an exit too), keyed by the
file's content so that an FMU changed on disk is read anew.
"""

import atexit
import io
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
# The FMI standard's compression methods: zipfile decompresses any other (bzip2, lzma) in one unbounded call.
METHODS = (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED)
DESCRIPTION = ("modelDescription.xml",)  # its path in the archive, as parts
_UNPACKED = {}  # content digest -> the folder it is unpacked in (this process)


def _refuse(path, reason):
    raise PlantError(f"{path}: {reason}")


def _parts(info):
    """An entry's path as the folder will hold it (``./a`` and ``a``, ``a\\b`` and ``a/b`` are one file)."""
    return PurePosixPath(info.filename.replace("\\", "/")).parts


def _entries(path, archive, size):
    """The archive's entries, each checked to stay inside its folder, to be the only one of its path, and to
    decompress to a sane size from compressed bytes that are in the file."""
    infos = archive.infolist()
    if len(infos) > MAX_ENTRIES:
        _refuse(path, f"not accepted: {len(infos)} entries in the archive (at most {MAX_ENTRIES})")
    total = claimed = 0
    files, folders = {}, set()  # parts -> the file's entry; the parts of every folder
    for info in infos:
        name, parts = info.filename, _parts(info)
        if name.startswith(("/", "\\")) or ".." in parts or (parts and ":" in parts[0]):
            _refuse(path, f"not accepted: the entry {name!r} leaves the FMU's folder")
        if stat.S_ISLNK(info.external_attr >> 16):
            _refuse(path, f"not accepted: the entry {name!r} is a symbolic link")
        if info.compress_type not in METHODS:
            method = zipfile.compressor_names.get(info.compress_type, f"method {info.compress_type}")
            _refuse(path, f"not accepted: the entry {name!r} is compressed by {method} (an FMU's entries are "
                          f"stored or deflated)")
        if info.file_size > MAX_RATIO * max(info.compress_size, 1024):
            _refuse(path, f"not accepted: the entry {name!r} decompresses to {info.file_size} bytes from "
                          f"{info.compress_size} (a zip bomb?)")
        if info.is_dir():
            folders.add(parts)
        elif not parts:
            _refuse(path, f"not accepted: the entry {name!r} names no file")
        elif parts in files:
            _refuse(path, f"not accepted: the entries {files[parts].filename!r} and {name!r} unpack to one file")
        else:
            files[parts] = info
        folders.update(parts[:end] for end in range(1, len(parts)))
        claimed += info.compress_size
        total += info.file_size
    for parts in folders.intersection(files):
        _refuse(path, f"not accepted: the entry {files[parts].filename!r} is a file and also a folder of other entries")
    if claimed > size:
        _refuse(path, f"not accepted: its entries claim {claimed} compressed bytes in a file of {size} (a zip bomb?)")
    if total > MAX_UNPACKED:
        _refuse(path, f"not accepted: {total} bytes decompressed (at most {MAX_UNPACKED})")
    return infos, files


def _copy(path, archive, info, sink):
    """Stream one entry into ``sink``, refused past its declared size whatever the decompressor makes of it."""
    left = info.file_size
    with archive.open(info) as source:
        while chunk := source.read(1 << 20):
            left -= len(chunk)
            if left < 0:
                _refuse(path, f"not accepted: the entry {info.filename!r} decompresses to more than the "
                              f"{info.file_size} bytes it declares")
            sink.write(chunk)


def _check_description(path, text):
    """Refuse a model description that is too large, too deep, declares entities or an encoding other than UTF-8
    (the standard's, and Python's lookup of an unknown one is no one-line error)."""
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

    def declaration(_version, encoding, _standalone):
        if encoding is not None and encoding.lower().replace("_", "-") not in ("utf-8", "utf8"):
            raise ValueError(f"its encoding {encoding!r} (a model description is UTF-8)")

    parser.StartElementHandler, parser.EndElementHandler = start, end
    parser.StartDoctypeDeclHandler = doctype
    parser.EntityDeclHandler = doctype
    parser.XmlDeclHandler = declaration
    try:
        parser.Parse(text, True)
    except (ValueError, xml.parsers.expat.ExpatError) as error:
        _refuse(path, f"modelDescription.xml is not accepted: {error}")


def unpack(path):
    """(folder, digest) of an FMU file, checked and extracted once per content in this process.

    Raises PlantError naming the file and the reason for anything that is not
    a sane FMU archive; the model description is checked here as bytes, and
    these very bytes are what the folder holds
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
            infos, files = _entries(path, archive, size)
            described = files.get(DESCRIPTION)
            if described is None:
                _refuse(path, "is not an FMU (no modelDescription.xml at the top of the archive)")
            if described.file_size > MAX_DESCRIPTION:
                _refuse(path, f"not accepted: modelDescription.xml has {described.file_size} bytes "
                              f"(at most {MAX_DESCRIPTION})")
            text = io.BytesIO()
            _copy(path, archive, described, text)
            _check_description(path, text.getvalue())
            folder = Path(tempfile.mkdtemp(prefix="dfwb_fmu_"))
            atexit.register(shutil.rmtree, folder, True)
            try:
                Path(folder, *DESCRIPTION).write_bytes(text.getvalue())  # the bytes checked are the bytes read
                for info in infos:
                    target = folder.joinpath(*_parts(info))
                    if info.is_dir():
                        target.mkdir(parents=True, exist_ok=True)
                    elif info is not described:
                        target.parent.mkdir(parents=True, exist_ok=True)
                        with open(target, "wb") as sink:
                            _copy(path, archive, info, sink)
            except BaseException:  # a refused entry or a Ctrl-C: nothing left behind
                shutil.rmtree(folder, True)
                raise
    except (zipfile.BadZipFile, zipfile.LargeZipFile, NotImplementedError, EOFError) as error:
        _refuse(path, f"is not a readable FMU archive ({error})")
    except OSError as error:
        _refuse(path, f"cannot be read ({error.strerror or error})")
    _UNPACKED[key] = folder
    return folder, key
