"""A small arithmetic expression language for parametric L-systems (never Python ``eval``).

Grammar (lowest to highest precedence)::

    expr    := or
    or      := and ('||' and)*
    and     := not ('&&' not)*
    not     := '!' not | cmp
    cmp     := sum (('<' | '<=' | '>' | '>=' | '==' | '!=') sum)?
    sum     := prod (('+' | '-') prod)*
    prod    := unary (('*' | '/' | '%') unary)*
    unary   := ('-' | '+') unary | power
    power   := atom ('^' unary)?          # right associative; '**' is accepted too
    atom    := NUMBER | NAME | NAME '(' expr (',' expr)* ')' | '(' expr ')'

Booleans are 1.0 and 0.0. Names are variables (bound by a production's predecessor),
constants (``pi``, ``e`` and the grammar's ``define:`` lines) or functions
(:data:`FUNCTIONS`). Expressions are parsed once into a tree of :class:`Node` and then
evaluated either on scalars (:func:`evaluate`) or column-wise on numpy arrays
(:func:`evaluate_array`, one value per module), which is how parametric derivation stays
fast. Division or modulo by zero raises :class:`ExprError` instead of producing inf.

>>> tree = parse_expr("x * 2 + max(y, 1)")
>>> evaluate(tree, {"x": 3.0, "y": 0.5})
7.0
>>> to_text(parse_expr("-(1+2)^2"))
'(-((1.0 + 2.0) ^ 2.0))'
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

__all__ = ["ExprError", "Node", "parse_expr", "evaluate", "evaluate_array", "to_text",
           "names_in", "FUNCTIONS", "CONSTANTS"]


class ExprError(ValueError):
    """A syntax or evaluation error; ``column`` is 1-based within the expression's line."""

    def __init__(self, message: str, column: int | None = None):
        self.message = message
        self.column = column
        super().__init__(message if column is None else f"column {column}: {message}")


@dataclass(frozen=True)
class Node:
    """One node of an expression tree.

    ``kind`` is ``"num"`` (``value``), ``"var"`` (``name``), ``"call"`` (``name``, ``args``),
    ``"unary"`` or ``"binary"`` (``op``, ``args``). ``column`` is where it starts (1-based,
    relative to the line the expression came from).
    """

    kind: str
    value: float = 0.0
    name: str = ""
    op: str = ""
    args: tuple = ()
    column: int = 1


FUNCTIONS = {
    "sin": (1, math.sin, np.sin), "cos": (1, math.cos, np.cos), "tan": (1, math.tan, np.tan),
    "asin": (1, math.asin, np.arcsin), "acos": (1, math.acos, np.arccos),
    "atan": (1, math.atan, np.arctan), "atan2": (2, math.atan2, np.arctan2),
    "sqrt": (1, math.sqrt, np.sqrt), "exp": (1, math.exp, np.exp), "log": (1, math.log, np.log),
    "abs": (1, abs, np.abs), "floor": (1, math.floor, np.floor), "ceil": (1, math.ceil, np.ceil),
    "min": (2, min, np.minimum), "max": (2, max, np.maximum),
    "sign": (1, lambda v: float(np.sign(v)), np.sign),
}
"""name -> (arity, scalar function, numpy function)."""

CONSTANTS = {"pi": math.pi, "e": math.e}

_TOKEN = re.compile(r"""
    (?P<ws>\s+)
  | (?P<num>(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)
  | (?P<name>[A-Za-z_][A-Za-z_0-9]*)
  | (?P<op>\*\*|<=|>=|==|!=|&&|\|\||[-+*/%^()<>!,])
""", re.VERBOSE)


def _tokenize(text: str, col0: int):
    pos = 0
    out = []
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            raise ExprError(f"unexpected character {text[pos]!r}", col0 + pos)
        if m.lastgroup != "ws":
            out.append((m.lastgroup, m.group(), col0 + pos))
        pos = m.end()
    out.append(("end", "", col0 + len(text)))
    return out


class _Parser:
    def __init__(self, text: str, col0: int):
        self.toks = _tokenize(text, col0)
        self.i = 0

    def peek(self):
        return self.toks[self.i]

    def take(self):
        tok = self.toks[self.i]
        self.i += 1
        return tok

    def expect(self, value):
        kind, text, col = self.take()
        if text != value:
            got = "end of expression" if kind == "end" else repr(text)
            raise ExprError(f"expected {value!r}, got {got}", col)

    def binary_chain(self, ops, sub):
        left = sub()
        while self.peek()[1] in ops:
            _, op, col = self.take()
            left = Node("binary", op=op, args=(left, sub()), column=left.column)
        return left

    def parse_or(self):
        return self.binary_chain(("||",), self.parse_and)

    def parse_and(self):
        return self.binary_chain(("&&",), self.parse_not)

    def parse_not(self):
        if self.peek()[1] == "!":
            _, _, col = self.take()
            return Node("unary", op="!", args=(self.parse_not(),), column=col)
        return self.parse_cmp()

    def parse_cmp(self):
        left = self.parse_sum()
        if self.peek()[1] in ("<", "<=", ">", ">=", "==", "!="):
            _, op, _ = self.take()
            left = Node("binary", op=op, args=(left, self.parse_sum()), column=left.column)
            if self.peek()[1] in ("<", "<=", ">", ">=", "==", "!="):
                raise ExprError("comparisons do not chain; use &&", self.peek()[2])
        return left

    def parse_sum(self):
        return self.binary_chain(("+", "-"), self.parse_prod)

    def parse_prod(self):
        return self.binary_chain(("*", "/", "%"), self.parse_unary)

    def parse_unary(self):
        if self.peek()[1] in ("-", "+"):
            _, op, col = self.take()
            arg = self.parse_unary()
            return arg if op == "+" else Node("unary", op="-", args=(arg,), column=col)
        return self.parse_power()

    def parse_power(self):
        base = self.parse_atom()
        if self.peek()[1] in ("^", "**"):
            self.take()
            return Node("binary", op="^", args=(base, self.parse_unary()), column=base.column)
        return base

    def parse_atom(self):
        kind, text, col = self.take()
        if kind == "num":
            return Node("num", value=float(text), column=col)
        if kind == "name":
            if self.peek()[1] == "(":
                self.take()
                args = [self.parse_or()]
                while self.peek()[1] == ",":
                    self.take()
                    args.append(self.parse_or())
                self.expect(")")
                if text not in FUNCTIONS:
                    known = ", ".join(sorted(FUNCTIONS))
                    raise ExprError(f"unknown function {text!r} (known: {known})", col)
                if len(args) != FUNCTIONS[text][0]:
                    raise ExprError(f"{text}() takes {FUNCTIONS[text][0]} argument(s), "
                                    f"got {len(args)}", col)
                return Node("call", name=text, args=tuple(args), column=col)
            return Node("var", name=text, column=col)
        if text == "(":
            inner = self.parse_or()
            self.expect(")")
            return inner
        got = "end of expression" if kind == "end" else repr(text)
        raise ExprError(f"expected a number, a name or '(', got {got}", col)


def parse_expr(text: str, *, column: int = 1) -> Node:
    """Parse ``text`` into a :class:`Node` tree.

    Parameters
    ----------
    text : str
    column : int
        Column of ``text``'s first character in its line, so errors point into the file.

    Raises
    ------
    ExprError
        With the 1-based column of the offending token.
    """
    p = _Parser(text, column)
    if p.peek()[0] == "end":
        raise ExprError("empty expression", column)
    node = p.parse_or()
    kind, tok, col = p.peek()
    if kind != "end":
        raise ExprError(f"unexpected {tok!r} after a complete expression", col)
    return node


def names_in(node: Node) -> set[str]:
    """Variable names a tree refers to."""
    if node.kind == "var":
        return {node.name}
    out: set[str] = set()
    for a in node.args:
        out |= names_in(a)
    return out


def to_text(node: Node) -> str:
    """Print a tree fully parenthesised; ``parse_expr(to_text(t))`` evaluates like ``t``."""
    if node.kind == "num":
        return repr(node.value)
    if node.kind == "var":
        return node.name
    if node.kind == "call":
        return f"{node.name}({', '.join(to_text(a) for a in node.args)})"
    if node.kind == "unary":
        return f"({node.op}{to_text(node.args[0])})"
    return f"({to_text(node.args[0])} {node.op} {to_text(node.args[1])})"


def _lookup(node: Node, env):
    if node.name in env:
        return env[node.name]
    if node.name in CONSTANTS:
        return CONSTANTS[node.name]
    raise ExprError(f"unknown name {node.name!r}", node.column)


_CMP = {"<": np.less, "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal,
        "==": np.equal, "!=": np.not_equal}


def evaluate(node: Node, env: dict) -> float:
    """Evaluate on scalars; ``env`` maps names to floats.

    Raises
    ------
    ExprError
        Unknown name, division by zero, or a math domain error (with the column).
    """
    k = node.kind
    if k == "num":
        return node.value
    if k == "var":
        return float(_lookup(node, env))
    if k == "call":
        try:
            return float(FUNCTIONS[node.name][1](*(evaluate(a, env) for a in node.args)))
        except (ValueError, OverflowError) as exc:
            raise ExprError(f"{node.name}(): {exc}", node.column) from None
    if k == "unary":
        v = evaluate(node.args[0], env)
        return -v if node.op == "-" else float(v == 0.0)
    op = node.op
    a = evaluate(node.args[0], env)
    if op == "&&":
        return float(a != 0.0 and evaluate(node.args[1], env) != 0.0)
    if op == "||":
        return float(a != 0.0 or evaluate(node.args[1], env) != 0.0)
    b = evaluate(node.args[1], env)
    if op in ("+", "-", "*", "/", "%"):
        if op in ("/", "%") and b == 0.0:
            raise ExprError("division by zero", node.column)
        r = (a + b if op == "+" else a - b if op == "-" else a * b if op == "*"
             else a / b if op == "/" else math.fmod(a, b))
        if not math.isfinite(r) and math.isfinite(a) and math.isfinite(b):
            raise ExprError(f"{op}: result is not a finite number (overflow)", node.column)
        return r
    if op == "^":
        try:
            r = a ** b
        except (OverflowError, ZeroDivisionError) as exc:
            raise ExprError(f"power: {exc}", node.column) from None
        if isinstance(r, complex):
            raise ExprError("power of a negative number to a fractional exponent", node.column)
        return float(r)
    return float(_CMP[op](a, b))


_ARITH = {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide, "%": np.fmod}


def evaluate_array(node: Node, env: dict, n: int) -> np.ndarray:
    """Evaluate column-wise: ``env`` maps names to ``(n,) float64`` arrays (or scalars).

    Returns ``(n,) float64``. ``&&`` and ``||`` short-circuit per element, so
    ``x > 0 && 1 / x > 2`` never divides by a zero ``x``.
    """
    out = _eval_arr(node, env, n)
    if np.ndim(out) == 0:
        return np.full(n, float(out))
    return out


def _eval_arr(node: Node, env: dict, n: int):
    k = node.kind
    if k == "num":
        return node.value
    if k == "var":
        return _lookup(node, env)
    if k == "call":
        args = [_eval_arr(a, env, n) for a in node.args]
        with np.errstate(all="ignore"):
            r = FUNCTIONS[node.name][2](*args)
        _check_finite(r, args, node)
        return r
    if k == "unary":
        v = _eval_arr(node.args[0], env, n)
        return -v if node.op == "-" else (np.asarray(v) == 0.0).astype(np.float64)
    op = node.op
    if op in ("&&", "||"):
        a = np.broadcast_to(np.asarray(_eval_arr(node.args[0], env, n), np.float64), (n,)) != 0
        need = a if op == "&&" else ~a
        out = a.astype(np.float64) if op == "||" else np.zeros(n)
        idx = np.flatnonzero(need)
        if len(idx):
            sub = {key: (val[idx] if np.ndim(val) else val) for key, val in env.items()}
            b = np.broadcast_to(np.asarray(_eval_arr(node.args[1], sub, len(idx)), np.float64),
                                (len(idx),))
            out[idx] = (b != 0).astype(np.float64)
        return out
    a = _eval_arr(node.args[0], env, n)
    b = _eval_arr(node.args[1], env, n)
    if op in ("+", "-", "*", "/", "%"):
        if op in ("/", "%") and np.any(np.asarray(b) == 0.0):
            raise ExprError("division by zero", node.column)
        with np.errstate(all="ignore"):
            r = _ARITH[op](a, b)
        _check_finite(r, (a, b), node)  # overflow to infinity: an error, not a silent inf
        return r
    if op == "^":
        with np.errstate(all="ignore"):
            r = np.power(np.asarray(a, np.float64), b)
        _check_finite(r, (a, b), node)
        return r
    return _CMP[op](a, b).astype(np.float64)


def _check_finite(result, args, node):
    if np.all(np.isfinite(result)):
        return
    if all(np.all(np.isfinite(a)) for a in args):
        raise ExprError(f"{node.name or node.op}: result is not a finite number "
                        "(domain error or overflow)", node.column)
