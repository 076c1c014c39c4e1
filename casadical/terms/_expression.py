"""The expression language of a terms file: numbers, names, a few functions, ``+ - * / **`` and parentheses.

A terms file is data, never code. An expression string is parsed with
:func:`ast.parse` (parsing alone evaluates nothing) and the tree is walked
here node by node: only the nodes this module lists are accepted, and the
accepted tree is copied into a small tree of its own (:class:`Expression`),
which :meth:`Expression.casadi` translates into CasADi symbols and
:meth:`Expression.numpy` into numpy arrays. Nothing is ever passed to
``eval``, ``exec`` or ``compile``.
"""

from __future__ import annotations

import ast
import math
import re
from dataclasses import dataclass
from typing import Any, Callable

import casadi as ca
import numpy as np

#: functions an expression may call, by bare name, with their number of arguments
FUNCTIONS = {"sin": 1, "cos": 1, "tan": 1, "exp": 1, "log": 1, "sqrt": 1, "abs": 1, "tanh": 1, "sign": 1,
             "min": 2, "max": 2}
#: constants an expression may name
CONSTANTS = {"pi": math.pi}
#: names of the model's point in the measurement frame: for ``point`` effects only
POINT_NAMES = ("px", "py", "pz", "azimuth", "elevation", "distance")
#: the moment of the weights carried by joint 1, base frame
MOMENT_NAMES = ("mx", "my", "mz")
#: columns of the measurements every file may have
KNOWN_COLUMNS = ("row", "payload_kg", "temperature_c", "time_s")
_JOINT_NAME = re.compile(r"^(q|tau)([1-9][0-9]*)$")
_COLUMN_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
#: readings and measured values: columns of the measurements that are not names
_READING = re.compile(r"^(q[0-9]+(_deg|_mm)?|[xyz]_mm|r[xyz]_deg|source_row|move[0-9]+|session)$")
#: longest expression text (a deep nesting must not exhaust the parser)
MAX_LENGTH = 2000

_CASADI: dict[str, Callable] = {"sin": ca.sin, "cos": ca.cos, "tan": ca.tan, "exp": ca.exp, "log": ca.log,
                                "sqrt": ca.sqrt, "abs": ca.fabs, "tanh": ca.tanh, "sign": ca.sign,
                                "min": ca.fmin, "max": ca.fmax}
_NUMPY: dict[str, Callable] = {"sin": np.sin, "cos": np.cos, "tan": np.tan, "exp": np.exp, "log": np.log,
                               "sqrt": np.sqrt, "abs": np.abs, "tanh": np.tanh, "sign": np.sign,
                               "min": np.minimum, "max": np.maximum}
_OPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}


class ExpressionError(ValueError):
    """An expression refused: ``token`` is what is at fault, ``message`` says why (one line)."""

    def __init__(self, token: str, message: str):
        self.token, self.message = token, message
        super().__init__(message)


@dataclass(frozen=True)
class Expression:
    """An accepted expression: ``kind`` one of ``num``, ``name``, ``call``, ``op``, ``neg``.

    ``value`` is the number, the name, the function or the operator;
    ``args`` the operands.
    """

    kind: str
    value: Any = None
    args: tuple = ()

    def names(self) -> set[str]:
        """Every name the expression uses (not the functions, not ``pi``)."""
        if self.kind == "name":
            return set() if self.value in CONSTANTS else {self.value}
        return set().union(*(a.names() for a in self.args)) if self.args else set()

    def evaluate(self, env: dict, functions: dict[str, Callable]) -> Any:
        """The value, with ``env`` giving each name's value and ``functions`` each function."""
        if self.kind == "num":
            return self.value
        if self.kind == "name":
            return CONSTANTS[self.value] if self.value in CONSTANTS else env[self.value]
        if self.kind == "neg":
            return -self.args[0].evaluate(env, functions)
        if self.kind == "call":
            return functions[self.value](*(a.evaluate(env, functions) for a in self.args))
        a, b = (x.evaluate(env, functions) for x in self.args)
        if self.value == "+":
            return a + b
        if self.value == "-":
            return a - b
        if self.value == "*":
            return a * b
        if self.value == "/":
            return a / b
        return a ** b

    def casadi(self, env: dict) -> Any:
        """The expression in CasADi symbols (``env``: name -> SX)."""
        return self.evaluate(env, _CASADI)

    def numpy(self, env: dict) -> Any:
        """The expression in numpy (``env``: name -> array or float); non-finite results are the caller's to
        find (no warning)."""
        with np.errstate(all="ignore"):
            return self.evaluate({k: np.asarray(v, dtype=float) for k, v in env.items()}, _NUMPY)


def names_help(parameters) -> str:
    """The names an expression may use, in words (for messages)."""
    own = ", ".join(parameters) or "none"
    return (f"names: q1..qN, tau1..tauN, mx, my, mz, {', '.join(POINT_NAMES)} (point effects), "
            f"{', '.join(KNOWN_COLUMNS)}, other numeric columns of the measurements, the term's parameters "
            f"({own}), pi")


def parse(text: Any, parameters, point: bool = False) -> Expression:
    """The expression of ``text``, checked node by node; nothing is evaluated.

    Parameters
    ----------
    text : str
        The expression.
    parameters : collection of str
        The term's own parameter names.
    point : bool
        The expression is a ``point`` effect's (``px``, ..., ``distance`` allowed).

    Raises
    ------
    ExpressionError
        Naming the token at fault.
    """
    if isinstance(text, bool) or not isinstance(text, (str, int, float)):
        raise ExpressionError(repr(text), f"an expression must be a string (or a number), got {type(text).__name__}")
    if not isinstance(text, str):
        if not math.isfinite(text):
            raise ExpressionError(repr(text), "a number in an expression must be finite")
        return Expression("num", float(text))
    if len(text) > MAX_LENGTH:
        raise ExpressionError(text[:20] + "...", f"an expression may be at most {MAX_LENGTH} characters long")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as e:
        token = (e.text or text)[max((e.offset or 1) - 1, 0):][:20].strip() or text.strip()[:20]
        raise ExpressionError(token, f"not an expression ({e.msg})") from None
    except (ValueError, RecursionError, MemoryError):
        raise ExpressionError(text[:20], "not an expression") from None
    walker = _Walker(text.strip(), set(parameters), point)
    try:
        return walker.walk(tree.body)
    except RecursionError:
        raise ExpressionError(text[:20], "an expression nested too deeply") from None


class _Walker:
    """Copies an accepted ``ast`` tree into an :class:`Expression`, refusing every other node."""

    def __init__(self, text: str, parameters: set[str], point: bool):
        self.text, self.parameters, self.point = text, parameters, point

    def segment(self, node: ast.AST) -> str:
        s = ast.get_source_segment(self.text, node) or type(node).__name__
        return s if len(s) <= 40 else s[:37] + "..."

    def refuse(self, node: ast.AST, what: str) -> ExpressionError:
        return ExpressionError(self.segment(node), f"{what} is not allowed in an expression (numbers, names, the "
                               f"functions {' '.join(FUNCTIONS)}, + - * / ** and parentheses)")

    def walk(self, node: ast.AST) -> Expression:
        if isinstance(node, ast.Constant):
            v = node.value
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise self.refuse(node, "a string" if isinstance(v, (str, bytes)) else f"the constant {v!r}")
            if not math.isfinite(float(v)):
                raise self.refuse(node, "a number that is not finite")
            return Expression("num", float(v))
        if isinstance(node, ast.Name):
            self.check_name(node.id)
            return Expression("name", node.id)
        if isinstance(node, ast.BinOp):
            op = _OPS.get(type(node.op))
            if op is None:
                raise ExpressionError(self.op_token(node), f"the operator {self.op_token(node)!r} is not allowed in "
                                      "an expression (operators: + - * / **)")
            return Expression("op", op, (self.walk(node.left), self.walk(node.right)))
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, ast.USub):
                return Expression("neg", None, (self.walk(node.operand),))
            if isinstance(node.op, ast.UAdd):
                return self.walk(node.operand)
            raise self.refuse(node, "this unary operator")
        if isinstance(node, ast.Call):
            return self.call(node)
        what = {ast.Attribute: "attribute access", ast.Subscript: "a subscript", ast.Lambda: "a lambda",
                ast.Compare: "a comparison", ast.BoolOp: "a boolean operator", ast.IfExp: "a conditional",
                ast.ListComp: "a comprehension", ast.SetComp: "a comprehension", ast.DictComp: "a comprehension",
                ast.GeneratorExp: "a comprehension", ast.Tuple: "a tuple", ast.List: "a list", ast.Dict: "a dict",
                ast.Set: "a set", ast.JoinedStr: "a string", ast.NamedExpr: "an assignment",
                ast.Starred: "unpacking", ast.Await: "await", ast.Slice: "a slice"}.get(type(node), "this")
        raise self.refuse(node, what)

    def op_token(self, node: ast.BinOp) -> str:
        between = self.text[len(self.segment(node.left)):]
        return {ast.FloorDiv: "//", ast.Mod: "%", ast.MatMult: "@", ast.BitAnd: "&", ast.BitOr: "|",
                ast.BitXor: "^", ast.LShift: "<<", ast.RShift: ">>"}.get(type(node.op), between[:3].strip())

    def call(self, node: ast.Call) -> Expression:
        if not isinstance(node.func, ast.Name):
            raise self.refuse(node.func, "calling anything but a function by its bare name")
        name = node.func.id
        if name not in FUNCTIONS:
            raise ExpressionError(name, f"{name!r} is not a function an expression may use (functions: "
                                  f"{' '.join(FUNCTIONS)})")
        if node.keywords:
            k = node.keywords[0]
            raise ExpressionError(f"{k.arg}=" if k.arg else "**", f"keyword arguments are not allowed in an "
                                  f"expression ({name} takes {FUNCTIONS[name]} plain argument(s))")
        if len(node.args) != FUNCTIONS[name]:
            raise ExpressionError(name, f"{name} takes {FUNCTIONS[name]} argument(s), got {len(node.args)}")
        return Expression("call", name, tuple(self.walk(a) for a in node.args))

    def check_name(self, name: str) -> None:
        if name in FUNCTIONS:
            raise ExpressionError(name, f"{name!r} is a function: call it, e.g. {name}(q1)")
        if name in self.parameters or name in CONSTANTS or name in MOMENT_NAMES or name in KNOWN_COLUMNS \
                or _JOINT_NAME.match(name):
            return
        if name in POINT_NAMES:
            if self.point:
                return
            raise ExpressionError(name, f"{name!r} is a name of point effects only (the model's point in the "
                                  "measurement frame)")
        if _READING.match(name):
            raise ExpressionError(name, f"{name!r} is a reading or a measured value, not a name an expression may "
                                  "use (a joint's reading is q1, q2, ... in rad)")
        if name.startswith("_") or not _COLUMN_NAME.match(name):
            raise ExpressionError(name, f"{name!r} is not a name an expression may use "
                                  f"({names_help(sorted(self.parameters))})")


def joint_name(name: str) -> tuple[str, int] | None:
    """``("q", 2)`` for ``q2``, ``("tau", 3)`` for ``tau3``; None for any other name."""
    m = _JOINT_NAME.match(name)
    return (m.group(1), int(m.group(2))) if m else None


def joint_names(expr: Expression) -> dict[str, set[int]]:
    """The joints whose reading (``q``) and load (``tau``) the expression uses."""
    out: dict[str, set[int]] = {"q": set(), "tau": set()}
    for kind, j in filter(None, map(joint_name, expr.names())):
        out[kind].add(j)
    return out


def is_reading(name: str) -> bool:
    """``name`` is a reading or a measured value of the measurements (``q2_deg``, ``x_mm``, ...), never a name."""
    return bool(_READING.match(name))


def is_column(name: str, parameters) -> bool:
    """``name`` is a column of the measurements (not a joint, moment, point name, parameter or constant)."""
    return not (name in parameters or name in CONSTANTS or name in MOMENT_NAMES or name in POINT_NAMES
                or _JOINT_NAME.match(name))
