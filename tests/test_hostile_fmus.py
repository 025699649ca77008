"""Hostile FMU files (issue 31's attack): each built here, each refused with exit 2 and one line, quickly.

A zip bomb of bzip2 (2 GiB of zeros in 13 kB, built in a tenth of a second
from one compressed block repeated) whose central directory lies about its
compressed size; a deflated entry that claims more compressed bytes than the
file has; a second ``./modelDescription.xml`` beside the clean one; a
modelIdentifier that leads out of the FMU; an unknown encoding; absurd
counts of event indicators; two variables of one name; a name that forges a
line; a parameter whose min exceeds its max. And no litter: an FMU's
extraction folder is gone when the run ends, after Ctrl-C and SIGTERM too.
"""

import bz2
import os
import re
import signal
import struct
import subprocess
import sys
import time
import zipfile
import zlib

import pytest

import dfwb
from dfwb.base.errors import PlantError
from dfwb.fmi.location import fmu_path

DFWB = [sys.executable, "-m", "dfwb.cli"]
VARIABLES = ('<ScalarVariable name="u" valueReference="0" causality="input" variability="continuous">'
             '<Real start="0"/></ScalarVariable>'
             '<ScalarVariable name="y" valueReference="1" causality="output"><Real unit="m"/></ScalarVariable>'
             '<ScalarVariable name="k" valueReference="2" causality="parameter" variability="fixed">'
             '<Real start="1" min="0" max="10"/></ScalarVariable>')


def _description(variables=VARIABLES, identifier="m", declaration='<?xml version="1.0" encoding="UTF-8"?>',
                 attributes=""):
    return (f'{declaration}<fmiModelDescription fmiVersion="2.0" modelName="m" guid="g"{attributes}>'
            f'<CoSimulation modelIdentifier="{identifier}"/><ModelVariables>{variables}</ModelVariables>'
            f'<ModelStructure><Outputs><Unknown index="2"/></Outputs></ModelStructure></fmiModelDescription>')


def _fmu(path, description=None, **extra):
    """An FMU that ``dfwb info`` accepts (its binary is never loaded: a placeholder), with ``extra`` entries."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("modelDescription.xml", description or _description())
        archive.writestr("binaries/linux64/m.so", b"\x7fELF placeholder")
        for name, data in extra.items():
            archive.writestr(name.replace("__", "/"), data)
    return path


def _raw_zip(path, entries):
    """A zip archive written byte by byte: entries of (name, method, compressed bytes, crc, size, claimed
    compressed size), so that a header can lie as an attacker's does."""
    body, directory = b"", b""
    for name, method, data, crc, size, claimed in entries:
        head = struct.pack("<HHHHHIIIHH", 46, 0, method, 0, 0x21, crc, claimed, size, len(name), 0)
        directory += (b"PK\x01\x02" + struct.pack("<H", 46) + head + struct.pack("<HHHII", 0, 0, 0, 0, len(body))
                      + name.encode())
        body += b"PK\x03\x04" + head + name.encode() + data
    path.write_bytes(body + directory + struct.pack("<4sHHHHIIH", b"PK\x05\x06", 0, 0, len(entries),
                                                    len(entries), len(directory), len(body), 0))
    return path


def _zeros_bz2(size):
    """A bzip2 stream of ``size`` zero bytes, made in milliseconds: one compressed block of zeros repeated
    (the stream's combined CRC recomputed), and a last block for the rest."""
    block, end = f"{0x314159265359:048b}", f"{0x177245385090:048b}"  # the block and end-of-stream magics

    def bits(data):  # a bzip2 stream after its 4-byte header, as a string of bits
        return f"{int.from_bytes(data, 'big'):0{8 * len(data)}b}"[32:]

    def stream(blocks):
        combined = 0
        for b in blocks:
            combined = ((combined << 1 | combined >> 31) & 0xFFFFFFFF) ^ int(b[48:80], 2)
        text = "".join(blocks) + end + f"{combined:032b}"
        text += "0" * (-len(text) % 8)
        return b"BZh1" + int(text, 2).to_bytes(len(text) // 8, "big")

    both = bits(bz2.compress(bytes(6 << 20), 1))  # at level 1 a block holds ~5 MB of zeros: one full, one partial
    starts = [i for i in range(len(both) - 47) if both.startswith(block, i)]
    full = both[starts[0]:starts[1]]
    count, rest = divmod(size, len(bz2.decompress(stream([full]))))
    return stream([full] * count + ([bits(bz2.compress(bytes(rest), 1)).rsplit(end, 1)[0]] if rest else []))


# Runs a command from a small Python and writes its peak memory (kB) to argv[1]. Linux carries a process's peak
# across fork and exec, so a command started straight from the test process (a pytest-xdist worker of a few
# hundred MB) would report the test's peak, not its own.
_PEAK = ("import os, sys\n"
         "pid = os.fork()\n"
         "if pid == 0:\n"
         "    os.execvp(sys.argv[2], sys.argv[2:])\n"
         "_, status, usage = os.wait4(pid, 0)\n"
         "open(sys.argv[1], 'w').write(str(usage.ru_maxrss))\n"
         "sys.exit(os.waitstatus_to_exitcode(status) % 256)\n")


def _run(argv, tmp_path, timeout=60):
    """(exit code, stdout, stderr, seconds, peak memory in MB) of ``dfwb argv``, its temporary folder in
    ``tmp_path/tmp`` (which must be empty afterwards: nothing unpacked is left behind)."""
    temporary = tmp_path / "tmp"
    temporary.mkdir(exist_ok=True)
    peak = tmp_path / "peak.txt"
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", _PEAK, str(peak), *DFWB, *argv], capture_output=True, text=True,
                          cwd=tmp_path, env=dict(os.environ, TMPDIR=str(temporary)), timeout=timeout)
    result = (done.returncode, done.stdout, done.stderr, time.perf_counter() - started,
              int(peak.read_text()) / 1024)
    assert list(temporary.iterdir()) == []
    return result


def _refused(argv, tmp_path, reason):
    """Exit 2 with one line on stderr naming the reason, nothing on stdout."""
    code, out, err, seconds, _ = _run(argv, tmp_path)
    assert code == 2 and out == "" and err.count("\n") == 1, (code, out, err)
    assert re.search(reason, err), err
    return seconds


# -- 1. bombs: refused before a byte is extracted ----------------------------------------------------------------------
def test_a_bzip2_bomb_with_a_lying_header_is_refused_at_once(tmp_path):
    """2 GiB of zeros, the central directory claiming size / 999 + 1 compressed bytes (ratio 999 < 1000)."""
    size, crc = 2 << 30, 0x4DBDF21C  # (zlib.crc32 of 2 GiB of zeros: 2 s to compute)
    data = _zeros_bz2(size)
    assert len(data) < 20_000
    described = _description().encode()
    path = _raw_zip(tmp_path / "bomb.fmu", [
        ("modelDescription.xml", 0, described, zlib.crc32(described), len(described), len(described)),
        ("binaries/linux64/m.so", 0, b"x", zlib.crc32(b"x"), 1, 1),
        ("resources/zeros.bin", zipfile.ZIP_BZIP2, data, crc, size, size // 999 + 1)])
    assert path.stat().st_size < 20_000
    code, out, err, seconds, megabytes = _run(["info", str(path)], tmp_path)
    assert code == 2 and out == "" and err.count("\n") == 1, (code, err)
    assert f"{path}: not accepted: the entry 'resources/zeros.bin' is compressed by bzip2 (an FMU's entries " \
           "are stored or deflated)" in err
    assert seconds < 15 and megabytes < 400, (seconds, megabytes)


def test_compressed_sizes_that_add_up_to_more_than_the_file_are_refused(tmp_path):
    """A deflated entry of 30 MB of zeros whose header claims size / 999 + 1 compressed bytes (the ratio
    passes; the file does not hold them): the same lie as the bomb's, in the method the standard allows."""
    size = 30 << 20
    packer = zlib.compressobj(9, zlib.DEFLATED, -15)
    data = packer.compress(bytes(size)) + packer.flush()
    described = _description().encode()
    path = _raw_zip(tmp_path / "liar.fmu", [
        ("modelDescription.xml", 0, described, zlib.crc32(described), len(described), len(described)),
        ("resources/zeros.bin", zipfile.ZIP_DEFLATED, data, zlib.crc32(bytes(size)), size, size // 999 + 1)])
    with pytest.raises(PlantError, match=rf"its entries claim {size // 999 + 1 + len(described)} compressed bytes "
                                         rf"in a file of {path.stat().st_size} \(a zip bomb\?\)"):
        dfwb.fmu_plant(path)


# -- 2. entries that unpack to one file ---------------------------------------------------------------------------------
@pytest.mark.parametrize("second, reason", [
    ("./modelDescription.xml", "the entries 'modelDescription.xml' and './modelDescription.xml' unpack to one file"),
    ("binaries\\linux64\\m.so", r"the entries 'binaries/linux64/m.so' and 'binaries\\\\linux64\\\\m.so' unpack to "
                                "one file"),
    ("binaries/linux64/m.so/x", "the entry 'binaries/linux64/m.so' is a file and also a folder of other entries"),
])
def test_entries_that_unpack_to_one_path_are_refused(tmp_path, second, reason):
    path = tmp_path / "twice.fmu"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("modelDescription.xml", _description())
        archive.writestr("binaries/linux64/m.so", b"x")
        archive.writestr(second, _description(VARIABLES * 3))  # another description, written over the clean one
    with pytest.raises(PlantError, match=re.escape(f"{path}: not accepted: ") + reason):
        dfwb.fmu_plant(path)


def test_a_second_description_is_one_line_on_the_command_line(tmp_path):
    path = _fmu(tmp_path / "twice.fmu", **{"./modelDescription.xml": _description(VARIABLES * 3)})
    assert _refused(["info", str(path)], tmp_path, "unpack to one file") < 15


# -- 3. a binary from outside the FMU ----------------------------------------------------------------------------------
@pytest.mark.parametrize("identifier", ["../../../../tmp/x/Outside", "{outside}", "a\\b", "..", ""])
def test_a_model_identifier_that_is_not_a_plain_file_name_is_refused(tmp_path, identifier):
    (tmp_path / "Outside.so").write_bytes(b"\x7fELF a library outside the FMU")
    identifier = identifier.format(outside=tmp_path / "Outside")
    path = _fmu(tmp_path / "outside.fmu", _description(identifier=identifier))
    with pytest.raises(PlantError, match=re.escape(f"{path}: the modelIdentifier {identifier!r} of its co-simulation "
                                                   "interface is not accepted: a plain file name")):
        dfwb.fmu_plant(path)


def test_a_model_identifier_out_of_the_fmu_is_refused_on_the_command_line(tmp_path):
    (tmp_path / "Outside.so").write_bytes(b"\x7fELF a library outside the FMU")
    path = _fmu(tmp_path / "outside.fmu", _description(identifier=tmp_path / "Outside"))
    _refused(["df", str(path), "--input", "u", "--output", "y", "--F", "1", "--omega", "1"], tmp_path,
             "is not accepted: a plain file name")


# -- 4 to 8. what the description says ---------------------------------------------------------------------------------
def test_an_unknown_encoding_is_one_line(tmp_path):
    path = _fmu(tmp_path / "bogus.fmu", _description(declaration='<?xml version="1.0" encoding="x-bogus"?>'))
    _refused(["info", str(path)], tmp_path, re.escape(f"{path}: modelDescription.xml is not accepted: its encoding "
                                                      "'x-bogus' (a model description is UTF-8)"))


@pytest.mark.parametrize("count", ["100000000", "4000000000", "-5", "100001"])
def test_an_absurd_number_of_event_indicators_is_refused(tmp_path, count):
    path = _fmu(tmp_path / "events.fmu", _description(attributes=f' numberOfEventIndicators="{count}"'))
    with pytest.raises(PlantError, match=re.escape(f"{path}: numberOfEventIndicators = {count} is not accepted "
                                                   "(0 to 100000)")):
        dfwb.fmu_plant(path)


def test_a_sane_number_of_event_indicators_is_kept(tmp_path):
    path = _fmu(tmp_path / "events.fmu", _description(attributes=' numberOfEventIndicators="100000"'))
    assert dfwb.fmu_plant(path).info.event_indicators == 100_000


def test_two_variables_of_one_name_are_refused(tmp_path):
    again = '<ScalarVariable name="k" valueReference="3" causality="parameter" variability="fixed"><Real start="2"/>' \
            '</ScalarVariable>'
    path = _fmu(tmp_path / "twice.fmu", _description(VARIABLES + again))
    with pytest.raises(PlantError, match=re.escape(f"{path}: two variables are named 'k' (a variable's name is "
                                                   "unique in an FMU)")):
        dfwb.fmu_plant(path)


@pytest.mark.parametrize("name, shown", [("k&#10;  forged: line", r"'k\n  forged: line'"),
                                         ("k&#13;", r"'k\r'"), ("k&#x202E;", r"'k\u202e'"),
                                         ("k&#x2028;", r"'k\u2028'"), ("k&#9;", r"'k\t'")])
def test_a_name_with_a_control_character_is_refused(tmp_path, name, shown):
    path = _fmu(tmp_path / "forged.fmu", _description(VARIABLES.replace('name="k"', f'name="{name}"')))
    with pytest.raises(PlantError, match=re.escape(f"{path}: the variable name {shown} is not accepted: a name is "
                                                   "printable text")):
        dfwb.fmu_plant(path)


def test_a_forged_line_never_reaches_info(tmp_path):
    path = _fmu(tmp_path / "forged.fmu", _description(VARIABLES.replace('name="k"', 'name="k&#10;forged"')
                                                      .replace('unit="m"', 'unit="m&#10;x"')))
    _refused(["info", str(path)], tmp_path, r"the variable name 'k\\nforged' is not accepted")
    path = _fmu(tmp_path / "unit.fmu", _description(VARIABLES.replace('unit="m"', 'unit="m&#10;x"')))
    _refused(["info", str(path)], tmp_path, r"the unit of 'y' 'm\\nx' is not accepted")


def test_a_parameter_with_min_above_max_is_refused_when_described(tmp_path):
    path = _fmu(tmp_path / "range.fmu", _description(VARIABLES.replace('min="0" max="10"', 'min="2" max="1"')))
    with pytest.raises(PlantError, match=re.escape(f"{path}: the variable 'k' is declared with min = 2 > max = 1 "
                                                   "(no value is allowed)")):
        dfwb.fmu_plant(path)


def test_a_clean_fmu_is_described_and_its_folder_holds_what_was_checked(tmp_path):
    path = _fmu(tmp_path / "clean.fmu", **{"resources__table.txt": "1 2 3", "documentation__": b""})
    info = dfwb.fmu_plant(path).info
    assert info.identifiers == {"co-simulation": "m"} and list(info.parameters) == ["k"]
    folder = __import__("pathlib").Path(info.folder)
    assert (folder / "modelDescription.xml").read_text() == _description()
    assert (folder / "resources" / "table.txt").read_text() == "1 2 3"
    code, out, err, _, _ = _run(["info", str(path)], tmp_path)
    assert code == 0 and out.startswith("m: FMI 2.0, co-simulation (runs here"), err


# -- 9. no litter ------------------------------------------------------------------------------------------------------
def _own_fmu():
    path = fmu_path(dfwb.plant("friction")).parent / "native" / "FrictionMass.fmu"
    return path if path.is_file() else fmu_path(dfwb.plant("friction"))


@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM])
def test_the_extraction_folder_is_removed_after_ctrl_c_and_sigterm(tmp_path, stop):
    """A DF of a user's FMU stopped once its folder is unpacked and its worker computes: the folder goes."""
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    process = subprocess.Popen(DFWB + ["df", str(_own_fmu()), "--input", "f", "--output", "x", "--omega", "1",
                                       "--F", *map(str, range(10, 40))],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
                               env=dict(os.environ, TMPDIR=str(temporary)), start_new_session=True)
    deadline = time.monotonic() + 60
    unpacked = []  # (Python's tempfile first probes the folder with a short-lived file of a random name)
    while not unpacked and time.monotonic() < deadline and process.poll() is None:
        unpacked = [p for p in temporary.iterdir() if p.name.startswith("dfwb_fmu_")]
        time.sleep(0.05)
    assert len(unpacked) == 1 and unpacked[0].is_dir(), list(temporary.iterdir())
    time.sleep(1.0)  # the worker process starts and computes
    (os.killpg if stop == signal.SIGINT else os.kill)(process.pid, stop)  # Ctrl-C reaches the whole group
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130 and err == "dfwb df: interrupted\n", err  # the worker says nothing
    assert list(temporary.iterdir()) == []


def test_no_folder_is_left_after_a_run_of_a_user_fmu_or_of_dfwb_own(tmp_path):
    code, out, err, _, _ = _run(["info", str(_own_fmu())], tmp_path)
    assert code == 0 and "FrictionMass" in out, err
    code, out, err, _, _ = _run(["df", "friction", "--F", "10", "--omega", "1"], tmp_path)  # fmpy unpacks it
    assert code == 0, err
