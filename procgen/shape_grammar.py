"""A small context-free shape grammar with geometry.

Rules rewrite a nonterminal into one of several weighted alternatives; a sentence is
interpreted left to right by a frame cursor (a 4x4 ``world_from_local`` transform):
terminal shapes emit geometry in the current frame and may move it; ``[`` and ``]`` push
and pop the frame (a push also tilts the branch). Text form, one rule per line::

    Start  -> cylinder Limb Limb Limb Tree
    Limb   -> cylinder [ Shoot ]
    Shoot  -> cylinder Branch Branch Tree
    Tree   -> Branch Tree {0.78} | leaf {0.22}
    Branch -> cylinder {0.3} | [ Shoot ] {0.25} | [ leaf ] {0.45}

This is the notes' plant grammar (``Tree -> Branch Tree | leaf; Branch -> cylinder |
[Tree]``, :data:`PLANT`) with a trunk, weights, and ``Shoot``: a ``Tree`` that starts with
a stem segment, so that a side branch is never a bare leaf unless the rule says so
(``[ leaf ]``: a leaf along the shoot). ``Start`` gives every plant a trunk segment
and three limbs with at least one stem segment, two branch chances and a leaf
each: a derivation cannot be a stick with a leaf, whatever the seed. Weights default to
1. Recursion deeper than ``max_depth`` takes the alternative with the fewest
nonterminals, so derivation ends.

>>> import numpy as np
>>> g = parse_shape_grammar(PLANT)
>>> sentence = derive_sentence(g, np.random.default_rng(0))
>>> sentence[-1]
'leaf'
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from core.frames import axis_angle_matrix
from core.validate import InputError
from procgen.sweeps import revolve, sweep

__all__ = ["ShapeGrammar", "parse_shape_grammar", "derive_sentence", "interpret_sentence",
           "plant_mesh", "leaf_blade", "PLANT", "TERMINALS", "GOLDEN_ANGLE_DEG"]

PLANT = """
Start  -> cylinder Limb Limb Limb Tree
Limb   -> cylinder [ Shoot ]
Shoot  -> cylinder Branch Branch Tree
Tree   -> Branch Tree {0.78} | leaf {0.22}
Branch -> cylinder {0.3} | [ Shoot ] {0.25} | [ leaf ] {0.45}
"""
GOLDEN_ANGLE_DEG = 137.50776405003785  # phyllotaxis: successive branches turn by it

TERMINALS = ("cylinder", "leaf", "[", "]")


@dataclass
class ShapeGrammar:
    """Rules ``name -> [(weight, (token, ...)), ...]`` and the start symbol."""

    rules: dict[str, list[tuple[float, tuple[str, ...]]]] = field(default_factory=dict)
    start: str = "Start"


def parse_shape_grammar(text: str, *, source: str | None = None) -> ShapeGrammar:
    """Parse the rule text; InputError naming the line for unknown tokens or bad weights."""
    g = ShapeGrammar()
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        where = f"line {lineno}"
        if "->" not in line:
            raise InputError("expected 'Name -> alternative | alternative'", path=source,
                             field=where)
        lhs, rhs = (s.strip() for s in line.split("->", 1))
        if not re.fullmatch(r"[A-Za-z_]\w*", lhs) or lhs in TERMINALS:
            raise InputError(f"bad rule name {lhs!r}", path=source, field=where)
        if not g.rules:
            g.start = lhs
        alts = []
        for alt in rhs.split("|"):
            m = re.search(r"\{([^}]*)\}\s*$", alt)
            weight = 1.0
            if m:
                try:
                    weight = float(m.group(1))
                except ValueError:
                    raise InputError(f"bad weight {m.group(1)!r}", path=source,
                                     field=where) from None
                alt = alt[:m.start()]
            if weight <= 0:
                raise InputError(f"weights must be > 0, got {weight:g}", path=source, field=where)
            alts.append((weight, tuple(alt.split())))
        g.rules.setdefault(lhs, []).extend(alts)
    for name, alts in g.rules.items():
        for _, toks in alts:
            for t in toks:
                if t not in TERMINALS and t not in g.rules:
                    raise InputError(f"rule {name!r} uses unknown symbol {t!r} (terminals: "
                                     f"{', '.join(TERMINALS)})", path=source)
    if not g.rules:
        raise InputError("no rules", path=source)
    return g


def derive_sentence(grammar: ShapeGrammar, rng: np.random.Generator, *,
                    max_depth: int = 8, max_terminals: int = 100_000) -> list[str]:
    """Expand the start symbol depth-first into a list of terminals."""
    out: list[str] = []
    stack: list[tuple[str, int]] = [(grammar.start, 0)]
    while stack:
        tok, depth = stack.pop()
        if tok not in grammar.rules:
            out.append(tok)
            if len(out) > max_terminals:
                raise ValueError(f"max_terminals: the sentence exceeds {max_terminals}")
            continue
        alts = grammar.rules[tok]
        if depth >= max_depth:
            toks = min(alts, key=lambda a: sum(t in grammar.rules for t in a[1]))[1]
        else:
            w = np.array([a[0] for a in alts])
            toks = alts[int(rng.choice(len(alts), p=w / w.sum()))][1]
        for t in reversed(toks):
            stack.append((t, depth + 1))
    return out


def leaf_blade(sides: int = 10, *, width: float = 0.42, thickness: float = 0.03,
               petiole: float = 0.18) -> tuple[np.ndarray, np.ndarray]:
    """A closed, flat, ovate leaf of length 1 along +Z (width along X, thin along Y).

    A profile revolved about Z and flattened: a thin petiole for the first ``petiole`` of
    the length, then a blade widest at about a third of its length, pointed at the tip.
    """
    u = np.linspace(0.0, 1.0, 16)
    blade = np.sin(np.pi * u) ** 0.9 * (1.0 - 0.45 * u)      # ovate: widest below the middle
    r = np.r_[0.0, 0.04, 0.04, 0.5 * width * blade[1:-1] / blade.max() + 0.01, 0.0]
    z = np.r_[0.0, 0.0, petiole, petiole + (1 - petiole) * u[1:-1], 1.0]
    v, f = revolve(np.c_[r, z], segments=sides)
    return v * [1.0, thickness / width, 1.0], f


def interpret_sentence(sentence: list[str], rng: np.random.Generator, *, length: float = 1.0,
                       radius: float = 0.08, shrink: float = 0.9, branch_shrink: float = 0.75,
                       tilt: tuple[float, float] = (35.0, 60.0),
                       leaf_tilt: tuple[float, float] = (45.0, 75.0), leaf_size: float = 0.6,
                       bend: float = 7.0, rise: float = 0.12, sides: int = 10,
                       leaves: bool = False):
    """Geometry of a sentence: tapered cylinders and flat ovate leaves.

    ``cylinder`` draws a frustum along the local +Z whose top radius is ``shrink`` times
    its base (the stem tapers segment by segment, continuously) and moves the frame to
    its top, turning it by a random ``bend`` (degrees, standard deviation) and toward the
    vertical by ``rise`` of its angle from it (shoots curve upward, as shoots do); ``[``
    pushes the frame, tilts it by a random angle in ``tilt`` (``leaf_tilt`` when the branch
    is a single leaf, ``[ leaf ]``) and scales by ``branch_shrink``; ``]`` pops. Successive
    branches of one axis turn about it by the golden angle (phyllotaxis, a few degrees of
    jitter), so they spiral around the stem instead of bunching. A ``leaf`` is
    :func:`leaf_blade` of length ``leaf_size * length * s**0.3`` (``s`` the current scale),
    its blade facing away from the stem.

    Returns ``(vertices, triangles)``, and with ``leaves=True`` also ``(n,) bool``: which
    vertices belong to leaves.
    """
    R = np.eye(3)
    p = np.zeros(3)
    s = 1.0
    turn = rng.uniform(0, 2 * np.pi)  # azimuth of the next branch on the current axis
    stack = []
    vs, fs, leafy = [], [], []
    count = 0
    t = np.linspace(0, 2 * np.pi, sides, endpoint=False)
    circle = np.c_[np.cos(t), np.sin(t)]
    lv, lf = leaf_blade(sides)
    for i, tok in enumerate(sentence):
        if tok == "cylinder":
            top = p + R[:, 2] * length * s
            v, f = sweep(circle * radius * s, np.stack([p, top]), normal=R[:, 0],
                         scale=np.array([1.0, shrink]))
            vs.append(v)
            leafy.append(np.zeros(len(v), bool))
            fs.append(f + count)
            count += len(v)
            p = top
            s *= shrink
            # a random bend, then a turn toward the vertical (an upward-curving shoot)
            a = rng.uniform(0, 2 * np.pi)
            R = axis_angle_matrix(R @ np.array([np.cos(a), np.sin(a), 0.0]),
                                  np.radians(rng.normal(0.0, bend))) @ R
            up = np.cross(R[:, 2], [0.0, 0.0, 1.0])
            if np.linalg.norm(up) > 1e-9:
                ang = np.arccos(np.clip(R[2, 2], -1.0, 1.0))
                R = axis_angle_matrix(up, rise * ang) @ R
        elif tok == "leaf":
            L = leaf_size * length * s ** 0.3
            v = (lv * L) @ R.T + p
            vs.append(v)
            leafy.append(np.ones(len(v), bool))
            fs.append(lf + count)
            count += len(v)
        elif tok == "[":
            turn += np.radians(GOLDEN_ANGLE_DEG + rng.normal(0.0, 5.0))
            stack.append((R.copy(), p.copy(), s, turn))
            axis = R @ np.array([np.cos(turn), np.sin(turn), 0.0])
            is_leaf = sentence[i + 1:i + 3] == ["leaf", "]"]
            R = axis_angle_matrix(axis, np.radians(rng.uniform(*(leaf_tilt if is_leaf
                                                                  else tilt)))) @ R
            # the new frame's X along the tilt axis: a leaf's blade faces away from the stem
            x = axis / np.linalg.norm(axis)
            R = np.c_[x, np.cross(R[:, 2], x), R[:, 2]]
            s *= branch_shrink
            turn = rng.uniform(0, 2 * np.pi)
        elif tok == "]":
            R, p, s, turn = stack.pop()
    if not vs:
        out = (np.empty((0, 3)), np.empty((0, 3), np.int64))
        return (*out, np.zeros(0, bool)) if leaves else out
    out = (np.vstack(vs), np.vstack(fs).astype(np.int64))
    return (*out, np.concatenate(leafy)) if leaves else out


def plant_mesh(rng: np.random.Generator, *, max_depth: int = 10, grammar: str = PLANT,
               leaves: bool = False):
    """Derive and build the plant grammar: ``(vertices, triangles)`` (and the leaf mask of
    the vertices with ``leaves=True``)."""
    g = parse_shape_grammar(grammar)
    return interpret_sentence(derive_sentence(g, rng, max_depth=max_depth), rng,
                              leaves=leaves)
