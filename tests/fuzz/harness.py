"""Runs one ``dfwb`` command line in a sandboxed subprocess and judges how it ended (see tests/test_fuzz.py).

A case gets a fresh sandbox::

    <case>/box/work      the working folder (scene files are written here)
    <case>/box/work/out  the output folder: the only place the command may write, besides
    <case>/box/cache     XDG_CACHE_HOME (and --cache DIR), and
    <case>/box/tmp       TMPDIR (FMUs are unpacked there, once per process)
    <case>/box/home      HOME

Everything else in ``<case>`` is compared before and after the run, and so is the list of entries next
to ``<case>`` (the other cases' folders), so a write anywhere up to three levels above the working
folder is seen.
"""

import csv
import io
import json
import math
import os
import re
import resource
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from dfwb.engine.describing import COLUMNS

TIMEOUT = float(os.environ.get("DFWB_FUZZ_TIMEOUT", "60"))  # [s] wall clock; more is a hang
ADDRESS_SPACE = 4 << 30  # [bytes] RLIMIT_AS of each process (numpy, scipy, matplotlib, the FMUs load in 1 GiB)
FILE_SIZE = 1 << 30  # [bytes] RLIMIT_FSIZE: no file may grow beyond this
DISK = 256 << 20  # [bytes] at most this much left in the output, cache and temporary folders by one case
GRACE = 3.0  # [s] for processes of the case to go after the command ended
STDERR_TAIL = 1500  # characters of stderr shown in a failure
NUMERIC_COLUMNS = set(COLUMNS) - {"plant", "params", "drive", "periodic", "note"}  # a DF point's numeric CSV columns
NON_FINITE = re.compile(r"(?i)(?<![\w.])[-+]?(nan|inf|infinity)(?![\w.])")
PYTHON = sys.executable


def _limits(cpu_seconds):
    def apply():
        resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))
        resource.setrlimit(resource.RLIMIT_CPU, (int(cpu_seconds), int(cpu_seconds) + 5))
        resource.setrlimit(resource.RLIMIT_FSIZE, (FILE_SIZE, FILE_SIZE))
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))

    return apply


class Sandbox:
    """One case's folders (see the module docstring); removed on leaving unless the case failed."""

    def __init__(self, base, fmu_dir):
        self.base, self.fmu_dir = Path(base), Path(fmu_dir)
        self.root = Path(tempfile.mkdtemp(prefix="case-", dir=self.base))
        self.box = self.root / "box"
        self.work, self.cache, self.tmp, self.home = (self.box / name for name in ("work", "cache", "tmp", "home"))
        self.out = self.work / "out"
        for folder in (self.work, self.cache, self.tmp, self.home):
            folder.mkdir(parents=True)
        mpl = self.base / "matplotlib"  # shared: the font cache is built once, not in every case
        mpl.mkdir(exist_ok=True)
        self.env = {key: value for key, value in os.environ.items() if not key.startswith(("DFWB_", "MPL"))}
        self.env.update(HOME=str(self.home), XDG_CACHE_HOME=str(self.cache), TMPDIR=str(self.tmp),
                        MPLCONFIGDIR=str(mpl), MPLBACKEND="Agg", COLUMNS="120", PYTHONFAULTHANDLER="1")

    def __enter__(self):
        return self

    def __exit__(self, kind, value, traceback):
        if kind is None:
            shutil.rmtree(self.root, ignore_errors=True)

    def write_input(self, name, data):
        path = self.work / name
        path.write_bytes(data)
        return path

    @property
    def allowed(self):
        return (self.out, self.cache, self.tmp)

    def bytes_written(self):
        """Bytes in the output, cache and temporary folders (links not followed)."""
        total = 0
        for top in self.allowed:
            for folder, _dirs, files in os.walk(top):
                for name in files:
                    try:
                        total += os.lstat(os.path.join(folder, name)).st_size
                    except FileNotFoundError:
                        pass
        return total

    def snapshot(self):
        """(files and folders of the case outside the allowed folders, names next to the case)."""
        tree = {}
        for folder, dirs, files in os.walk(self.root):
            here = Path(folder)
            dirs[:] = [d for d in dirs if here / d not in self.allowed]
            for name in dirs + files:
                path = here / name
                if path in self.allowed:
                    continue
                try:
                    info = os.lstat(path)
                except FileNotFoundError:
                    continue
                kind = stat.S_IFMT(info.st_mode)
                tree[str(path.relative_to(self.root))] = (kind,) if kind == stat.S_IFDIR else \
                    (kind, info.st_size, info.st_mtime_ns)
        return tree, sorted(os.listdir(self.base))


@dataclass
class Result:
    argv: list
    command: str
    returncode: int = None
    stdout: str = ""
    stderr: str = ""
    seconds: float = 0.0
    timed_out: bool = False
    left_running: list = field(default_factory=list)
    changes: list = field(default_factory=list)
    written: int = 0
    out: Path = None
    timeout: float = TIMEOUT

    def explain(self, problem):
        shown = [word if len(word) <= 200 else f"{word[:60]}...<{len(word)} characters>...{word[-20:]}"
                 for word in self.argv]
        code = self.returncode
        if code is not None and code < 0:
            code = f"{code} (killed by {signal.Signals(-code).name})"
        tail = self.stderr[-STDERR_TAIL:]
        return (f"{problem}\n  argv: {shown!r}\n  exit code: {code}, {self.seconds:.1f} s\n"
                f"  stderr (tail):\n{tail}\n  stdout (tail): {self.stdout[-300:]!r}")


def _members(session):
    """Live processes (not zombies) of the session the case was started in."""
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            text = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        fields = text[text.rfind(")") + 2:].split()
        if fields[0] != "Z" and session in (int(fields[2]), int(fields[3])):  # pgrp, session
            found.append(int(entry))
    return found


def _kill(pids):
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def launch(box, cmdline, argv, command, timeout=None):
    """Run ``cmdline`` in the sandbox; the Result carries the exit and what changed outside the output."""
    timeout = TIMEOUT if timeout is None else timeout
    before = box.snapshot()
    result = Result(argv=list(argv), command=command, out=box.out, timeout=timeout)
    start = time.monotonic()
    process = subprocess.Popen(cmdline, cwd=box.work, env=box.env, stdin=subprocess.DEVNULL,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
                               preexec_fn=_limits(timeout + 10))
    try:
        stdout, stderr = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        ended = process.poll() is not None
        result.timed_out = True
        result.left_running = [] if not ended else _members(process.pid)
        _kill(_members(process.pid))
        try:
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        try:
            stdout, stderr = process.communicate(timeout=10)
        except subprocess.TimeoutExpired:  # a process outside the session holds the pipes
            stdout, stderr = b"", b"(no output: the pipes stayed open after the kill)"
        if ended:  # the command ended, but something it started kept its output open
            result.timed_out = False
    result.seconds = time.monotonic() - start
    result.returncode = process.returncode
    result.stdout = stdout.decode("utf-8", "replace")
    result.stderr = stderr.decode("utf-8", "replace")
    deadline = time.monotonic() + GRACE
    while not result.left_running and _members(process.pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    left = _members(process.pid)
    if left:
        result.left_running = result.left_running or left
        _kill(left)
    result.written = box.bytes_written()
    after = box.snapshot()
    tree_before, tree_after = before[0], after[0]
    result.changes = sorted(
        [f"created {p}" for p in tree_after.keys() - tree_before.keys()]
        + [f"removed {p}" for p in tree_before.keys() - tree_after.keys()]
        + [f"changed {p}" for p in tree_after.keys() & tree_before.keys() if tree_after[p] != tree_before[p]]
        + [f"created {name} next to the case" for name in set(after[1]) - set(before[1])])
    return result


def run_dfwb(box, argv, timeout=None):
    """``python -m dfwb.cli ARGV --fmus <the built FMUs>`` in the sandbox."""
    command = argv[0] if argv and not argv[0].startswith("-") else ""
    cmdline = [PYTHON, "-m", "dfwb.cli", *argv, "--fmus", str(box.fmu_dir)]
    return launch(box, cmdline, cmdline[3:], command, timeout)


def run_python(box, code, timeout=None, command="df", argv=None):
    """Python code in the sandbox, judged as if it were ``dfwb COMMAND`` (tests of the harness)."""
    return launch(box, [PYTHON, "-c", code], argv or [command], command, timeout)


def _reject_constant(name):
    raise ValueError(f"{name} in the JSON output")


def _finite_json(text, where):
    """The parsed JSON; AssertionError-worthy ValueError on NaN, Infinity or a number that overflows."""
    value = json.loads(text, parse_constant=_reject_constant)

    def walk(item, path):
        if isinstance(item, float) and not math.isfinite(item):
            raise ValueError(f"{where}: {path or 'value'} = {item!r} is not finite")
        if isinstance(item, dict):
            for key, sub in item.items():
                walk(sub, f"{path}.{key}")
        elif isinstance(item, list):
            for i, sub in enumerate(item):
                walk(sub, f"{path}[{i}]")

    walk(value, "")
    return value


def _finite_csv(path):
    text = path.read_text(encoding="utf-8")
    rows = csv.DictReader(io.StringIO(text))
    every = path.parent.name == "traces"
    for number, row in enumerate(rows, start=2):
        for column, cell in row.items():
            if column is None or cell is None or not (every or column in NUMERIC_COLUMNS):
                continue
            try:
                value = float(cell)
            except ValueError:
                continue
            if not math.isfinite(value):
                raise ValueError(f"{path.name} line {number}: {column} = {cell} is not finite")


def _check_success(result):
    """Exit 0: every result the command reports is finite. Returns a problem, or None."""
    try:
        if result.command in ("df", "limit-cycle"):
            if "--json" in result.argv:
                value = _finite_json(result.stdout, "stdout")
                if result.command == "df":
                    if not isinstance(value, list) or not value:
                        return "df --json printed no list of points"
                    for i, point in enumerate(value):
                        for key in ("N_re", "N_im"):
                            if not isinstance(point.get(key), (int, float)):
                                return f"df --json: point {i} has {key} = {point.get(key)!r}, not a finite number"
            elif NON_FINITE.search(result.stdout):
                return f"non-finite number in the output: {NON_FINITE.search(result.stdout).group(0)!r}"
        elif result.command in ("sweep", "run"):
            found = sorted(result.out.rglob("results.json")) if result.out.exists() else []
            if not found:
                return f"exit 0 but no results.json under {result.out}"
            for path in found:
                _finite_json(path.read_text(encoding="utf-8"), str(path.relative_to(result.out)))
            for path in sorted(result.out.rglob("*.csv")):
                _finite_csv(path)
    except (ValueError, UnicodeDecodeError) as error:
        return f"exit 0 with results that are not finite or not readable: {error}"
    return None


def _check_refusal(result):
    """Exit 2: one line ``dfwb <command>: error: ...`` (after argparse's usage block). A problem, or None."""
    lines = result.stderr.rstrip("\n").split("\n")
    prefixes = (f"dfwb {result.command}: error: ", "dfwb: error: ") if result.command else ("dfwb: error: ",)
    before, last = lines[:-1], lines[-1]
    if before and not (before[0].startswith("usage: dfwb") and all(line.startswith(" ") for line in before[1:])):
        return f"exit 2 with {len(lines)} lines on stderr: the error must be one line"
    if not last.startswith(prefixes) or not last.split(": error: ", 1)[1].strip():
        return f"exit 2 without the one line '{prefixes[0]}<what>'"
    return None


def check(result, expect=None):
    """Raise AssertionError naming the case unless it ended well (``expect``: the exit code required)."""
    if result.timed_out:
        raise AssertionError(result.explain(f"hang: no exit within {result.timeout:g} s"))
    if "Traceback" in result.stderr:
        raise AssertionError(result.explain("Traceback on stderr"))
    if result.left_running:
        raise AssertionError(result.explain(f"processes left running after the command ended: {result.left_running}"))
    if result.changes:
        raise AssertionError(result.explain("wrote outside the output folder: " + "; ".join(result.changes[:10])))
    if result.written > DISK:
        raise AssertionError(result.explain(f"left {result.written / 2**20:.0f} MiB in the output, cache and "
                                            f"temporary folders (at most {DISK >> 20} MiB)"))
    if result.returncode not in (0, 2):
        raise AssertionError(result.explain(f"exit code {result.returncode}: expected 0 (done) or 2 (refused)"))
    if expect is not None and result.returncode != expect:
        raise AssertionError(result.explain(f"exit code {result.returncode}: expected {expect}"))
    problem = _check_success(result) if result.returncode == 0 else _check_refusal(result)
    if problem:
        raise AssertionError(result.explain(problem))


_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_string(text):
    out = []
    for char in text:
        code = ord(char)
        if char in '"\\':
            out.append("\\" + char)
        elif code < 0x20 or code == 0x7F or 0xD800 <= code <= 0xDFFF:
            out.append(f"\\u{code:04X}")  # a surrogate this way is invalid TOML, which the command must refuse
        else:
            out.append(char)
    return '"' + "".join(out) + '"'


def _toml_value(value):
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return _toml_string(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(item) for item in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(f"TOML has no {type(value).__name__}")


def _toml_key(key):
    return key if _BARE_KEY.match(key) else _toml_string(key)


def toml_document(document):
    """TOML text for a dict (every table inline: ``series = [{name = "a", ...}]``)."""
    return "".join(f"{_toml_key(key)} = {_toml_value(value)}\n" for key, value in document.items())
