"""Controllers G(s) from user text, parsed safely, as python-control transfer functions.

Only numbers, the variable ``s``, named parameters, ``+ - * / **`` (integer
powers) and parentheses are accepted: the text is parsed into Python's
syntax tree and every node is checked against that list before anything is
evaluated, so user text is never ``eval``-ed. A name other than ``s`` is a
parameter of the controller (``"Kp + Ki/s"``); each needs a value. A name is
what is written, character for character, here as in ``--set``, ``--x`` and
scene files: ``PARAMETER`` (ASCII) is checked on G's text, not on the name
Python's parser makes of it (which folds ``K𝐢`` into ``Ki``, NFKC).

The arithmetic is done on plain lists of coefficients (highest power first,
of degree at most ``MAX_DEGREE``, so a product is a short loop): a
:class:`TransferFamily` parsed once evaluates in microseconds for each set of
parameter values, which a continuation needs, and checking a controller
(:func:`check_coefficients`) needs neither numpy nor python-control. A scene
is checked when it is read, so a re-run whose results are all in the cache
imports neither; python-control comes in only when a system is built.

Examples
--------
>>> from dfwb.engine.transfer import parse_transfer_function
>>> G = parse_transfer_function("100*(s+1)/(s+10)")
>>> G.num[0][0].tolist(), G.den[0][0].tolist()
([100.0, 100.0], [1.0, 10.0])
>>> parse_transfer_function("Kp + Ki/s", {"Kp": 10, "Ki": 2}).num[0][0].tolist()
[10.0, 2.0]
>>> parse_transfer_function("s**2/(s+1)")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
dfwb.base.errors.InputError: G(s) = s**2/(s+1) is improper (numerator degree 2 > denominator degree 1): ...
"""

import ast
import math
import numbers
import re

from dfwb.base.errors import InputError

ALLOWED_OPERATORS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
MAX_LENGTH = 1000  # characters of an expression: a controller is a line, not a file
MAX_DEPTH = 100  # nesting of the syntax tree
MAX_DEGREE = 20  # of a numerator or denominator, at every step of the evaluation
MAX_PARAMETERS = 32  # named parameters in one expression
MAX_COEFFICIENTS = 10_000  # numbers read from a (num, den) pair before its degree is judged
PARAMETER = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,63}")  # a parameter's name


class _Rational:
    """num(s) / den(s) as lists of coefficients (highest power first), with SISO transfer-function arithmetic."""

    __slots__ = ("num", "den")

    def __init__(self, num, den):
        self.num, self.den = _trim(num), _trim(den)

    @staticmethod
    def of(value):
        return value if isinstance(value, _Rational) else _Rational([float(value)], [1.0])

    def __neg__(self):
        return _Rational([-c for c in self.num], self.den)

    def __add__(self, other):
        other = _Rational.of(other)
        return _Rational(_polyadd(_polymul(self.num, other.den), _polymul(other.num, self.den)),
                         _polymul(self.den, other.den))

    __radd__ = __add__

    def __sub__(self, other):
        return self + (-other)

    def __rsub__(self, other):
        return (-self) + other

    def __mul__(self, other):
        other = _Rational.of(other)
        return _Rational(_polymul(self.num, other.num), _polymul(self.den, other.den))

    def __rmul__(self, other):
        return _Rational.of(other) * self

    def __truediv__(self, other):
        other = _Rational.of(other)
        return _Rational(_polymul(self.num, other.den), _polymul(self.den, other.num))

    def __rtruediv__(self, other):
        return _Rational.of(other) / self

    def degree(self):
        return max(len(self.num), len(self.den)) - 1


def _polymul(a, b):
    """The product of two polynomials (their coefficients' convolution)."""
    out = [0.0] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] += x * y
    return out


def _polyadd(a, b):
    """The sum of two polynomials (the shorter padded with leading zeros)."""
    width = max(len(a), len(b))
    a, b = [0.0] * (width - len(a)) + list(a), [0.0] * (width - len(b)) + list(b)
    return [x + y for x, y in zip(a, b)]


def _strip(coefficients):
    """Leading zeros removed (all zeros: [])."""
    coefficients = [float(c) for c in coefficients]
    first = next((i for i, c in enumerate(coefficients) if c != 0.0), len(coefficients))
    return coefficients[first:]


def _trim(coefficients):
    """Leading zeros removed (all zeros: [0.0]), as python-control truncates its polynomials."""
    return _strip(coefficients) or [0.0]


def _float(value):
    """float(value), infinite where a Python integer is too large for a float."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


def _number(value, text):
    """A finite float of a literal (1e309 and 10**400 written out are not numbers the engine can use)."""
    number = _float(value)
    if not math.isfinite(number):
        raise InputError(f"G(s) = {text}: the number {value!r} is not finite")
    return number


def _checked_degree(value, text):
    if isinstance(value, _Rational):
        degree = value.degree()
        if degree > MAX_DEGREE:
            raise InputError(f"G(s) = {text}: a polynomial of degree {degree}, at most {MAX_DEGREE} is allowed")
    elif not math.isfinite(value):
        raise InputError(f"G(s) = {text}: a coefficient overflows ({value})")
    return value


def _depth(node, limit):
    """The depth of a syntax tree, counted without recursion (refused beyond ``limit``)."""
    level, depth = [node], 0
    while level:
        depth += 1
        if depth > limit:
            return depth
        level = [child for parent in level for child in ast.iter_child_nodes(parent)]
    return depth


def _evaluate(node, text, values):
    """Value of a checked syntax-tree node: a float or a :class:`_Rational`; ``values`` give the parameters."""
    if isinstance(node, ast.Expression):
        return _evaluate(node.body, text, values)
    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        return _number(node.value, text)
    if isinstance(node, ast.Name):
        if node.id == "s":
            return _Rational([1.0, 0.0], [1.0])
        return values[node.id]
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
        value = _evaluate(node.operand, text, values)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.BinOp) and type(node.op) in ALLOWED_OPERATORS:
        left, right = _evaluate(node.left, text, values), _evaluate(node.right, text, values)
        if isinstance(node.op, ast.Pow):
            if isinstance(right, _Rational) or not (0 <= right <= MAX_DEGREE and right == int(right)):
                power = "an expression in s" if isinstance(right, _Rational) else f"{right:g}"
                raise InputError(f"G(s) = {text}: the power {power} is not allowed: integer powers 0..{MAX_DEGREE} "
                                 "only (write a large number out, e.g. 1e40)")
            result = 1.0
            for _ in range(int(right)):
                result = _checked_degree(result * left, text)
            return result
        if isinstance(node.op, ast.Div) and not isinstance(right, _Rational) and right == 0:
            raise InputError(f"G(s) = {text}: division by zero")
        return _checked_degree({ast.Add: lambda: left + right, ast.Sub: lambda: left - right,
                                ast.Mult: lambda: left * right, ast.Div: lambda: left / right}[type(node.op)](), text)
    raise AssertionError("unchecked node")  # _check refused it before


def _check_tree(tree, text):
    """The parameters' names of a syntax tree parsed from ``text.strip()``, first appearance first; InputError for
    any node not allowed, and for a name not written as ``PARAMETER`` allows."""
    names, source = [], text.strip()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Expression, ast.Load)) or type(node) in ALLOWED_OPERATORS:
            continue
        if isinstance(node, (ast.UAdd, ast.USub)) or (isinstance(node, ast.UnaryOp)
                                                     and isinstance(node.op, (ast.UAdd, ast.USub))):
            continue
        if isinstance(node, ast.BinOp) and type(node.op) in ALLOWED_OPERATORS:
            continue
        if isinstance(node, ast.Constant) and type(node.value) in (int, float):
            continue
        written = ast.get_source_segment(source, node) if isinstance(node, ast.Name) else None
        if written is not None and PARAMETER.fullmatch(written):
            if node.id != "s" and node.id not in names:
                names.append(node.id)
            continue
        what = type(node).__name__
        if isinstance(node, ast.Name):
            what = f"the name {written!r} (a parameter is an ASCII letter or _, then ASCII letters, digits or _)"
        elif isinstance(node, ast.Constant):
            what = f"the constant {node.value!r}"
        raise InputError(f"G(s) = {text}: {what} is not allowed (numbers, s, parameters, + - * / **, "
                         "parentheses)")
    if len(names) > MAX_PARAMETERS:
        raise InputError(f"G(s) = {text}: {len(names)} parameters, at most {MAX_PARAMETERS}")
    return tuple(sorted(names, key=lambda name: text.find(name)))


def check_coefficients(num, den, text):
    """(num, den) of a proper, finite G(s) of degree at most ``MAX_DEGREE`` that depends on s, leading
    zeros removed; anything else refused in one line naming ``text``. Plain Python: no numpy, no control."""
    num, den = _strip(num), _strip(den)
    if not den:
        raise InputError(f"G(s) = {text} has a zero denominator")
    if not all(math.isfinite(c) for c in num + den):
        raise InputError(f"G(s) = {text} has coefficients that are not finite")
    if len(den) - 1 > MAX_DEGREE:
        raise InputError(f"G(s) = {text} has degree {len(den) - 1}: at most {MAX_DEGREE} is allowed")
    if len(num) > len(den):
        raise InputError(f"G(s) = {text} is improper (numerator degree {len(num) - 1} > denominator degree "
                         f"{len(den) - 1}): a controller must be proper")
    if len(den) == 1 and len(num) <= 1:
        raise InputError(f"G(s) = {text} has no s: a controller must depend on s")
    return num or [0.0], den


def check_loop_controller(num, den, text):
    """Refuse a checked G(s) that the exact closed loop cannot take: its order (the denominator's degree)
    beyond the controller FMU's, or coefficients that overflow once the denominator is made monic."""
    from dfwb.fmus.linear_system import MAX_ORDER

    order = len(den) - 1
    if not 1 <= order <= MAX_ORDER:
        raise InputError(f"G(s) = {text} has order {order}: the exact closed loop takes controllers of order "
                         f"1..{MAX_ORDER}")
    scaled = [c / den[0] for c in list(num) + list(den)]
    if not all(math.isfinite(c) for c in scaled):
        raise InputError(f"G(s) = {text}: its coefficients divided by the leading denominator coefficient "
                         f"{den[0]:g} are not finite numbers")


def check_transfer_function(G, text=None):
    """Refuse a G(s) that is not a proper, finite SISO transfer function; return it."""
    import control as ct

    if not text:  # a system's own text runs over lines: its coefficients name it on one
        siso = isinstance(G, ct.TransferFunction) and (G.ninputs, G.noutputs) == (1, 1)
        text = "num {}, den {}".format(*num_den(G)) if siso else " ".join(str(G).split())[:200]
    if not isinstance(G, ct.TransferFunction):
        if isinstance(G, ct.StateSpace):
            G = ct.ss2tf(G)
        else:
            raise InputError(f"G(s) = {text} has no s: a controller must depend on s")
    if G.ninputs != 1 or G.noutputs != 1:
        raise InputError(f"G(s) = {text} must have one input and one output")
    if not G.isctime():
        raise InputError(f"G(s) = {text} must be a continuous-time transfer function")
    check_coefficients(*num_den(G), text)
    return G


class TransferFamily:
    """A controller G(s) with named parameters, parsed and checked once, evaluated for any values.

    Attributes
    ----------
    text : str
        The expression.
    names : tuple of str
        Its parameters, in the order they first appear.

    Examples
    --------
    >>> family = TransferFamily("Kp + Ki/s + Kd*s/(Tf*s + 1)")
    >>> family.names
    ('Kp', 'Ki', 'Kd', 'Tf')
    >>> family.coefficients({"Kp": 10, "Ki": 2, "Kd": 1, "Tf": 0.1})
    ([2.0, 10.2, 2.0], [0.1, 1.0, 0.0])
    """

    def __init__(self, text):
        if not isinstance(text, str) or not text.strip():
            raise InputError("G(s) is empty: give an expression in s, e.g. '100*(s+1)/(s+10)'")
        if len(text) > MAX_LENGTH:
            raise InputError(f"G(s) is {len(text)} characters long: at most {MAX_LENGTH}")
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except SyntaxError as error:
            raise InputError(f"G(s) = {text} does not parse: {error.msg} at column {error.offset} "
                             f"(write products with *, e.g. 2*s)") from None
        except (RecursionError, MemoryError):
            raise InputError(f"G(s) = {text[:40]}...: nested too deeply to parse") from None
        if _depth(tree, MAX_DEPTH) > MAX_DEPTH:
            raise InputError(f"G(s) = {text[:40]}...: nested more than {MAX_DEPTH} levels deep")
        self.text, self._tree = text, tree
        self.names = _check_tree(tree, text)

    def values(self, values):
        """The parameters' values from ``values`` (a mapping; other names ignored), checked: finite numbers."""
        out = {}
        for name in self.names:
            if name not in values:
                raise InputError(f"G(s) = {self.text}: the parameter {name} is given no value (set it, e.g. "
                                 f"{name}=1)")
            value = values[name]
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise InputError(f"G(s) parameter {name} = {value!r:.40} is not a number")
            if not math.isfinite(float(value)):
                raise InputError(f"G(s) parameter {name} = {value!r} is not finite")
            out[name] = float(value)
        return out

    def _rational(self, values):
        try:
            value = _evaluate(self._tree, self.text, self.values(values))
        except ValueError as error:
            if str(error).startswith("G(s)"):
                raise
            raise InputError(f"G(s) = {self.text}: {error}") from None
        except (ArithmeticError, FloatingPointError) as error:
            raise InputError(f"G(s) = {self.text}: {error}") from None
        if not isinstance(value, _Rational):
            raise InputError(f"G(s) = {self.text} has no s: a controller must depend on s")
        return value

    def checked(self, values=None):
        """(num, den) at ``values``, checked as :func:`check_coefficients` checks them (no system built)."""
        value = self._rational(values or {})
        return check_coefficients(value.num, value.den, self.text)

    def transfer_function(self, values=None):
        """The checked python-control TransferFunction at ``values``."""
        return system(*self.checked(values))

    def coefficients(self, values=None):
        """(num, den) at ``values``, highest power first, as python-control would hold them (not checked)."""
        value = self._rational(values or {})
        return [float(c) for c in value.num], [float(c) for c in value.den]


def parse_transfer_function(text, values=None):
    """A proper python-control TransferFunction from an expression in s (``values``: its parameters')."""
    return TransferFamily(text).transfer_function(values)


def checked_pair(num, den, names=("--num", "--den")):
    """(num, den) given as coefficient lists (highest power first), checked; ``names``: how the user wrote them."""
    if not num or not den:
        raise InputError(f"{names[0]} and {names[1]} both need at least one coefficient")
    if not all(math.isfinite(c) for c in list(num) + list(den)):
        raise InputError(f"G(s) coefficients num = {num}, den = {den} must be finite")
    if not any(den):
        raise InputError(f"G(s) den = {den} is zero")
    return check_coefficients(num, den, f"({num})/({den})")


def from_coefficients(num, den, names=("--num", "--den")):
    """A proper TransferFunction from coefficient lists (highest power first); ``names``: how the user wrote them."""
    return system(*checked_pair(num, den, names))


def num_den(G):
    """(num, den) of a SISO transfer function as lists of floats, highest power first (JSON, keys, reports)."""
    return [float(c) for c in G.num[0][0]], [float(c) for c in G.den[0][0]]


def is_pair(G):
    """Whether G is given as (num, den)."""
    return isinstance(G, (tuple, list)) and len(G) == 2


def pair_of(G):
    """(num, den) of G given as two flat lists (or arrays) of real numbers, checked; no system is built."""
    if all(isinstance(part, (list, tuple)) and len(part) <= MAX_COEFFICIENTS
           and all(type(c) in (int, float) for c in part) for part in G):  # plain numbers: no numpy needed
        num, den = ([_float(c) for c in part] for part in G)
    else:
        from dfwb.base.values import reals, short

        try:
            num, den = (reals(name, part, MAX_COEFFICIENTS) for name, part in zip(("num", "den"), G))
        except InputError as error:
            raise InputError(f"G = {short(G)}: num and den must be lists of real numbers ({error})") from None
        if num.ndim > 1 or den.ndim > 1:
            raise InputError(f"G = {short(G)}: num and den must be flat lists of real numbers")
        num, den = num.reshape(-1).tolist(), den.reshape(-1).tolist()
    if max(len(num), len(den)) > MAX_DEGREE + 1:
        raise InputError(f"G = ({num[:3]}..., {den[:3]}...): a polynomial of degree {max(len(num), len(den)) - 1}, "
                         f"at most {MAX_DEGREE} is allowed")
    return checked_pair(num, den, names=("num", "den"))


def system(num, den):
    """The python-control TransferFunction of checked coefficients (python-control is imported here)."""
    import control as ct

    return ct.tf(list(num), list(den))


def to_transfer_function(G):
    """G as a checked TransferFunction: an expression in s, (num, den), or a python-control system (see
    :func:`dfwb.transfer_function`)."""
    if isinstance(G, str):
        return parse_transfer_function(G)
    if is_pair(G):
        return system(*pair_of(G))
    import control as ct
    import numpy as np

    from dfwb.base.values import short

    if isinstance(G, (ct.TransferFunction, ct.StateSpace)):
        text = f"the {type(G).__name__} {G.name!r}"  # str(G) is a multi-line table
        if G.ninputs != 1 or G.noutputs != 1:
            raise InputError(f"G(s) = {text} must have one input and one output (it has {G.ninputs} and "
                             f"{G.noutputs})")
        if isinstance(G, ct.StateSpace):
            if G.nstates > MAX_DEGREE:
                raise InputError(f"G(s) = {text} has {G.nstates} states: a degree of at most {MAX_DEGREE} is allowed")
            if not all(np.all(np.isfinite(np.asarray(m, dtype=complex))) for m in (G.A, G.B, G.C, G.D)):
                raise InputError(f"G(s) = {text} has matrix entries that are not finite")
            if not G.isctime():
                raise InputError(f"G(s) = {text} must be a continuous-time system (dt = 0), not dt = {G.dt}")
        return check_transfer_function(G, text)
    raise InputError(f"G = {short(G)} is not a controller: give an expression in s, (num, den), "
                     "or a python-control TransferFunction or StateSpace")
