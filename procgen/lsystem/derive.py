"""Derivation: rewriting an axiom ``n`` times with a grammar's productions.

Strings are arrays: one ``uint8`` ASCII code per module, plus a ``(n, k) float64``
parameter table for parametric grammars. Three engines, chosen automatically:

- **D0L** (deterministic, context-free, non-parametric): the expansion of every symbol
  after ``k`` steps is built from the expansions after ``k - 1`` steps by block copies
  (``h^k(a) = h^(k-1)(h(a))``), so derivation runs at memory-copy speed.
- **stochastic 0L** (non-parametric): one compiled pass per step chooses a production per
  module from one uniform draw and copies the successors.
- **general** (parametric, context-sensitive, or both): per predecessor symbol, all its
  modules are processed at once; conditions and successor parameters are evaluated
  column-wise with :func:`procgen.lsystem.expr.evaluate_array`, contexts are matched
  bracket-aware in a compiled kernel.

The cut symbol ``%`` (:data:`procgen.lsystem.grammar.CUT`) is applied at the end of every
step by :func:`_cut_keep`; grammars that can produce it skip the D0L engine (whose block
copies would only cut at the end). Growth is checked before each step allocates:
:class:`GrowthLimitError` instead of a hang.
:func:`derive_reference` is a plain per-module Python engine kept as the tests' oracle.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numba
import numpy as np

from procgen.lsystem.expr import ExprError, evaluate, evaluate_array
from procgen.lsystem.grammar import Grammar, GrammarError, Production

__all__ = ["LString", "GrowthLimitError", "derive", "derive_reference", "axiom_string",
           "MAX_SYMBOLS", "MAX_BYTES", "MAX_STEPS"]

_log = logging.getLogger(__name__)

MAX_SYMBOLS = 50_000_000
"""Default limit on the number of modules of a derived string."""
MAX_BYTES = 2_000_000_000
"""Default limit on the memory of a derived string (codes plus parameters)."""
MAX_STEPS = 10_000
"""Default limit on ``n``."""

_LB, _RB = ord("["), ord("]")


class GrowthLimitError(ValueError):
    """A derivation would exceed its symbol or memory limit (runaway growth)."""


@dataclass
class LString:
    """A derived string.

    Attributes
    ----------
    codes : (n,) uint8
        ASCII code of each module's symbol.
    params : (n, k) float64 or None
        Parameters, NaN where a module has fewer than ``k``; ``None`` when non-parametric.
    nparams : (n,) uint8 or None
        Number of parameters of each module.
    """

    codes: np.ndarray
    params: np.ndarray | None = None
    nparams: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.codes)

    @property
    def symbols(self) -> str:
        """The symbols without parameters, e.g. ``'F[+F]F'``."""
        return self.codes.tobytes().decode("ascii")

    def text(self, *, digits: int = 6) -> str:
        """The string with parameters, e.g. ``'A(1,2.5)F(1)'``."""
        if self.params is None:
            return self.symbols
        out = []
        for c, k, row in zip(self.codes, self.nparams, self.params, strict=False):
            out.append(chr(c))
            if k:
                out.append("(" + ",".join(f"{v:.{digits}g}" for v in row[:k]) + ")")
        return "".join(out)

    def counts(self) -> dict[str, int]:
        """Number of modules of each symbol."""
        bc = np.bincount(self.codes, minlength=128)
        return {chr(i): int(bc[i]) for i in np.flatnonzero(bc)}


def axiom_string(grammar: Grammar) -> LString:
    """The axiom as an :class:`LString` (arguments evaluated with the grammar's defines)."""
    codes = np.frombuffer("".join(m.symbol for m in grammar.axiom).encode("ascii"),
                          dtype=np.uint8).copy()
    k = grammar.max_arity()
    if not grammar.is_parametric:
        return LString(codes)
    params = np.full((len(codes), max(k, 1)), np.nan)
    nparams = np.zeros(len(codes), np.uint8)
    for i, m in enumerate(grammar.axiom):
        nparams[i] = len(m.args)
        for j, a in enumerate(m.args):
            params[i, j] = evaluate(a, grammar.defines)
    return LString(codes, params, nparams)


def _limits(total: int, width: int, step: int, n: int, max_symbols: int, max_bytes: int):
    nbytes = total * (1 + (1 + 8 * width if width else 0))
    if total > max_symbols or nbytes > max_bytes:
        raise GrowthLimitError(
            f"derivation step {step} of {n} would produce {total:,} modules "
            f"({nbytes / 1e6:,.0f} MB); limits are max_symbols={max_symbols:,} and "
            f"max_bytes={max_bytes:,}: lower n or raise the limits")


def derive(grammar: Grammar, n: int | None = None, *, rng: np.random.Generator | None = None,
           max_symbols: int = MAX_SYMBOLS, max_bytes: int = MAX_BYTES,
           method: str = "auto") -> LString:
    """Rewrite the axiom ``n`` times.

    Parameters
    ----------
    grammar : Grammar
    n : int, optional
        Number of steps; the grammar's ``n`` when omitted.
    rng : numpy.random.Generator, optional
        Required for stochastic grammars.
    max_symbols, max_bytes : int
        Growth limits checked before every step allocates.
    method : {'auto', 'general'}
        ``'general'`` forces the general engine (tests compare it with the fast ones).

    Returns
    -------
    LString

    Raises
    ------
    GrowthLimitError
        The string would exceed a limit.
    ValueError
        A stochastic grammar without ``rng``; an expression error while rewriting (division
        by zero), naming the grammar line.
    """
    from core.validate import check_choice

    check_choice(method, "method", {"auto", "general"})
    n = grammar.n if n is None else int(n)
    if n < 0 or n > MAX_STEPS:
        raise ValueError(f"n: expected an integer in [0, {MAX_STEPS}], got {n}")
    if grammar.is_stochastic and rng is None:
        raise ValueError("rng: a stochastic grammar needs a numpy.random.Generator")
    s = axiom_string(grammar)
    _limits(len(s), grammar.max_arity() if grammar.is_parametric else 0, 0, n, max_symbols,
            max_bytes)
    if n == 0:
        return s
    simple = not grammar.is_parametric and not grammar.is_context_sensitive
    if method == "auto" and simple and not grammar.is_stochastic and not grammar.has_cut:
        return _derive_d0l(grammar, s, n, max_symbols, max_bytes)
    if method == "auto" and simple:
        return _derive_stochastic(grammar, s, n, rng, max_symbols, max_bytes)
    return _derive_general(grammar, s, n, rng, max_symbols, max_bytes)


# --------------------------------------------------------------------------- D0L


def _successor_codes(p: Production) -> np.ndarray:
    return np.frombuffer("".join(m.symbol for m in p.successor).encode("ascii"),
                         dtype=np.uint8).copy()


def _derive_d0l(grammar, s, n, max_symbols, max_bytes) -> LString:
    succ = {ord(p.predecessor.symbol): _successor_codes(p) for p in grammar.productions}
    # lengths after k steps, per symbol (floats: no overflow, exact below 2**53)
    length = np.ones(128)
    reach = set(np.unique(s.codes).tolist())
    frontier = list(reach)
    while frontier:
        a = frontier.pop()
        for b in np.unique(succ.get(a, np.empty(0, np.uint8))).tolist():
            if b not in reach:
                reach.add(b)
                frontier.append(b)
    for step in range(1, n + 1):
        new = length.copy()
        for a, sc in succ.items():
            new[a] = length[sc].sum()
        length = new
        total = length[s.codes].sum()
        _limits(int(min(total, 2**62)), 0, step, n, max_symbols, max_bytes)
    # expansions level by level, by block copies
    exp = {a: np.array([a], np.uint8) for a in reach}
    for step in range(1, n + 1):
        last = step == n
        targets = np.unique(s.codes).tolist() if last else reach
        new = {}
        for a in targets:
            if a in succ:
                sc = succ[a]
                new[a] = (np.concatenate([exp[b] for b in sc.tolist()]) if len(sc)
                          else np.empty(0, np.uint8))
            else:
                new[a] = exp[a]
        exp = new
    if len(s.codes) == 1:
        a = int(s.codes[0])
        return LString(exp[a] if a in succ else exp[a].copy())
    return LString(np.concatenate([exp[a] for a in s.codes.tolist()]))


# --------------------------------------------------------------------------- stochastic 0L


@numba.njit(cache=True)
def _choose(codes, u, first, count, cumprob, succ_len):
    n = len(codes)
    choice = np.empty(n, np.int32)
    total = 0
    for i in range(n):
        c = codes[i]
        k = count[c]
        if k == 0:
            choice[i] = -1
            total += 1
            continue
        r = first[c]
        end = r + k - 1
        while r < end and u[i] >= cumprob[r]:
            r += 1
        choice[i] = r
        total += succ_len[r]
    return choice, total


@numba.njit(cache=True)
def _fill(codes, choice, total, succ_off, succ_flat):
    out = np.empty(total, np.uint8)
    j = 0
    for i in range(len(codes)):
        r = choice[i]
        if r < 0:
            out[j] = codes[i]
            j += 1
        else:
            for t in range(succ_off[r], succ_off[r + 1]):
                out[j] = succ_flat[t]
                j += 1
    return out


def _stochastic_tables(grammar):
    by_sym: dict[int, list[Production]] = {}
    for p in grammar.productions:
        by_sym.setdefault(ord(p.predecessor.symbol), []).append(p)
    first = np.zeros(128, np.int64)
    count = np.zeros(128, np.int64)
    cum, lens, flat = [], [], []
    for a in sorted(by_sym):
        prods = by_sym[a]
        first[a] = len(cum)
        count[a] = len(prods)
        acc = 0.0
        for p in prods:
            acc += 1.0 if p.probability is None else p.probability
            cum.append(acc)
            sc = _successor_codes(p)
            lens.append(len(sc))
            flat.append(sc)
        cum[-1] = np.inf  # the last choice takes whatever rounding leaves
    succ_len = np.array(lens, np.int64)
    succ_off = np.concatenate([[0], np.cumsum(succ_len)]).astype(np.int64)
    succ_flat = np.concatenate(flat) if flat else np.empty(0, np.uint8)
    return first, count, np.array(cum, np.float64), succ_len, succ_off, succ_flat


def _derive_stochastic(grammar, s, n, rng, max_symbols, max_bytes) -> LString:
    first, count, cum, succ_len, succ_off, succ_flat = _stochastic_tables(grammar)
    codes = s.codes
    cut = grammar.has_cut
    if rng is None:  # a deterministic grammar with cuts: no draw decides anything
        rng = np.random.default_rng(0)
    for step in range(1, n + 1):
        u = rng.random(len(codes))
        choice, total = _choose(codes, u, first, count, cum, succ_len)
        _limits(int(total), 0, step, n, max_symbols, max_bytes)
        codes = _fill(codes, choice, total, succ_off, succ_flat)
        if cut:
            codes = codes[_cut_keep(codes)]
    return LString(codes)


# --------------------------------------------------------------------------- cut


@numba.njit(cache=True)
def _cut_keep(codes):
    """Mask of the modules kept when every ``%`` cuts the rest of its branch: from the
    ``%`` up to (not including) the ``]`` that closes its branch, or to the end."""
    n = len(codes)
    keep = np.ones(n, np.bool_)
    i = 0
    while i < n:
        if codes[i] == 37:
            depth = 0
            while i < n:
                c = codes[i]
                if c == 91:
                    depth += 1
                elif c == 93:
                    if depth == 0:
                        break
                    depth -= 1
                keep[i] = False
                i += 1
        else:
            i += 1
    return keep


# --------------------------------------------------------------------------- contexts


@numba.njit(cache=True)
def _bracket_links(codes):
    """For each '[' the index of its ']' (n - 1 when unclosed); for each ']' its '['."""
    n = len(codes)
    link = np.full(n, -1, np.int64)
    stack = np.empty(n, np.int64)
    top = 0
    for i in range(n):
        c = codes[i]
        if c == 91:
            stack[top] = i
            top += 1
        elif c == 93:
            if top > 0:
                top -= 1
                link[i] = stack[top]
                link[stack[top]] = i
            else:
                link[i] = -1
    for t in range(top):
        link[stack[t]] = n - 1
    return link


@numba.njit(cache=True)
def _match_left(codes, link, ignore, positions, pattern):
    m = len(positions)
    L = len(pattern)
    ok = np.ones(m, np.bool_)
    idx = np.full((m, max(L, 1)), -1, np.int64)
    for q in range(m):
        i = positions[q] - 1
        for j in range(L - 1, -1, -1):
            while i >= 0:
                c = codes[i]
                if ignore[c]:
                    i -= 1
                elif c == 93:
                    i = link[i] - 1 if link[i] >= 0 else i - 1
                elif c == 91:
                    i -= 1
                else:
                    break
            if i < 0 or codes[i] != pattern[j]:
                ok[q] = False
                break
            idx[q, j] = i
            i -= 1
    return ok, idx


def _pattern_links(pattern: np.ndarray) -> np.ndarray:
    """For each '[' of a context pattern the index of its ']' (``len`` when unclosed)."""
    link = np.full(len(pattern), -1, np.int64)
    stack = []
    for j, c in enumerate(pattern.tolist()):
        if c == _LB:
            stack.append(j)
        elif c == _RB and stack:
            link[stack.pop()] = j
    for j in stack:
        link[j] = len(pattern)
    return link


@numba.njit  # no cache: numba's on-disk cache of a recursive function crashes on reload
def _right_seq(codes, link, ignore, i, end, pattern, plink, ps, pe, idx_row, k0):
    """Match ``pattern[ps:pe]`` from ``codes[i]`` inside one branch (``end`` is the index
    of the branch's ']' or ``len(codes)``). Returns (position after the match or -1, number
    of symbol positions recorded in ``idx_row``)."""
    n = len(codes)
    k = k0
    j = ps
    while j < pe:
        pc = pattern[j]
        if pc == 91:
            # a bracketed sub-pattern matches the first of the sibling branches here whose
            # content matches it (ABOP 1.8, extended across several branches: A > [B] also
            # matches A[C][B])
            jend = plink[j]
            while i < end and ignore[codes[i]]:
                i += 1
            found = False
            while i < end and codes[i] == 91:
                bend = link[i] if codes[link[i]] == 93 else n
                r, k2 = _right_seq(codes, link, ignore, i + 1, bend, pattern, plink, j + 1,
                                   min(jend, pe), idx_row, k)
                i = bend + 1
                if r >= 0:
                    k = k2
                    found = True
                    break
                while i < end and ignore[codes[i]]:
                    i += 1
            if not found:
                return -1, k0
            j = jend + 1
            continue
        if pc == 93:
            # an unmatched ']' in the pattern: leave the current branch
            found = False
            while i < n:
                c = codes[i]
                if c == 91:
                    i = link[i] + 1
                elif c == 93:
                    i += 1
                    found = True
                    break
                else:
                    i += 1
            if not found:
                return -1, k0
            j += 1
            continue
        while i < end:
            c = codes[i]
            if ignore[c]:
                i += 1
            elif c == 91:
                i = link[i] + 1
            else:
                break
        if i >= end or codes[i] != pc:
            return -1, k0
        idx_row[k] = i
        k += 1
        i += 1
        j += 1
    return i, k


@numba.njit
def _match_right(codes, link, ignore, positions, pattern, plink, nsym):
    n = len(codes)
    m = len(positions)
    ok = np.ones(m, np.bool_)
    idx = np.full((m, max(nsym, 1)), -1, np.int64)
    for q in range(m):
        r, _k = _right_seq(codes, link, ignore, positions[q] + 1, n, pattern, plink, 0,
                           len(pattern), idx[q], 0)
        ok[q] = r >= 0
    return ok, idx


def _pattern_codes(pats) -> np.ndarray:
    return np.array([ord(p.symbol) for p in pats], np.uint8)


# --------------------------------------------------------------------------- general engine


class _Group:
    """Productions sharing predecessor, contexts and condition (a stochastic group)."""

    def __init__(self, prods: list[Production], grammar: Grammar):
        self.prods = prods
        p = prods[0]
        self.head = p
        self.left = _pattern_codes(p.left)
        right_syms = [c for c in p.right if c.symbol not in "[]"]
        self.right = _pattern_codes(p.right)
        self.right_links = _pattern_links(self.right)
        self.right_syms = right_syms
        self.cum = np.cumsum([1.0 if q.probability is None else q.probability for q in prods])
        self.cum[-1] = np.inf
        self.succ_codes = [_successor_codes(q) for q in prods]


def _groups(grammar: Grammar) -> dict[int, list[_Group]]:
    by_key: dict[str, list[Production]] = {}
    order: list[str] = []
    for p in grammar.productions:
        if p.key not in by_key:
            order.append(p.key)
        by_key.setdefault(p.key, []).append(p)
    out: dict[int, list[_Group]] = {}
    for key in order:
        g = _Group(by_key[key], grammar)
        out.setdefault(ord(g.head.predecessor.symbol), []).append(g)
    return out


def _expr_error(grammar, prod, exc):
    raise GrammarError(f"while rewriting: {exc.message}", path=grammar.source, line=prod.line,
                       column=exc.column) from None


def _derive_general(grammar, s, n, rng, max_symbols, max_bytes) -> LString:
    groups = _groups(grammar)
    k = max(grammar.max_arity(), 1)
    parametric = grammar.is_parametric
    ignore = np.zeros(256, np.bool_)
    for ch in grammar.ignore:
        ignore[ord(ch)] = True
    codes = s.codes
    params = s.params if parametric else None
    npar = s.nparams if parametric else None
    for step in range(1, n + 1):
        link = _bracket_links(codes) if grammar.is_context_sensitive else None
        order = np.argsort(codes, kind="stable")
        bounds = np.concatenate([[0], np.cumsum(np.bincount(codes, minlength=256))])
        applied = []  # (production, positions, [per-module list of arg arrays])
        out_len = np.ones(len(codes), np.int64)
        for sym in sorted(groups):
            remaining = order[bounds[sym]:bounds[sym + 1]]
            for g in groups[sym]:
                if len(remaining) == 0:
                    break
                ok = np.ones(len(remaining), bool)
                lidx = ridx = None
                if len(g.left):
                    lok, lidx = _match_left(codes, link, ignore, remaining, g.left)
                    ok &= lok
                if len(g.right):
                    rok, ridx = _match_right(codes, link, ignore, remaining, g.right,
                                             g.right_links, len(g.right_syms))
                    ok &= rok
                cand = np.flatnonzero(ok)
                env = dict(grammar.defines)
                if parametric and len(cand):
                    pos = remaining[cand]
                    for j, name in enumerate(g.head.predecessor.params):
                        env[name] = params[pos, j]
                    for pats, ix in ((g.head.left, lidx), (g.right_syms, ridx)):
                        for t, pat in enumerate(pats):
                            for j, name in enumerate(pat.params):
                                env[name] = params[ix[cand, t], j]
                if g.head.condition is not None and len(cand):
                    try:
                        cond = evaluate_array(g.head.condition, env, len(cand)) != 0
                    except ExprError as exc:
                        _expr_error(grammar, g.head, exc)
                    cand = cand[cond]
                    env = {key: (v[cond] if np.ndim(v) else v) for key, v in env.items()}
                if len(cand) == 0:
                    continue
                pos = remaining[cand]
                if len(g.prods) > 1:
                    which = np.searchsorted(g.cum, rng.random(len(pos)), side="right")
                else:
                    which = np.zeros(len(pos), np.int64)
                for w, prod in enumerate(g.prods):
                    sel = np.flatnonzero(which == w) if len(g.prods) > 1 else slice(None)
                    ppos = pos[sel]
                    if len(ppos) == 0:
                        continue
                    sub = {key: (v[sel] if np.ndim(v) else v) for key, v in env.items()}
                    args = []
                    for mod in prod.successor:
                        try:
                            args.append([evaluate_array(a, sub, len(ppos)) for a in mod.args])
                        except ExprError as exc:
                            _expr_error(grammar, prod, exc)
                    out_len[ppos] = len(prod.successor)
                    applied.append((prod, ppos, args, g.succ_codes[w]))
                keep = np.ones(len(remaining), bool)
                keep[cand] = False
                remaining = remaining[keep]
        total = int(out_len.sum())
        _limits(total, k if parametric else 0, step, n, max_symbols, max_bytes)
        start = np.cumsum(out_len) - out_len
        new_codes = np.empty(total, np.uint8)
        ident = out_len == 1
        for _prod, ppos, _args, _sc in applied:
            ident[ppos] = False
        id_pos = np.flatnonzero(ident)
        new_codes[start[id_pos]] = codes[id_pos]
        if parametric:
            new_params = np.full((total, k), np.nan)
            new_npar = np.zeros(total, np.uint8)
            new_params[start[id_pos]] = params[id_pos]
            new_npar[start[id_pos]] = npar[id_pos]
        for _prod, ppos, args, sc in applied:
            base = start[ppos]
            for j, mod_args in enumerate(args):
                dst = base + j
                new_codes[dst] = sc[j]
                if parametric:
                    new_npar[dst] = len(mod_args)
                    for t, vals in enumerate(mod_args):
                        new_params[dst, t] = vals
        codes = new_codes
        if parametric:
            params, npar = new_params, new_npar
        if grammar.has_cut:
            keep = _cut_keep(codes)
            codes = codes[keep]
            if parametric:
                params, npar = params[keep], npar[keep]
    return LString(codes, params, npar)


# --------------------------------------------------------------------------- reference


def _ref_left(mods, p, pattern, ignore):
    i = p - 1
    found = []
    for sym in reversed(pattern):
        depth = 0
        while i >= 0:
            c = mods[i][0]
            if c in ignore:
                i -= 1
            elif c == "]":
                depth = 1
                i -= 1
                while i >= 0 and depth:
                    depth += (mods[i][0] == "]") - (mods[i][0] == "[")
                    i -= 1
            elif c == "[":
                i -= 1
            else:
                break
        if i < 0 or mods[i][0] != sym:
            return None
        found.append(i)
        i -= 1
    return found[::-1]


def _ref_skip_branch(mods, i):
    """``mods[i]`` is '['; index after its ']'."""
    depth = 0
    while i < len(mods):
        depth += (mods[i][0] == "[") - (mods[i][0] == "]")
        i += 1
        if depth == 0:
            return i
    return i


def _ref_right_seq(mods, i, end, pattern, ignore):
    """Match ``pattern`` (a string) from ``mods[i]`` inside a branch ending at ``end``;
    return (position after, [indices of symbol matches]) or None."""
    found = []
    j = 0
    while j < len(pattern):
        sym = pattern[j]
        if sym == "[":
            depth, jend = 0, len(pattern)
            for t in range(j, len(pattern)):
                depth += (pattern[t] == "[") - (pattern[t] == "]")
                if depth == 0:
                    jend = t
                    break
            while i < end and mods[i][0] in ignore:
                i += 1
            hit = None
            while hit is None and i < end and mods[i][0] == "[":
                after = _ref_skip_branch(mods, i)
                close = after - 1 if mods[after - 1][0] == "]" else len(mods)
                hit = _ref_right_seq(mods, i + 1, close, pattern[j + 1:jend], ignore)
                i = close + 1
                while hit is None and i < end and mods[i][0] in ignore:
                    i += 1
            if hit is None:
                return None
            found += hit[1]
            j = jend + 1
            continue
        if sym == "]":
            while i < len(mods) and mods[i][0] != "]":
                i = _ref_skip_branch(mods, i) if mods[i][0] == "[" else i + 1
            if i >= len(mods):
                return None
            i += 1
            j += 1
            continue
        while i < end and (mods[i][0] in ignore or mods[i][0] == "["):
            i = _ref_skip_branch(mods, i) if mods[i][0] == "[" else i + 1
        if i >= end or mods[i][0] != sym:
            return None
        found.append(i)
        i += 1
        j += 1
    return i, found


def _ref_right(mods, p, pattern, ignore):
    hit = _ref_right_seq(mods, p + 1, len(mods), "".join(pattern), ignore)
    return None if hit is None else hit[1]


def _ref_cut(mods):
    out = []
    depth = None  # inside a cut: bracket depth relative to the '%'
    for m in mods:
        if depth is None and m[0] == "%":
            depth = 0
        if depth is not None:
            if m[0] == "[":
                depth += 1
            elif m[0] == "]":
                if depth == 0:
                    depth = None
                else:
                    depth -= 1
                    continue
            if depth is not None:
                continue
        out.append(m)
    return out


def derive_reference(grammar: Grammar, n: int | None = None, *,
                     rng: np.random.Generator | None = None) -> LString:
    """A plain per-module Python derivation (slow; the tests' oracle for :func:`derive`)."""
    n = grammar.n if n is None else n
    s = axiom_string(grammar)
    if s.params is None:
        mods = [(chr(c), ()) for c in s.codes]
    else:
        mods = [(chr(c), tuple(row[:k]))
                for c, k, row in zip(s.codes, s.nparams, s.params, strict=True)]
    ign = set(grammar.ignore)
    for _ in range(n):
        out = []
        for p, (sym, vals) in enumerate(mods):
            done = False
            prods = [q for q in grammar.productions if q.predecessor.symbol == sym]
            tried = set()
            for q in prods:
                if q.key in tried:
                    continue
                tried.add(q.key)
                env = dict(grammar.defines)
                env.update(zip(q.predecessor.params, vals, strict=False))
                if q.left:
                    li = _ref_left(mods, p, [c.symbol for c in q.left], ign)
                    if li is None:
                        continue
                    for pat, i in zip(q.left, li, strict=False):
                        env.update(zip(pat.params, mods[i][1], strict=False))
                if q.right:
                    ri = _ref_right(mods, p, [c.symbol for c in q.right], ign)
                    if ri is None:
                        continue
                    rsyms = [c for c in q.right if c.symbol not in "[]"]
                    for pat, i in zip(rsyms, ri, strict=True):
                        env.update(zip(pat.params, mods[i][1], strict=False))
                if q.condition is not None and evaluate(q.condition, env) == 0.0:
                    continue
                group = [r for r in prods if r.key == q.key]
                chosen = group[0]
                if len(group) > 1:
                    u = rng.random()
                    acc = 0.0
                    for r in group:
                        acc += r.probability
                        chosen = r
                        if u < acc:
                            break
                for m in chosen.successor:
                    out.append((m.symbol, tuple(evaluate(a, env) for a in m.args)))
                done = True
                break
            if not done:
                out.append((sym, vals))
        mods = _ref_cut(out)
    codes = np.frombuffer("".join(m[0] for m in mods).encode("ascii"), np.uint8).copy()
    if s.params is None:
        return LString(codes)
    k = max(grammar.max_arity(), 1)
    params = np.full((len(mods), k), np.nan)
    npar = np.zeros(len(mods), np.uint8)
    for i, (_, vals) in enumerate(mods):
        npar[i] = len(vals)
        params[i, :len(vals)] = vals
    return LString(codes, params, npar)
