"""The L-system grammar text format: parsing into a :class:`Grammar`.

The format is documented in ``docs/lsystem.md``; in short::

    # ABOP Fig. 1.24a
    angle: 25.7
    n: 5
    axiom: F
    F -> F[+F]F[-F]F

Directives are ``key: value`` lines (see :data:`DIRECTIVES`); productions are
``[left <] pred [> right] [: condition] -> successor``, stochastic ones use the arrow
``-(p)->``. Symbols are single printable ASCII characters; a module is a symbol with
an optional parameter list ``A(x, y)``. Comments start with ``#``.

Every error is a :class:`GrammarError` naming the file, line and column.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from core.validate import InputError
from procgen.lsystem.expr import ExprError, Node, evaluate, parse_expr

__all__ = ["GrammarError", "Module", "Pattern", "Production", "Grammar", "parse_grammar",
           "load_grammar", "example_names", "TURTLE_SYMBOLS", "CUT", "DIRECTIVES"]

TURTLE_SYMBOLS = "FfG+-&^\\/|[]!'{}.$"
"""Symbols the turtle interprets (see :mod:`procgen.lsystem.turtle`)."""

CUT = "%"
"""The cut symbol: at the end of every derivation step, ``%`` and the rest of its branch
(up to the ``]`` that closes it, or the end of the string) are removed (ABOP p. 73)."""

_ONE_ARG = set("FfG+-&^\\/!'")
_RESERVED = set("()<>,:;#")

DIRECTIVES = {
    "axiom": "the starting string (required)",
    "n": "number of derivation steps (default 0)",
    "angle": "turning angle in degrees for + - & ^ \\ / (default 90); an expression",
    "step": "length of F, f, G without a parameter (default 1)",
    "width": "initial segment width (default 0.1)",
    "width_factor": "factor applied to the width by ! without a parameter (default 0.7)",
    "tropism": "x, y, z, e: bend each F toward (x, y, z) by e |H x T| (default none)",
    "ignore": "symbols skipped when matching contexts",
    "draw": "extra symbols drawn like F (e.g. the L and R of a dragon curve)",
    "move": "extra symbols that move like f",
    "symbols": "extra constant symbols (no production, no turtle meaning)",
    "define": "NAME = expression: a named constant usable in every expression",
}

_EXAMPLES = Path(__file__).with_name("examples")


class GrammarError(InputError):
    """A grammar error pinned to ``path``, ``line`` and ``column`` (1-based)."""

    def __init__(self, message: str, *, path=None, line: int | None = None,
                 column: int | None = None):
        self.line = line
        self.column = column
        where = None
        if line is not None:
            where = f"line {line}" + (f", column {column}" if column is not None else "")
        super().__init__(message, path=path if path is not None else "<grammar>", field=where)


@dataclass(frozen=True)
class Module:
    """A module of an axiom or successor: a symbol and its argument expressions."""

    symbol: str
    args: tuple[Node, ...] = ()
    column: int = 1


@dataclass(frozen=True)
class Pattern:
    """A module of a predecessor or context: a symbol and its formal parameter names."""

    symbol: str
    params: tuple[str, ...] = ()
    column: int = 1


@dataclass
class Production:
    """One production ``left < predecessor > right : condition -(probability)-> successor``."""

    predecessor: Pattern
    successor: tuple[Module, ...]
    left: tuple[Pattern, ...] = ()
    right: tuple[Pattern, ...] = ()
    condition: Node | None = None
    probability: float | None = None
    line: int = 0
    key: str = ""

    @property
    def variables(self) -> set[str]:
        out = set(self.predecessor.params)
        for p in self.left + self.right:
            out |= set(p.params)
        return out


@dataclass
class Grammar:
    """A parsed L-system.

    Attributes
    ----------
    axiom : tuple of Module
        Argument expressions are constant (already checked to evaluate).
    productions : list of Production
        In file order; the first that applies to a module wins.
    n : int
        Default number of derivation steps.
    angle : float
        Degrees.
    """

    axiom: tuple[Module, ...]
    productions: list[Production]
    n: int = 0
    angle: float = 90.0
    step: float = 1.0
    width: float = 0.1
    width_factor: float = 0.7
    tropism: tuple[float, float, float, float] | None = None
    ignore: frozenset = frozenset()
    draw: str = ""
    move: str = ""
    symbols: str = ""
    defines: dict = field(default_factory=dict)
    source: str | None = None

    @property
    def is_parametric(self) -> bool:
        return any(m.args for m in self.axiom) or any(
            p.predecessor.params or p.condition is not None or any(m.args for m in p.successor)
            for p in self.productions)

    @property
    def is_stochastic(self) -> bool:
        return any(p.probability is not None for p in self.productions)

    @property
    def has_cut(self) -> bool:
        """Whether the cut symbol ``%`` can appear in a derived string."""
        return any(m.symbol == CUT for m in self.axiom) or any(
            m.symbol == CUT for p in self.productions for m in p.successor)

    @property
    def is_context_sensitive(self) -> bool:
        return any(p.left or p.right for p in self.productions)

    @property
    def classes(self) -> tuple[str, ...]:
        """L-system classes this grammar belongs to, e.g. ``('D0L', 'bracketed')``."""
        out = []
        if self.is_context_sensitive:
            two = any(p.left and p.right for p in self.productions)
            out.append("2L" if two else "1L")
        else:
            out.append("0L")
        if not self.is_stochastic and not self.is_context_sensitive and not self.is_parametric:
            out[0] = "D0L"
        if self.is_stochastic:
            out.append("stochastic")
        if self.is_parametric:
            out.append("parametric")
        if any(m.symbol == "[" for m in self.axiom) or any(
                m.symbol == "[" for p in self.productions for m in p.successor):
            out.append("bracketed")
        return tuple(out)

    def max_arity(self) -> int:
        mods = list(self.axiom) + [m for p in self.productions for m in p.successor]
        return max((len(m.args) for m in mods), default=0)


# --------------------------------------------------------------------------- parsing


_DIRECTIVE = re.compile(r"^\s*([A-Za-z_][A-Za-z_0-9]*)\s*:(.*)$")
_STOCH_ARROW = re.compile(r"-\(([^()]*)\)->")


class _Ctx:
    def __init__(self, path, lineno):
        self.path = path
        self.line = lineno

    def error(self, message, column=None):
        return GrammarError(message, path=self.path, line=self.line, column=column)


def _strip_comment(line: str) -> str:
    i = line.find("#")
    return line if i < 0 else line[:i]


def _check_symbol(ch: str, col: int, ctx: _Ctx):
    if not (33 <= ord(ch) <= 126) or ch in _RESERVED:
        raise ctx.error(f"{ch!r} cannot be a symbol (symbols are single printable ASCII "
                        "characters other than ( ) < > , : ; #)", col)


def _split_args(text: str, start: int, ctx: _Ctx,
                offset: int = 0) -> tuple[list[tuple[str, int]], int]:
    """``text[start] == '('``: return [(arg text, column)], index after ')'."""
    depth = 0
    args = []
    begin = start + 1
    for i in range(start, len(text)):
        c = text[i]
        if c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
            if depth == 0:
                args.append((text[begin:i], begin))
                return args, i + 1
        elif c == "," and depth == 1:
            args.append((text[begin:i], begin))
            begin = i + 1
    raise ctx.error("unbalanced '(': missing ')'", offset + start + 1)


def _parse_modules(text: str, offset: int, ctx: _Ctx) -> tuple[Module, ...]:
    """Parse a successor/axiom string; ``offset`` is the 0-based column of ``text[0]``."""
    out = []
    i = 0
    while i < len(text):
        c = text[i]
        if c.isspace():
            i += 1
            continue
        col = offset + i + 1
        _check_symbol(c, col, ctx)
        args: tuple[Node, ...] = ()
        i += 1
        if i < len(text) and text[i] == "(":
            raw, i = _split_args(text, i, ctx, offset)
            nodes = []
            for arg, start in raw:
                try:
                    nodes.append(parse_expr(arg, column=offset + start + 1))
                except ExprError as exc:
                    raise ctx.error(exc.message, exc.column) from None
            args = tuple(nodes)
        out.append(Module(c, args, col))
    return tuple(out)


def _parse_patterns(text: str, offset: int, ctx: _Ctx, *, brackets: bool) -> tuple[Pattern, ...]:
    out = []
    i = 0
    while i < len(text):
        c = text[i]
        if c.isspace():
            i += 1
            continue
        col = offset + i + 1
        _check_symbol(c, col, ctx)
        if c in "[]" and not brackets:
            raise ctx.error(f"{c!r} is not allowed here (brackets only in a right context)", col)
        params: tuple[str, ...] = ()
        i += 1
        if i < len(text) and text[i] == "(":
            raw, i = _split_args(text, i, ctx, offset)
            names = []
            for arg, start in raw:
                name = arg.strip()
                if not re.fullmatch(r"[A-Za-z_][A-Za-z_0-9]*", name):
                    raise ctx.error(f"expected a parameter name, got {arg.strip()!r}",
                                    offset + start + 1)
                names.append(name)
            params = tuple(names)
        out.append(Pattern(c, params, col))
    return tuple(out)


def _split_depth0(text: str, chars: str) -> int:
    depth = 0
    for i, c in enumerate(text):
        if c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
        elif depth == 0 and c in chars:
            return i
    return -1


def _const(text: str, col: int, ctx: _Ctx, defines: dict) -> float:
    try:
        v = evaluate(parse_expr(text, column=col), defines)
    except ExprError as exc:
        raise ctx.error(exc.message, exc.column) from None
    if not math.isfinite(v):
        raise ctx.error("expected a finite number", col)
    return v


def _parse_production(line: str, ctx: _Ctx) -> Production:
    prob_text = None
    m = _STOCH_ARROW.search(line)
    if m is not None and line[:m.start()].strip():
        head, succ_text, succ_off = line[:m.start()], line[m.end():], m.end()
        prob_text, prob_col = m.group(1), m.start(1) + 1
    else:
        idx = line.find("->")
        head, succ_text, succ_off = line[:idx], line[idx + 2:], idx + 2
    condition = None
    ci = _split_depth0(head, ":")
    lhs = head
    if ci >= 0:
        lhs = head[:ci]
        cond_text = head[ci + 1:]
        try:
            condition = parse_expr(cond_text, column=ci + 2)
        except ExprError as exc:
            raise ctx.error(f"condition: {exc.message}", exc.column) from None
    left: tuple[Pattern, ...] = ()
    right: tuple[Pattern, ...] = ()
    pred_off = 0
    li = _split_depth0(lhs, "<")
    if li >= 0:
        left = _parse_patterns(lhs[:li], 0, ctx, brackets=False)
        if not left:
            raise ctx.error("empty left context before '<'", li + 1)
        pred_off = li + 1
    rest = lhs[pred_off:]
    ri = _split_depth0(rest, ">")
    pred_text = rest
    if ri >= 0:
        pred_text = rest[:ri]
        right = _parse_patterns(rest[ri + 1:], pred_off + ri + 1, ctx, brackets=True)
        if not right:
            raise ctx.error("empty right context after '>'", pred_off + ri + 1)
    preds = _parse_patterns(pred_text, pred_off, ctx, brackets=False)
    if len(preds) != 1:
        col = preds[1].column if len(preds) > 1 else pred_off + 1
        raise ctx.error(f"expected exactly one predecessor module, got {len(preds)}", col)
    probability = None
    if prob_text is not None:
        probability = _const(prob_text, prob_col, ctx, {})
        if not 0.0 <= probability <= 1.0:
            raise ctx.error(f"probability must be in [0, 1], got {probability:g}", prob_col)
    successor = _parse_modules(succ_text, succ_off, ctx)
    key = "|".join([_pat_key(left), _pat_key(preds), _pat_key(right),
                    "" if condition is None else re.sub(r"\s+", "", head[ci + 1:])])
    prod = Production(preds[0], successor, left, right, condition, probability, ctx.line, key)
    seen: set[str] = set()
    for pat in left + preds + right:
        for name in pat.params:
            if name in seen:
                raise ctx.error(f"parameter {name!r} is bound twice", pat.column)
            seen.add(name)
    return prod


def _check_names(node: Node, known: set, ctx: _Ctx, defines: dict | None = None):
    from procgen.lsystem.expr import CONSTANTS

    def walk(nd):
        if nd.kind == "var" and nd.name not in known and nd.name not in CONSTANTS and (
                defines is None or nd.name not in defines):
            raise ctx.error(f"unknown name {nd.name!r} (not a parameter of the predecessor or "
                            "its context, nor a constant)", nd.column)
        for a in nd.args:
            walk(a)

    walk(node)


def _pat_key(pats) -> str:
    return "".join(p.symbol + str(len(p.params)) for p in pats)


def parse_grammar(text: str, *, source: str | os.PathLike | None = None) -> Grammar:
    """Parse grammar ``text`` (the format of ``docs/lsystem.md``).

    Parameters
    ----------
    text : str
    source : path-like, optional
        Named in error messages.

    Raises
    ------
    GrammarError
        Syntax errors, unknown symbols or names, probabilities that do not sum to 1,
        with file, line and column.

    Examples
    --------
    >>> g = parse_grammar("angle: 25.7\\nn: 5\\naxiom: F\\nF -> F[+F]F[-F]F")
    >>> g.n, g.classes
    (5, ('D0L', 'bracketed'))
    """
    path = None if source is None else str(source)
    values: dict = {}
    seen_lines: dict = {}
    defines: dict = {}
    productions: list[Production] = []
    axiom_line = None
    for lineno, raw in enumerate(text.splitlines(), start=1):
        ctx = _Ctx(path, lineno)
        line = _strip_comment(raw).rstrip()
        if not line.strip():
            continue
        m = _DIRECTIVE.match(line)
        if m is not None and "->" not in line:
            key, value = m.group(1), m.group(2)
            vcol = m.start(2) + 1
            if key not in DIRECTIVES:
                listed = ", ".join(sorted(DIRECTIVES))
                raise ctx.error(f"unknown directive {key!r} (known: {listed})", m.start(1) + 1)
            if key != "define" and key in seen_lines:
                raise ctx.error(f"directive {key!r} given twice (first on line "
                                f"{seen_lines[key]})", m.start(1) + 1)
            seen_lines[key] = lineno
            if key == "define":
                dm = re.fullmatch(r"\s*([A-Za-z_][A-Za-z_0-9]*)\s*=(.*)", value)
                if dm is None:
                    raise ctx.error("expected 'define: NAME = expression'", vcol)
                defines[dm.group(1)] = _const(dm.group(2), vcol + dm.start(2), ctx, defines)
            elif key == "axiom":
                values["axiom"] = _parse_modules(value, vcol - 1, ctx)
                axiom_line = lineno
                if not values["axiom"]:
                    raise ctx.error("empty axiom", vcol)
            elif key in ("ignore", "draw", "move", "symbols"):
                syms = "".join(value.split())
                for i, ch in enumerate(syms):
                    _check_symbol(ch, vcol + value.find(ch) if ch in value else vcol + i, ctx)
                values[key] = syms
            elif key == "tropism":
                parts = value.split(",")
                if len(parts) != 4:
                    raise ctx.error("expected 'tropism: x, y, z, e'", vcol)
                vals, col = [], vcol
                for part in parts:
                    vals.append(_const(part, col, ctx, defines))
                    col += len(part) + 1
                if math.hypot(*vals[:3]) == 0.0:
                    raise ctx.error("tropism direction must be non-zero", vcol)
                values["tropism"] = tuple(vals)
            else:
                v = _const(value, vcol, ctx, defines)
                if key == "n":
                    if v != int(v) or v < 0:
                        raise ctx.error(f"n must be a non-negative integer, got {v:g}", vcol)
                    v = int(v)
                elif key in ("step", "width") and v < 0:
                    raise ctx.error(f"{key} must be >= 0, got {v:g}", vcol)
                values[key] = v
            continue
        if "->" not in line:
            raise ctx.error("expected a directive 'key: value' or a production "
                            "'predecessor -> successor'", len(line) - len(line.lstrip()) + 1)
        productions.append(_parse_production(line, ctx))
    if "axiom" not in values:
        raise GrammarError("missing 'axiom:' directive", path=path)
    g = Grammar(axiom=values["axiom"], productions=productions, n=values.get("n", 0),
                angle=values.get("angle", 90.0), step=values.get("step", 1.0),
                width=values.get("width", 0.1), width_factor=values.get("width_factor", 0.7),
                tropism=values.get("tropism"), ignore=frozenset(values.get("ignore", "")),
                draw=values.get("draw", ""), move=values.get("move", ""),
                symbols=values.get("symbols", ""), defines=defines, source=path)
    _validate(g, path, axiom_line)
    return g


def _validate(g: Grammar, path, axiom_line):
    # constants in productions: substitute-free check that every name is known
    for p in g.productions:
        ctx = _Ctx(path, p.line)
        known = p.variables | set(g.defines)
        if p.condition is not None:
            _check_names(p.condition, known, ctx)
        for m in p.successor:
            for a in m.args:
                _check_names(a, known, ctx)
    ax_ctx = _Ctx(path, axiom_line)
    for m in g.axiom:
        for a in m.args:
            _check_names(a, set(), ax_ctx, g.defines)
            try:
                evaluate(a, g.defines)
            except ExprError as exc:
                raise ax_ctx.error(exc.message, exc.column) from None
    preds = {p.predecessor.symbol for p in g.productions}
    known = set(TURTLE_SYMBOLS) | {CUT} | preds | set(g.draw) | set(g.move) | set(g.symbols)
    arity: dict[str, tuple[int, int]] = {}
    for p in g.productions:
        prev = arity.get(p.predecessor.symbol)
        k = len(p.predecessor.params)
        if prev is not None and prev[0] != k:
            raise _Ctx(path, p.line).error(
                f"{p.predecessor.symbol!r} has {k} parameter(s) here but {prev[0]} on line "
                f"{prev[1]}", p.predecessor.column)
        arity.setdefault(p.predecessor.symbol, (k, p.line))

    def check_module(sym, nargs, line, col, where):
        ctx = _Ctx(path, line)
        if sym not in known:
            raise ctx.error(f"unknown symbol {sym!r} in {where}: no production, no turtle "
                            f"meaning; declare constants with 'symbols: {sym}'", col)
        if sym in arity and arity[sym][0] != nargs:
            raise ctx.error(f"{sym!r} takes {arity[sym][0]} parameter(s) (line {arity[sym][1]})"
                            f", got {nargs}", col)
        if sym in TURTLE_SYMBOLS and sym not in arity:
            limit = 1 if sym in _ONE_ARG else 0
            if nargs > limit:
                raise ctx.error(f"turtle symbol {sym!r} takes at most {limit} parameter(s), "
                                f"got {nargs}", col)

    for m in g.axiom:
        check_module(m.symbol, len(m.args), axiom_line, m.column, "the axiom")
    for p in g.productions:
        for m in p.successor:
            check_module(m.symbol, len(m.args), p.line, m.column, "a successor")
        for c in p.left + p.right:
            if c.symbol not in "[]":
                check_module(c.symbol, len(c.params), p.line, c.column, "a context")
        _check_brackets(p.successor, _Ctx(path, p.line))
    _check_brackets(g.axiom, ax_ctx)
    _check_groups(g, path)


def _check_brackets(mods, ctx):
    """Every ']' closes a '[' and every '[' is closed, in the same string: a branch is
    never left open for the derivation to guess where it ends."""
    opened = []
    for m in mods:
        if m.symbol == "[":
            opened.append(m.column)
        elif m.symbol == "]":
            if not opened:
                raise ctx.error("']' without a matching '['", m.column)
            opened.pop()
    if opened:
        raise ctx.error(f"unbalanced brackets: {len(opened)} '[' never closed with ']'",
                        opened[-1])


def _check_groups(g: Grammar, path):
    groups: dict[str, list[Production]] = {}
    for p in g.productions:
        groups.setdefault(p.key, []).append(p)
    for prods in groups.values():
        stoch = [p for p in prods if p.probability is not None]
        if stoch and len(stoch) != len(prods):
            p = next(p for p in prods if p.probability is None)
            raise _Ctx(path, p.line).error(
                "a production without probability has the same predecessor, context and "
                f"condition as the stochastic production on line {stoch[0].line}")
        if stoch:
            total = sum(p.probability for p in stoch)
            if abs(total - 1.0) > 1e-6:
                lines = ", ".join(str(p.line) for p in stoch)
                raise _Ctx(path, stoch[0].line).error(
                    f"probabilities of {stoch[0].predecessor.symbol!r} (lines {lines}) sum to "
                    f"{total:.6g}, expected 1")
        elif len(prods) > 1:
            raise _Ctx(path, prods[1].line).error(
                f"duplicate production: line {prods[0].line} has the same predecessor, context "
                "and condition, so this one never applies")


def example_names() -> list[str]:
    """Names of the grammar files shipped in ``procgen/lsystem/examples``."""
    return sorted(p.stem for p in _EXAMPLES.glob("*.lsys"))


def load_grammar(name_or_path: str | os.PathLike) -> Grammar:
    """Load a grammar file, or a shipped example by name (see :func:`example_names`).

    Raises
    ------
    InputError
        The file is missing (the message lists the examples) or the grammar is bad.
    """
    path = Path(name_or_path)
    if not path.is_file():
        candidate = _EXAMPLES / f"{name_or_path}.lsys"
        if candidate.is_file():
            path = candidate
        else:
            raise InputError("no such grammar file or example (examples: "
                             f"{', '.join(example_names())})", path=name_or_path)
    try:
        text = path.read_text()
    except UnicodeDecodeError:
        raise InputError("not a text file", path=path) from None
    return parse_grammar(text, source=path)
