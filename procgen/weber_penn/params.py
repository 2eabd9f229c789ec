"""Weber & Penn tree parameters: the field table, the per-species TOML files, validation.

A species file (``procgen/weber_penn/species/NAME.toml``) holds the parameters of Weber and
Penn, "Creation and rendering of realistic trees" (SIGGRAPH 1995), under their names in the
paper (and Arbaro's additions ``BranchDist``, ``LeafDistrib``, ``LeafBend``, ``LeafQuality``,
``LeafStemLen``, ``Smooth``), in four tables:

- ``[species]``: ``name``, ``common``, ``latin``, ``source`` (where the values come from);
- ``[tree]``: the general parameters (``Shape``, ``Levels``, ``Scale``, ..., ``0Scale``,
  ``0ScaleV``, ``0BaseSplits``);
- ``[level.0]`` ... ``[level.3]``: the per-level parameters without their level prefix
  (``DownAngle``, ``Branches``, ``Length``, ``Taper``, ``SegSplits``, ``CurveRes`` ...);
- ``[appearance]`` and ``[model]``: what the paper leaves to the renderer (bark and leaf
  colours, the bark texture, whether the leaves are needles) and the two growth laws scanamp
  adds (the exponent of Leonardo's rule the radii follow, and the height-diameter exponent
  that relates trees of one species across ages).

Every field must be present (a missing field is an error naming it), angles are degrees
as in the paper, lengths metres. :func:`load_species` reads a shipped species by name or
any file by path; :func:`params_to_dict` gives back the table a file holds, so a loaded set
writes back to the same values (:func:`write_species`).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

from core.files import read_toml, require, write_toml
from core.validate import InputError

__all__ = ["TREE_FIELDS", "LEVEL_FIELDS", "APPEARANCE_FIELDS", "MODEL_FIELDS", "LEAF_SHAPES",
           "BARK_TEXTURES", "MAX_LEVELS", "TreeParams", "species_names", "species_path",
           "load_species", "parse_params", "params_to_dict", "write_species", "leaf_shape_name"]

SPECIES_DIR = Path(__file__).with_name("species")
MAX_LEVELS = 4  # the trunk and three levels of branches, as in the paper
INF = math.inf

# (name, kind, lo, hi): kind int, float or "leafshape"; bounds inclusive
TREE_FIELDS = (
    ("Shape", int, 0, 8), ("Levels", int, 1, MAX_LEVELS), ("Scale", float, 1e-6, INF),
    ("ScaleV", float, 0, INF), ("BaseSize", float, 0, 1), ("Ratio", float, 1e-6, 1),
    ("RatioPower", float, 0, 10), ("Flare", float, -1, 10), ("Lobes", int, 0, 64),
    ("LobeDepth", float, 0, 1), ("Smooth", float, 0, 1), ("Leaves", int, -10000, 10000),
    ("LeafShape", "leafshape", None, None), ("LeafScale", float, 1e-6, INF),
    ("LeafScaleX", float, 1e-6, INF), ("LeafQuality", float, 1e-6, 10),
    ("LeafStemLen", float, 0, INF), ("LeafDistrib", int, 0, 8), ("LeafBend", float, 0, 1),
    ("AttractionUp", float, -INF, INF), ("PruneRatio", float, 0, 1),
    ("PrunePowerLow", float, 0, INF), ("PrunePowerHigh", float, 0, INF),
    ("PruneWidth", float, 1e-6, INF), ("PruneWidthPeak", float, 0, 1),
    ("0Scale", float, 1e-6, INF), ("0ScaleV", float, 0, INF), ("0BaseSplits", int, 0, 32),
)
LEVEL_FIELDS = (
    ("DownAngle", float, -360, 360), ("DownAngleV", float, -360, 360),
    ("Rotate", float, -360, 360), ("RotateV", float, 0, 360), ("Branches", int, 0, 100000),
    ("BranchDist", float, 0, 1), ("Length", float, 0, INF), ("LengthV", float, 0, INF),
    ("Taper", float, 0, 3), ("SegSplits", float, 0, 32), ("SplitAngle", float, -360, 360),
    ("SplitAngleV", float, 0, 360), ("CurveRes", int, 1, 1000), ("Curve", float, -3600, 3600),
    ("CurveBack", float, -3600, 3600), ("CurveV", float, -90, 3600),
)
BARK_TEXTURES = ("smooth", "lenticels", "furrowed", "plated", "scaly", "ringed")
APPEARANCE_FIELDS = (
    ("bark", "rgb", None, None), ("bark_dark", "rgb", None, None),
    ("bark_texture", "barktexture", None, None), ("leaf", "rgb", None, None),
    ("leaf_variation", float, 0, 1), ("autumn", "rgb", None, None),
    ("deciduous", bool, None, None), ("needles", bool, None, None),
)
MODEL_FIELDS = (("leonardo_exponent", float, 1, 4), ("height_diameter_exponent", float, 0.2, 1),)
SPECIES_FIELDS = ("name", "common", "latin", "source")
# Arbaro's leaf shapes by index (0 the paper's default disc) and by name; "needles" and
# "lobed" are scanamp's (a cluster of needles, a palmate maple leaf)
LEAF_SHAPES = ("disc", "disc1", "disc2", "disc3", "palm", "needles", "lobed", "square")


def leaf_shape_name(value: int | str) -> str:
    """The leaf shape's name (:data:`LEAF_SHAPES`) of a ``LeafShape`` value (index or name)."""
    return LEAF_SHAPES[value] if isinstance(value, int) else value


@dataclass(frozen=True)
class TreeParams:
    """One species' parameter set, as its file holds it (see the module docstring).

    ``tree`` maps the general parameters' names to values, ``levels`` holds the four
    per-level tables (``levels[n]["DownAngle"]``), ``appearance`` and ``model`` scanamp's
    own tables, ``species`` the names and the source.
    """

    species: dict
    tree: dict
    levels: tuple
    appearance: dict
    model: dict
    path: str | None = field(default=None, compare=False)

    def __getitem__(self, name: str):
        return self.tree[name]

    @property
    def name(self) -> str:
        return self.species["name"]


def species_names() -> list[str]:
    """Names of the shipped species files (``quaking_aspen``, ``norway_spruce``, ...)."""
    return sorted(p.stem for p in SPECIES_DIR.glob("*.toml"))


def species_path(name: str | os.PathLike) -> Path:
    """The file of a shipped species name, or ``name`` itself when it is a ``.toml`` path."""
    text = str(name)
    if text.endswith(".toml") or os.sep in text:
        return Path(name)
    key = text.strip().lower().replace(" ", "_").replace("-", "_")
    path = SPECIES_DIR / f"{key}.toml"
    if not path.is_file():
        raise InputError(f"unknown species {text!r}; expected one of {', '.join(species_names())}"
                         " or a .toml parameter file", field="--species")
    return path


def load_species(name: str | os.PathLike) -> TreeParams:
    """Read and check a species' parameters: a shipped name or a TOML file path.

    Raises :class:`core.validate.InputError` (a ValueError) naming the file and the field
    when a field is missing, of the wrong type or out of its range.
    """
    path = species_path(name)
    return parse_params(read_toml(path), path=path)


def _check_value(table: dict, spec, *, path, prefix: str):
    name, kind, lo, hi = spec
    where = f"{prefix}.{name}"
    if kind == "leafshape":
        value = require(table, name, (int, str), path=path, prefix=prefix)
        ok = (0 <= value < len(LEAF_SHAPES)) if isinstance(value, int) else value in LEAF_SHAPES
        if not ok:
            raise InputError(f"expected an index 0-{len(LEAF_SHAPES) - 1} or one of "
                             f"{', '.join(LEAF_SHAPES)}, got {value!r}", path=path, field=where)
        return value
    if kind == "barktexture":
        value = require(table, name, str, path=path, prefix=prefix)
        if value not in BARK_TEXTURES:
            raise InputError(f"expected one of {', '.join(BARK_TEXTURES)}, got {value!r}",
                             path=path, field=where)
        return value
    if kind == "rgb":
        value = require(table, name, list, path=path, prefix=prefix)
        if len(value) != 3 or not all(isinstance(c, (int, float)) and not isinstance(c, bool)
                                      and 0 <= c <= 1 for c in value):
            raise InputError(f"expected three numbers in [0, 1], got {value!r}", path=path,
                             field=where)
        return [float(c) for c in value]
    value = require(table, name, kind, path=path, prefix=prefix)
    if kind is bool:
        return value
    if not (math.isfinite(value) or (value == hi == INF) or (value == lo == -INF)):
        raise InputError(f"expected a finite number, got {value!r}", path=path, field=where)
    if not lo <= value <= hi:
        raise InputError(f"expected a value in [{lo:g}, {hi:g}], got {value!r}", path=path,
                         field=where)
    return value


def _table(data: dict, key: str, *, path) -> dict:
    value = require(data, key, dict, path=path)
    return value


def parse_params(data: dict, *, path: str | os.PathLike | None = None) -> TreeParams:
    """Check a parameter table (as read from TOML) and return it as :class:`TreeParams`."""
    species = _table(data, "species", path=path)
    sp = {k: require(species, k, str, path=path, prefix="species") for k in SPECIES_FIELDS}
    tree_t = _table(data, "tree", path=path)
    tree = {s[0]: _check_value(tree_t, s, path=path, prefix="tree") for s in TREE_FIELDS}
    level_t = _table(data, "level", path=path)
    extra = sorted(set(level_t) - {str(n) for n in range(MAX_LEVELS)})
    if extra:
        raise InputError(f"levels are numbered 0-{MAX_LEVELS - 1} (at most {MAX_LEVELS} "
                         f"levels), got level {extra[0]}", path=path, field=f"level.{extra[0]}")
    levels = []
    for n in range(MAX_LEVELS):
        lt = require(level_t, str(n), dict, path=path, prefix="level")
        levels.append({s[0]: _check_value(lt, s, path=path, prefix=f"level.{n}")
                       for s in LEVEL_FIELDS})
    app_t = _table(data, "appearance", path=path)
    app = {s[0]: _check_value(app_t, s, path=path, prefix="appearance")
           for s in APPEARANCE_FIELDS}
    model_t = _table(data, "model", path=path)
    model = {s[0]: _check_value(model_t, s, path=path, prefix="model") for s in MODEL_FIELDS}
    return TreeParams(species=sp, tree=tree, levels=tuple(levels), appearance=app, model=model,
                      path=None if path is None else str(path))


def params_to_dict(params: TreeParams) -> dict:
    """The TOML table of ``params`` (:func:`parse_params` of it gives ``params`` back)."""
    return {"species": dict(params.species), "tree": dict(params.tree),
            "level": {str(n): dict(lv) for n, lv in enumerate(params.levels)},
            "appearance": {k: (list(v) if isinstance(v, list) else v)
                           for k, v in params.appearance.items()},
            "model": dict(params.model)}


def write_species(path: str | os.PathLike, params: TreeParams) -> Path:
    """Write ``params`` as a species TOML file (atomically)."""
    return write_toml(path, params_to_dict(params))
