"""Controllers G(s) from user text, parsed safely, as python-control transfer functions.

Only numbers, the variable ``s``, ``+ - * / **`` (integer powers) and
parentheses are accepted: the text is parsed into Python's syntax tree and
every node is checked against that list before anything is evaluated, so
user text is never ``eval``-ed.

Examples
--------
>>> from dfwb.engine.transfer import parse_transfer_function
>>> G = parse_transfer_function("100*(s+1)/(s+10)")
>>> G.num[0][0].tolist(), G.den[0][0].tolist()
([100.0, 100.0], [1.0, 10.0])
>>> parse_transfer_function("s**2/(s+1)")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
dfwb.base.errors.InputError: G(s) = s**2/(s+1) is improper (numerator degree 2 > denominator degree 1): ...
"""

import ast
import math

import control as ct
import numpy as np

from dfwb.base.errors import InputError

ALLOWED_OPERATORS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
MAX_LENGTH = 1000  # characters of an expression: a controller is a line, not a file
MAX_DEPTH = 100  # nesting of the syntax tree
MAX_DEGREE = 20  # of a numerator or denominator, at every step of the evaluation


def _number(value, text):
    """A finite float of a literal (1e309 and 10**400 written out are not numbers the engine can use)."""
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    if not math.isfinite(number):
        raise InputError(f"G(s) = {text}: the number {value!r} is not finite")
    return number


def _checked_degree(value, text):
    if isinstance(value, ct.TransferFunction):
        degree = max(len(value.num[0][0]), len(value.den[0][0])) - 1
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


def _evaluate(node, text):
    """Value of a checked syntax-tree node: a float or a python-control TransferFunction."""
    if isinstance(node, ast.Expression):
        return _evaluate(node.body, text)
    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        return _number(node.value, text)
    if isinstance(node, ast.Name) and node.id == "s":
        return ct.tf("s")
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
        value = _evaluate(node.operand, text)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.BinOp) and type(node.op) in ALLOWED_OPERATORS:
        left, right = _evaluate(node.left, text), _evaluate(node.right, text)
        if isinstance(node.op, ast.Pow):
            if isinstance(right, ct.TransferFunction) or not (0 <= right <= MAX_DEGREE and right == int(right)):
                raise InputError(f"G(s) = {text}: only integer powers 0..{MAX_DEGREE} of an expression are allowed")
            result = 1.0
            for _ in range(int(right)):
                result = _checked_degree(result * left, text)
            return result
        if isinstance(node.op, ast.Div) and not isinstance(right, ct.TransferFunction) and right == 0:
            raise InputError(f"G(s) = {text}: division by zero")
        return _checked_degree({ast.Add: lambda: left + right, ast.Sub: lambda: left - right,
                                ast.Mult: lambda: left * right, ast.Div: lambda: left / right}[type(node.op)](), text)
    what = type(node).__name__
    if isinstance(node, ast.Name):
        what = f"the name {node.id!r} (the only variable is s)"
    elif isinstance(node, ast.Constant):
        what = f"the constant {node.value!r}"
    raise InputError(f"G(s) = {text}: {what} is not allowed (numbers, s, + - * / **, parentheses)")


def check_transfer_function(G, text=None):
    """Refuse a G(s) that is not a proper, finite SISO transfer function; return it."""
    text = text or str(G).strip()
    if not isinstance(G, ct.TransferFunction):
        if isinstance(G, ct.StateSpace):
            G = ct.ss2tf(G)
        else:
            raise InputError(f"G(s) = {text} has no s: a controller must depend on s")
    if G.ninputs != 1 or G.noutputs != 1:
        raise InputError(f"G(s) = {text} must have one input and one output")
    if not G.isctime():
        raise InputError(f"G(s) = {text} must be a continuous-time transfer function")
    num, den = np.trim_zeros(np.atleast_1d(G.num[0][0]), "f"), np.trim_zeros(np.atleast_1d(G.den[0][0]), "f")
    if len(den) == 0:
        raise InputError(f"G(s) = {text} has a zero denominator")
    if not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))):
        raise InputError(f"G(s) = {text} has coefficients that are not finite")
    if len(den) - 1 > MAX_DEGREE:
        raise InputError(f"G(s) = {text} has degree {len(den) - 1}: at most {MAX_DEGREE} is allowed")
    if len(num) > len(den):
        raise InputError(f"G(s) = {text} is improper (numerator degree {len(num) - 1} > denominator degree "
                         f"{len(den) - 1}): a controller must be proper")
    if len(den) == 1 and len(num) <= 1:
        raise InputError(f"G(s) = {text} has no s: a controller must depend on s")
    return G


def parse_transfer_function(text):
    """A proper python-control TransferFunction from an expression in s."""
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
    try:
        value = _evaluate(tree, text)
    except ValueError as error:
        if str(error).startswith("G(s)"):
            raise
        raise InputError(f"G(s) = {text}: {error}") from None
    except (ArithmeticError, FloatingPointError) as error:
        raise InputError(f"G(s) = {text}: {error}") from None
    return check_transfer_function(value, text)


def from_coefficients(num, den, names=("--num", "--den")):
    """A proper TransferFunction from coefficient lists (highest power first); ``names``: how the user wrote them."""
    if not num or not den:
        raise InputError(f"{names[0]} and {names[1]} both need at least one coefficient")
    if not all(math.isfinite(c) for c in list(num) + list(den)):
        raise InputError(f"G(s) coefficients num = {num}, den = {den} must be finite")
    if not any(den):
        raise InputError(f"G(s) den = {den} is zero")
    return check_transfer_function(ct.tf(list(num), list(den)), f"({num})/({den})")
