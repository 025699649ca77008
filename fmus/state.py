"""FMU state: an exact copy of a facade and its solver, in memory and as bytes.

``fmi2GetFMUstate`` keeps a :class:`FMUState`: the facade's own values
(parameters, input, start time, absolute time, the phase of the FMI state
machine, the cached outputs) and a deep copy of the solver. A solver is
plain data: numbers, complex numbers, lists, tuples, dicts and instances of
a few classes with no behaviour on creation (the solver class, ``Drive``,
``Motion``, ``Search`` and the search functions of :mod:`.piecewise`,
``EventKind``) - no closure, no bound method - so :func:`copy.deepcopy`
copies it exactly and shares nothing mutable with the original. A solver of
the compiled core (:mod:`.native_core`) is copied by its own exact ``copy``.

``fmi2SerializeFMUstate`` writes::

    MAGIC  <header: JSON, one line>  <pickle of (facade values, solver)>

The header names the format, the model and the package the FMU bundles its
code as (``dfwb_fmus_<source hash>``), and the pickle's length and SHA-256: a
state of another model or another build, and bytes that are not exactly
what the FMU wrote (truncated, extended, a flipped bit), are refused before
anything is unpickled, at deserialization. The pickle is read by a
restricted unpickler (the "Restricting Globals" recipe of the :mod:`pickle`
documentation): ``find_class`` returns only the classes of an explicit
table (:func:`allowed_classes`, looked up by module and name, never through
``getattr`` on a module) and ``complex``; every other global (``os.system``,
``builtins.eval``, ``getattr``...) is refused. The bytes are capped in size,
and the object read is then checked: the expected structure, only allowed
types, no NaN, the solver an instance of the facade's own solver class (or a
:class:`NativeState` of its plant).
A crafted state can therefore not run code; at worst it holds wrong but
well-typed numbers, like a crafted parameter would.

A solver of the compiled core is written as a :class:`NativeState` (the
plant's name and the core's own state bytes), never as the native class:
unpickling that would load a library from a path named in the data. The
facade turns it back into a solver with its own core's ``from_bytes``,
which checks every byte (header, CRC-32, each field's range) and refuses
anything else.

Plain Python only: this module runs inside the FMUs.
"""

import copy
import hashlib
import io
import json
import math
import pickle

MAGIC = b"dfwb-fmu-state\n"
FORMAT = 2  # 2: the header holds the pickle's length and SHA-256
MAX_BYTES = 1 << 18  # 256 kB: a solver state is a few kB (LinearSystem's full transition cache 45 kB); a
# pickle builds objects of ~60-220 bytes from one-byte opcodes before they are checked, so this also bounds
# the memory a crafted state takes (4 MiB of EMPTY_LIST opcodes took 370 MB)
HASH_PIECE = 2000  # bytes: below hashlib's 2048, over which it releases the GIL (see _sha256)
MAX_NODES = 200_000  # objects visited when a restored state is checked


class StateRefused(ValueError):
    """A state (in memory or as bytes) that this FMU cannot restore; the message says why."""


class FMUState:
    """What fmi2GetFMUstate hands the importer: the facade's values and a private copy of the solver."""

    __slots__ = ("model", "package", "values", "solver")

    def __init__(self, model, package, values, solver):
        self.model, self.package, self.values, self.solver = model, package, values, solver


class RefusedState:
    """What deserialisation returns for bytes it refuses: setting it logs ``refused`` as an error.

    (pythonfmu calls the deserialiser on the class, with no instance to log
    to. The FMU's shim serializes what was deserialized once more and
    refuses at fmi2DeSerializeFMUstate what serializes as ``MAGIC +
    b"refused: "``; without the shim, the error surfaces at fmi2SetFMUstate.)
    """

    __slots__ = ("refused",)

    def __init__(self, refused):
        self.refused = str(refused)


class NativeState:
    """A solver of the compiled core, serialized: ``plant`` (the NativeCore attribute, e.g. "FrictionMass")
    and ``data``, the bytes of its ``to_bytes()`` (read back by the FMU's own core, which checks them)."""

    __slots__ = ("plant", "data")

    def __init__(self, plant, data):
        self.plant, self.data = plant, data


SCALARS = (type(None), bool, int, float, str, complex, bytes)


class _Unpickler(pickle.Unpickler):
    """Only the classes of ``table`` ({(module, qualname): class}) and builtins.complex can be named."""

    def __init__(self, data, table):
        super().__init__(io.BytesIO(data))
        self._table = table

    def find_class(self, module, name):
        if (module, name) == ("builtins", "complex"):
            return complex
        cls = self._table.get((module, name))
        if cls is None:
            raise StateRefused(f"the state names {module}.{name}, which is not a class of this FMU's state")
        return cls

    def persistent_load(self, pid):
        raise StateRefused("the state holds a persistent reference")


def encode(state, table):
    """Bytes of a :class:`FMUState` (MAGIC, a JSON header line, the pickle)."""
    payload = pickle.dumps((state.values, state.solver), protocol=4)
    check_graph((state.values, state.solver), table)  # what is written can be read back
    return frame(state.model, state.package, payload)


def _sha256(data):
    """SHA-256 in pieces of HASH_PIECE bytes: hashlib releases the GIL for a larger update, and inside a
    pythonfmu FMU called from a Python host that let another thread run mid-call and corrupted the heap
    (tests/test_attack_fmu.py's long random call sequences died in 1 run of 4, "corrupted double-linked list")."""
    digest = hashlib.sha256()
    for start in range(0, len(data), HASH_PIECE):
        digest.update(data[start:start + HASH_PIECE])
    return digest.hexdigest()


def frame(model, package, payload):
    """MAGIC, the header line (format, model, package, the payload's length and SHA-256), the payload."""
    header = json.dumps({"format": FORMAT, "model": model, "package": package,
                         "bytes": len(payload), "sha256": _sha256(payload)}).encode()
    return MAGIC + header + b"\n" + payload


def decode(data, model, package, table):
    """The :class:`FMUState` in ``data``; StateRefused unless it is a state of this model and build."""
    if not isinstance(data, (bytes, bytearray)):
        raise StateRefused(f"a serialized state must be bytes, not {type(data).__name__}")
    if len(data) > MAX_BYTES:
        raise StateRefused(f"a serialized state of {len(data)} bytes is larger than {MAX_BYTES}")
    if not data.startswith(MAGIC):
        raise StateRefused("these bytes are not a serialized dfwb FMU state")
    line, sep, payload = bytes(data[len(MAGIC):]).partition(b"\n")
    try:
        header = json.loads(line.decode("utf-8")) if sep else None
    except (UnicodeDecodeError, ValueError):
        header = None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise StateRefused("the state's header is damaged or of another format")
    if header.get("model") != model:
        raise StateRefused(f"the state is one of model {header.get('model')!r}, not {model!r}")
    if header.get("package") != package:
        raise StateRefused(f"the state comes from another build ({header.get('package')!r}; "
                           f"this FMU is {package!r})")
    if header.get("bytes") != len(payload):
        raise StateRefused(f"the state holds {len(payload)} bytes after its header, which says "
                           f"{header.get('bytes')!r} (truncated, or bytes appended)")
    if header.get("sha256") != _sha256(payload):
        raise StateRefused("the state's bytes do not match their SHA-256 (damaged)")
    try:
        loaded = _Unpickler(payload, table).load()
    except StateRefused:
        raise
    except Exception as error:  # a truncated or damaged pickle: any error of the reader
        raise StateRefused(f"the state cannot be read ({type(error).__name__}: {error})") from None
    if not (isinstance(loaded, tuple) and len(loaded) == 2 and isinstance(loaded[0], dict)):
        raise StateRefused("the state does not hold (facade values, solver)")
    check_graph(loaded, table)
    return FMUState(model, package, loaded[0], loaded[1])


def check_graph(root, table):
    """StateRefused unless everything reachable from root is allowed data (no NaN, no class, no function)."""
    allowed = frozenset(table.values())
    seen = set()
    todo = [root]
    while todo:
        obj = todo.pop()
        if id(obj) in seen:
            continue
        seen.add(id(obj))
        if len(seen) > MAX_NODES:
            raise StateRefused(f"the state holds more than {MAX_NODES} objects")
        kind = type(obj)
        if kind is float:
            if math.isnan(obj):
                raise StateRefused("the state holds a NaN")
        elif kind is complex:
            if math.isnan(obj.real) or math.isnan(obj.imag):
                raise StateRefused("the state holds a NaN")
        elif kind is int:
            if obj.bit_length() > 64:  # a counter or an index: no larger (an output is a 32-bit fmi2Integer)
                raise StateRefused("the state holds an integer of more than 64 bits")
        elif kind in SCALARS:
            pass
        elif kind in (list, tuple):
            todo.extend(obj)
        elif kind is dict:
            todo.extend(obj.keys())
            todo.extend(obj.values())
        elif kind in allowed:
            if isinstance(obj, str):  # a str enum member (EventKind): no attributes to visit
                continue
            todo.extend(getattr(obj, "__dict__", {}).values())
            for klass in kind.__mro__:
                for slot in getattr(klass, "__slots__", ()):
                    if hasattr(obj, slot):
                        todo.append(getattr(obj, slot))
        else:
            raise StateRefused(f"the state holds an object of type {kind.__name__}, which is not allowed")


def copy_solver(solver):
    """An exact, independent copy of a solver (shares nothing mutable with it)."""
    return copy.deepcopy(solver)
