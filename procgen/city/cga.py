"""A split grammar for buildings after Mueller et al. (2006), "Procedural modeling of
buildings", SIGGRAPH (doi:10.1145/1141911.1141931), the grammar CityEngine's CGA grew from.

A *shape* is a scope (an oriented box: ``origin (3,)``, axes ``(3, 3)`` as columns,
``size (3,)``) with a symbol. Rules replace a shape by others through one operation each:

``extrude``  a footprint (a flat scope) becomes a mass of ``height``;
``comp``     a mass is split into its faces, ``front`` (the one facing the street),
             ``back``, ``left``, ``right`` (or ``side`` for both), ``top`` and
             ``bottom``; a face's scope has x along it as seen from outside, y up, z out;
``split``    a scope is cut along ``axis`` (x, y or z) into ``parts``, each of a ``size``:
             absolute metres, or relative with ``~`` (relative parts share what the
             absolute ones leave); a part with ``repeat = true`` is repeated as often as
             it fits, its copies stretched to fill (CGA's ``{ ~s : A }*``);
``roof``     a top face gets a roof of ``kind`` flat, gable or hip at ``pitch`` degrees;
``select``   one of several successors by weight (drawn from the building's generator);

and the terminals ``wall``, ``window`` and ``door`` (an opening recessed by ``depth``),
``ledge`` (a slab standing ``depth`` out of the facade) and ``nil`` (nothing).

Rule files are TOML: an ``[attributes]`` table (numbers, names, or a list of choices of
which each building draws one; ``height`` and ``floors`` come from the city) and a
``[rules]`` table of ``Name = { op = ..., ... }``. Every size may be a number, an
attribute's name, or either behind ``~``. The shipped rule files live beside this module
(``rules/*.toml``); :data:`SHAPE_OPERATIONS` lists the operations.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from core.files import read_toml
from core.validate import InputError

__all__ = ["SHAPE_OPERATIONS", "Grammar", "load_grammar", "parse_grammar", "Scope",
           "BuildingGeometry", "build", "eave_height", "emit_roof", "LABELS",
           "shipped_rules"]

SHAPE_OPERATIONS = ("extrude", "comp", "split", "roof", "select", "wall", "window", "door",
                    "ledge", "nil")
ROOF_KINDS = ("flat", "gable", "hip")
FACES = ("front", "back", "left", "right", "side", "top", "bottom")
LABELS = ("wall", "window", "door", "ledge", "roof", "ground")
"""Part labels of a building's triangles, in this order (the index is the label code)."""


@dataclass
class Grammar:
    """A parsed rule file: ``attributes`` (name -> value or list of choices), ``rules``
    (name -> operation table), the ``axiom`` and where it came from."""

    attributes: dict
    rules: dict
    axiom: str = "Lot"
    source: str | None = None


def shipped_rules() -> list[str]:
    """Names of the rule files shipped with scanamp (``procgen/city/rules/NAME.toml``)."""
    folder = resources.files("procgen.city") / "rules"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def load_grammar(name_or_path) -> Grammar:
    """Read a rule file: a shipped name (``"office"``) or a path to a TOML file."""
    p = Path(str(name_or_path))
    if p.suffix != ".toml" and str(name_or_path) in shipped_rules():
        p = Path(str(resources.files("procgen.city") / "rules" / f"{name_or_path}.toml"))
    elif not p.is_file():
        raise InputError(f"no such rule file (shipped rule files: {', '.join(shipped_rules())})",
                         path=p, field="rules")
    return parse_grammar(read_toml(p), source=str(p))


def _err(msg, source, field_):
    return InputError(msg, path=source, field=field_)


def parse_grammar(table: dict, *, source: str | None = None) -> Grammar:
    """Check a rule table (as read from TOML) and return the :class:`Grammar`.

    Raises :class:`core.validate.InputError` naming the file and the dotted field for an
    unknown operation, face, roof kind or axis, a successor that is no rule, a size that is
    neither a number nor an attribute, or a missing axiom.
    """
    attrs = dict(table.get("attributes") or {})
    rules = table.get("rules")
    if not isinstance(rules, dict) or not rules:
        raise _err("expected a [rules] table with at least one rule", source, "rules")
    axiom = str(table.get("axiom", "Lot"))
    if axiom not in rules:
        raise _err(f"the axiom {axiom!r} is not a rule (rules: {', '.join(sorted(rules))})",
                   source, "axiom")
    known = set(attrs) | {"height", "floors", "floor_height"}

    def check_size(v, where):
        if isinstance(v, bool):
            raise _err(f"expected a size (metres, an attribute, or ~ either), got {v!r}",
                       source, where)
        if isinstance(v, int | float):
            if v < 0:
                raise _err(f"expected a size >= 0, got {v}", source, where)
            return
        if not isinstance(v, str):
            raise _err(f"expected a size, got {v!r}", source, where)
        s = v[1:] if v.startswith("~") else v
        try:
            if float(s) < 0:
                raise _err(f"expected a size >= 0, got {v}", source, where)
            return
        except ValueError:
            pass
        if s not in known:
            raise _err(f"unknown attribute {s!r} (attributes: {', '.join(sorted(known))})",
                       source, where)

    def check_successor(v, where):
        if v is not None and v not in rules:
            raise _err(f"no rule named {v!r} (rules: {', '.join(sorted(rules))})", source,
                       where)

    for name, rule in rules.items():
        where = f"rules.{name}"
        if not isinstance(rule, dict) or "op" not in rule:
            raise _err("expected a table with an 'op'", source, where)
        op = rule["op"]
        if op not in SHAPE_OPERATIONS:
            raise _err(f"unknown shape operation {op!r} (expected one of: "
                       f"{', '.join(SHAPE_OPERATIONS)})", source, f"{where}.op")
        if op == "extrude":
            check_size(rule.get("height", "height"), f"{where}.height")
            check_successor(rule.get("then"), f"{where}.then")
        elif op == "comp":
            for face, succ in rule.items():
                if face == "op":
                    continue
                if face not in FACES:
                    raise _err(f"unknown face {face!r} (expected one of: {', '.join(FACES)})",
                               source, f"{where}.{face}")
                check_successor(succ, f"{where}.{face}")
        elif op == "split":
            if rule.get("axis") not in ("x", "y", "z"):
                raise _err(f"expected axis x, y or z, got {rule.get('axis')!r}", source,
                           f"{where}.axis")
            parts = rule.get("parts")
            if not isinstance(parts, list) or not parts:
                raise _err("expected a list of parts", source, f"{where}.parts")
            for i, part in enumerate(parts):
                if not isinstance(part, dict) or "size" not in part:
                    raise _err("expected a table with a size", source, f"{where}.parts[{i}]")
                check_size(part["size"], f"{where}.parts[{i}].size")
                check_successor(part.get("then"), f"{where}.parts[{i}].then")
        elif op == "roof":
            kind = rule.get("kind", "flat")
            if kind not in ROOF_KINDS and kind not in attrs:
                raise _err(f"expected a roof kind ({', '.join(ROOF_KINDS)}) or an attribute, "
                           f"got {kind!r}", source, f"{where}.kind")
            check_size(rule.get("pitch", 30.0), f"{where}.pitch")
        elif op == "select":
            options = rule.get("options")
            if not isinstance(options, list) or not options:
                raise _err("expected a list of options", source, f"{where}.options")
            for i, o in enumerate(options):
                check_successor(o.get("then"), f"{where}.options[{i}].then")
                check_size(o.get("weight", 1.0), f"{where}.options[{i}].weight")
        elif op in ("window", "door", "ledge"):
            check_size(rule.get("depth", 0.2), f"{where}.depth")
    for name, value in attrs.items():
        if isinstance(value, list):
            if not value:
                raise _err("expected at least one choice", source, f"attributes.{name}")
        elif name == "roof" and value not in ROOF_KINDS:
            raise _err(f"expected a roof kind ({', '.join(ROOF_KINDS)}), got {value!r}",
                       source, f"attributes.{name}")
    return Grammar(attrs, dict(rules), axiom, source)


@dataclass
class Scope:
    """An oriented box: ``origin (3,)``, ``axes (3, 3)`` (columns x, y, z), ``size (3,)``."""

    origin: np.ndarray
    axes: np.ndarray
    size: np.ndarray

    def corner(self, u: float, v: float, w: float = 0.0) -> np.ndarray:
        return self.origin + self.axes @ np.array([u, v, w])


@dataclass
class BuildingGeometry:
    """What the grammar built: polygons (each ``(k, 3)``) with their label codes (index in
    :data:`LABELS`), and the windows and doors counted per facade."""

    polygons: list = field(default_factory=list)
    labels: list = field(default_factory=list)
    windows: dict = field(default_factory=dict)
    doors: dict = field(default_factory=dict)
    roof_kind: str = "flat"
    eave_height: float = 0.0
    ridge_height: float = 0.0

    def emit(self, poly, label: str) -> None:
        self.polygons.append(np.asarray(poly, np.float64))
        self.labels.append(LABELS.index(label))

    def mesh(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Fan-triangulated ``(vertices (n, 3), triangles (t, 3), labels (t,) int8)``."""
        vs, fs, ls, count = [], [], [], 0
        by_size: dict = {}
        for poly, lab in zip(self.polygons, self.labels, strict=True):
            by_size.setdefault(len(poly), ([], []))
            by_size[len(poly)][0].append(poly)
            by_size[len(poly)][1].append(lab)
        for k in sorted(by_size):
            polys, labs = np.asarray(by_size[k][0], np.float64), by_size[k][1]
            fan = np.stack([np.zeros(k - 2, np.int64), np.arange(1, k - 1),
                            np.arange(2, k)], 1)
            base = count + k * np.arange(len(polys))
            vs.append(polys.reshape(-1, 3))
            fs.append((base[:, None, None] + fan[None]).reshape(-1, 3))
            ls.append(np.repeat(np.asarray(labs, np.int8), k - 2))
            count += k * len(polys)
        if not vs:
            return np.empty((0, 3)), np.empty((0, 3), np.int64), np.empty(0, np.int8)
        return np.vstack(vs), np.vstack(fs), np.concatenate(ls)


@dataclass
class _Face:
    """A facade's frame, and its polygons in the frame's (u, v, w) coordinates."""

    scope: Scope
    name: str
    quads: list = field(default_factory=list)
    labels: list = field(default_factory=list)


@dataclass
class _Rect:
    """A rectangle ``[u, u + su] x [v, v + sv]`` of a face (pure floats: a facade is split
    into hundreds of them)."""

    face: _Face
    u: float
    v: float
    su: float
    sv: float


class _Builder:
    def __init__(self, grammar: Grammar, attrs: dict, rng: np.random.Generator,
                 max_shapes: int):
        self.g, self.attrs, self.rng = grammar, attrs, rng
        self.out = BuildingGeometry()
        self.faces: list[_Face] = []
        self.budget = max_shapes
        self._values: dict = {}
        self._splits: dict = {}

    def value(self, v) -> tuple[float, bool]:
        """``(metres, relative)`` of a size."""
        key = v if isinstance(v, str) else float(v)
        got = self._values.get(key)
        if got is not None:
            return got
        if isinstance(v, int | float):
            got = float(v), False
        else:
            rel = v.startswith("~")
            s = v[1:] if rel else v
            try:
                got = float(s), rel
            except ValueError:
                got = float(self.attrs[s]), rel
        self._values[key] = got
        return got

    def run(self, symbol: str | None, shape, facade: str | None = None) -> None:
        if symbol is None:
            return
        self.budget -= 1
        if self.budget < 0:
            raise RuntimeError(f"the grammar {self.g.source or ''} made more shapes than "
                               f"allowed: a rule that repeats without end?")
        rule = self.g.rules[symbol]
        getattr(self, "op_" + rule["op"])(rule, shape, facade)

    def finish(self) -> BuildingGeometry:
        """Carry every face's polygons into the world, in one product per face."""
        for face in self.faces:
            if not face.quads:
                continue
            local = np.asarray(face.quads, np.float64)           # (k, 4, 3)
            world = face.scope.origin + local @ face.scope.axes.T
            self.out.polygons.extend(world)
            self.out.labels.extend(face.labels)
        return self.out

    # -- operations on masses -----------------------------------------------------------
    def op_extrude(self, rule, scope, facade):
        h, _ = self.value(rule.get("height", "height"))
        self.out.eave_height = h
        self.run(rule.get("then"), Scope(scope.origin, scope.axes,
                                         np.array([scope.size[0], scope.size[1], h])), facade)

    def op_comp(self, rule, scope, facade):
        o, (X, Y, Z) = scope.origin, scope.axes.T
        sx, sy, sz = scope.size
        faces = {
            "front": Scope(o, np.stack([X, Z, -Y], 1), np.array([sx, sz, 0.0])),
            "right": Scope(o + sx * X, np.stack([Y, Z, X], 1), np.array([sy, sz, 0.0])),
            "back": Scope(o + sx * X + sy * Y, np.stack([-X, Z, Y], 1), np.array([sx, sz, 0.0])),
            "left": Scope(o + sy * Y, np.stack([-Y, Z, -X], 1), np.array([sy, sz, 0.0])),
            "top": Scope(o + sz * Z, np.stack([X, Y, Z], 1), np.array([sx, sy, 0.0])),
            "bottom": Scope(o + sy * Y, np.stack([X, -Y, -Z], 1), np.array([sx, sy, 0.0])),
        }
        for name, sc in faces.items():
            succ = rule.get(name)
            if succ is None and name in ("left", "right"):
                succ = rule.get("side")
            if succ is None:
                continue
            face = _Face(sc, name)
            self.faces.append(face)
            self.run(succ, _Rect(face, 0.0, 0.0, float(sc.size[0]), float(sc.size[1])), name)

    def _sizes(self, rule, total: float) -> list:
        """The parts of a split of ``total`` metres: ``[(size, successor), ...]`` (kept per
        rule and total: a facade splits hundreds of floors and tiles of one width)."""
        key = (id(rule), total)
        got = self._splits.get(key)
        if got is None:
            got = self._splits[key] = self._split_sizes(rule, total)
        return got

    def _split_sizes(self, rule, total: float) -> list:
        parts = []
        for part in rule["parts"]:
            size, rel = self.value(part["size"])
            parts.append((size, rel, part.get("then"), bool(part.get("repeat", False))))
        # absolute parts take their size; a repeated part is copied as often as its
        # nominal size fits in the rest, and relative parts and copies stretch to fill it
        fixed = sum(s for s, r, _, rep in parts if not r and not rep)
        rest = total - fixed
        rel_nominal = sum(s for s, r, _, rep in parts if r and not rep)
        rep_nominal = sum(s for s, _, _, rep in parts if rep)
        n = 0
        if rep_nominal > 0:
            n = max(int(max(rest - rel_nominal, 0.0) / rep_nominal + 0.5), 1)
        flexible = rel_nominal + n * rep_nominal
        stretch = rest / flexible if flexible > 0 else 0.0
        shrink = 1.0
        if rest < 0:                     # absolute parts overflow: shrink them
            shrink, stretch = total / max(fixed, 1e-12), 0.0
        sequence = []
        for size, rel, succ, rep in parts:
            if rep:
                sequence += [(size * stretch, succ)] * n
            else:
                sequence.append((size * stretch if rel else size * shrink, succ))
        return sequence

    def op_split(self, rule, shape, facade):
        axis = "xyz".index(rule["axis"])
        if isinstance(shape, _Rect):
            if axis == 2:
                raise RuntimeError(f"{self.g.source or 'the grammar'}: a facade cannot be "
                                   f"split along z")
            pos = 0.0
            total = shape.su if axis == 0 else shape.sv
            for size, succ in self._sizes(rule, total):
                if size > 1e-9:
                    if axis == 0:
                        child = _Rect(shape.face, shape.u + pos, shape.v, size, shape.sv)
                    else:
                        child = _Rect(shape.face, shape.u, shape.v + pos, shape.su, size)
                    self.run(succ, child, facade)
                pos += size
            return
        pos = 0.0
        for size, succ in self._sizes(rule, float(shape.size[axis])):
            if size > 1e-9:
                new_size = shape.size.copy()
                new_size[axis] = size
                self.run(succ, Scope(shape.origin + shape.axes[:, axis] * pos, shape.axes,
                                     new_size), facade)
            pos += size

    def op_select(self, rule, shape, facade):
        w = np.array([self.value(o.get("weight", 1.0))[0] for o in rule["options"]])
        k = int(self.rng.choice(len(w), p=w / w.sum()))
        self.run(rule["options"][k].get("then"), shape, facade)

    def op_roof(self, rule, shape, facade):
        scope = self._scope(shape)
        kind = rule.get("kind", "flat")
        if kind not in ROOF_KINDS:
            kind = str(self.attrs[kind])
        pitch = np.radians(self.value(rule.get("pitch", 30.0))[0])
        self.out.roof_kind = kind
        rise = emit_roof(self.out, scope, kind, pitch)
        self.out.ridge_height = self.out.eave_height + rise

    @staticmethod
    def _scope(shape) -> Scope:
        if isinstance(shape, Scope):
            return shape
        sc = shape.face.scope
        return Scope(sc.corner(shape.u, shape.v), sc.axes, np.array([shape.su, shape.sv, 0.0]))

    # -- terminals ----------------------------------------------------------------------
    def _emit(self, shape, poly, label: str) -> None:
        if isinstance(shape, _Rect):
            shape.face.quads.append(poly)
            shape.face.labels.append(LABELS.index(label))
        else:                    # a terminal straight on a mass's scope: world coordinates
            sc = shape
            self.out.emit(sc.origin + np.asarray(poly) @ sc.axes.T, label)

    @staticmethod
    def _corners(shape, w: float = 0.0) -> list:
        if isinstance(shape, _Rect):
            u0, v0, u1, v1 = shape.u, shape.v, shape.u + shape.su, shape.v + shape.sv
        else:
            u0, v0, u1, v1 = 0.0, 0.0, float(shape.size[0]), float(shape.size[1])
        return [(u0, v0, w), (u1, v0, w), (u1, v1, w), (u0, v1, w)]

    def op_wall(self, rule, shape, facade):
        self._emit(shape, self._corners(shape), "wall")

    def _opening(self, rule, shape, label, counter, facade):
        d, _ = self.value(rule.get("depth", 0.2))
        outer, inner = self._corners(shape), self._corners(shape, -d)
        for i in range(4):        # the reveals, facing into the opening
            j = (i + 1) % 4
            self._emit(shape, [outer[j], inner[j], inner[i], outer[i]], "wall")
        self._emit(shape, inner, label)
        counter[facade] = counter.get(facade, 0) + 1

    def op_window(self, rule, shape, facade):
        self._opening(rule, shape, "window", self.out.windows, facade)

    def op_door(self, rule, shape, facade):
        self._opening(rule, shape, "door", self.out.doors, facade)

    def op_ledge(self, rule, shape, facade):
        d, _ = self.value(rule.get("depth", 0.3))
        q, out = self._corners(shape), self._corners(shape, d)
        self._emit(shape, out, "ledge")
        for i in range(4):
            j = (i + 1) % 4
            self._emit(shape, [out[j], out[i], q[i], q[j]], "ledge")

    def op_nil(self, rule, shape, facade):
        return


def _quad(scope: Scope) -> np.ndarray:
    """The face of a flat scope, counter-clockwise seen from its +z side."""
    sx, sy = scope.size[0], scope.size[1]
    return np.array([scope.corner(0, 0), scope.corner(sx, 0), scope.corner(sx, sy),
                     scope.corner(0, sy)])


def emit_roof(out: BuildingGeometry, scope: Scope, kind: str, pitch: float) -> float:
    """Emit a roof over the flat top scope; returns its rise above the eaves (metres).

    Gable and hip roofs put the ridge along the longer side; gable ends are walls.
    """
    sx, sy = scope.size[0], scope.size[1]
    c = scope.corner
    if kind == "flat":
        out.emit(_quad(scope), "roof")
        return 0.0
    along_x = sx >= sy
    L, W = (sx, sy) if along_x else (sy, sx)
    h = 0.5 * W * np.tan(pitch)

    def P(u, v, w):          # (u along the ridge, v across) -> world
        return c(u, v, w) if along_x else c(W - v, u, w)

    a, b = (0.0, L) if kind == "gable" else (0.5 * W, L - 0.5 * W)
    if b < a:                # a square hip roof: a pyramid
        a = b = 0.5 * L
    r0, r1 = P(a, 0.5 * W, h), P(b, 0.5 * W, h)
    e00, e10, e11, e01 = P(0, 0, 0), P(L, 0, 0), P(L, W, 0), P(0, W, 0)
    out.emit([e00, e10, r1, r0] if b > a else [e00, e10, r0], "roof")
    out.emit([e11, e01, r0, r1] if b > a else [e11, e01, r0], "roof")
    end = "wall" if kind == "gable" else "roof"
    out.emit([e01, e00, r0], end)
    out.emit([e10, e11, r1], end)
    return float(h)


def eave_height(grammar: Grammar, floors: int) -> float:
    """The height of ``floors`` storeys under the grammar's ``ground_floor_height`` and
    ``floor_height`` (3 m each where it gives none)."""
    a = grammar.attributes
    ground = float(a.get("ground_floor_height", a.get("floor_height", 3.0)))
    return ground + (int(floors) - 1) * float(a.get("floor_height", 3.0))


def build(grammar: Grammar, footprint: np.ndarray, *, floors: int,
          rng: np.random.Generator, height: float | None = None,
          max_shapes: int = 20000) -> BuildingGeometry:
    """Run ``grammar`` on a rectangular footprint.

    Parameters
    ----------
    footprint : (4, 2) float64
        Corners in order, the first edge (0 -> 1) along the street (its front), the lot
        to its left (counter-clockwise seen from above).
    floors : int
        The ``floors`` attribute.
    height : float, optional
        Eave height, metres (the ``height`` attribute); by default :func:`eave_height`.
    rng : numpy.random.Generator
        Draws the building's attributes given as lists of choices, and ``select``.

    Returns
    -------
    BuildingGeometry
    """
    fp = np.asarray(footprint, np.float64)
    X = np.array([*(fp[1] - fp[0]), 0.0])
    Y = np.array([*(fp[3] - fp[0]), 0.0])
    sx, sy = np.linalg.norm(X), np.linalg.norm(Y)
    axes = np.stack([X / sx, Y / sy, [0.0, 0.0, 1.0]], 1)
    attrs = {}
    for name, value in grammar.attributes.items():
        attrs[name] = value[int(rng.integers(len(value)))] if isinstance(value, list) else value
    if height is None:
        height = eave_height(grammar, floors)
    attrs["height"], attrs["floors"] = float(height), int(floors)
    attrs.setdefault("floor_height", float(height) / max(int(floors), 1))
    b = _Builder(grammar, attrs, rng, max_shapes)
    b.run(grammar.axiom, Scope(np.array([fp[0, 0], fp[0, 1], 0.0]), axes,
                               np.array([sx, sy, 0.0])))
    return b.finish()
