"""Amplification recipes: TOML with an ordered list of ``[[step]]`` tables.

Every field is checked here, before any work starts, and an error names the file and
the field (``recipe.toml: step[2].amplitude: expected a value in [0, 10], got 12``).
Shipped recipes live in ``scanamp/amplify/recipes/*.toml`` and are addressed by name.
"""

from __future__ import annotations

import copy
import inspect
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from core.files import read_toml, require
from core.validate import InputError
from procgen.amplify.plants import scatter_plants
from procgen.city import CityConfig
from procgen.terrain.erosion import KINDS as EROSION_KINDS
from reconstruct.surface.clean import CleanOptions

__all__ = ["KINDS", "Recipe", "Step", "load_recipe", "parse_recipe", "recipe_names",
           "RECIPE_DIR"]

RECIPE_DIR = Path(__file__).parent / "recipes"
KINDS = ("clean", "displace", "refine-terrain", "scatter", "sweep", "snow", "hypertexture",
         "city", "animate")

_INF = float("inf")


@dataclass(frozen=True)
class _F:
    """A field: type(s), default (``...``: required), numeric bounds or allowed values."""

    kind: Any
    default: Any = ...
    lo: float | None = None
    hi: float | None = None
    choices: tuple | None = None
    length: int | None = None   # lists: exact length (numbers inside, bounded by lo/hi)
    lo_open: bool = False
    hi_open: bool = False


_NOISE3 = ("fbm", "turbulence", "ridged")
_CLEAN = CleanOptions()  # the clean step's defaults are the library's, declared once
_CITY = CityConfig()
_PLANTS = inspect.signature(scatter_plants).parameters   # the library's plant defaults

# Sizes marked "relative" are fractions of the current mesh's bounding-box diagonal.
SPECS: dict[str, dict[str, _F]] = {
    "clean": {
        "min_component_area": _F(float, _CLEAN.min_component_area, 0.0, 1.0, hi_open=True),
        "max_hole_edges": _F(int, _CLEAN.max_hole_edges, 0, 100_000),
        "remesh": _F(bool, _CLEAN.remesh),
        "edge_fraction": _F(float, _CLEAN.edge_fraction, 0.0, 1.0, lo_open=True,
                            hi_open=True),
        "smooth_steps": _F(int, _CLEAN.smooth_steps, 0, 100),
    },
    "displace": {
        "edge": _F(float, 0.5, 0.0, 100.0),              # target edge / input mean edge; 0: none
        "noise": _F(str, "fbm", choices=_NOISE3),
        "amplitude": _F(float, 0.3, 0.0, 10.0),           # RMS offset / local scale
        "scale": _F(str, "local", choices=("local", "global")),
        "wavelength": _F(float, 4.0, 0.0, 1e6, lo_open=True),
        "octaves": _F(int, 5, 1, 16),
        "hurst": _F(float, 1.0, 0.0, 1.0, lo_open=True),   # octave gain 2**-hurst
        "mask": _F(str, "none", choices=("none", "slope", "curvature")),
        "mask_range": _F(list, [20.0, 40.0], 0.0, 1e6, length=2),
        "invert_mask": _F(bool, False),
        "max_triangles": _F(int, 2_000_000, 1, 50_000_000),
    },
    "refine-terrain": {
        "control_size": _F(int, 33, 3, 1025),
        "levels": _F(int, 3, 0, 8),
        "hurst": _F(float, 0.8, 0.0, 1.0, lo_open=True, hi_open=True),
        "sigma": _F(float, None, 0.0, 1e6),               # metres; default: continue roughness
        "trim": _F(bool, True),
        "objects": _F(str, "keep", choices=("keep", "refine")),  # keep: only the ground
        "erosion": _F(str, "none", choices=EROSION_KINDS),  # rates: ErosionConfig's defaults
    },
    "scatter": {
        "grammar": _F(str, "tree"),
        # Weber & Penn species, comma-separated shipped names or .toml files ("": the
        # grammar's plants); the variants cycle over them
        "species": _F(str, ""),
        "density": _F(float, 4.0, 0.0, 1e6, lo_open=True),  # plants per density_unit
        # "m2": per square metre; "diagonal": per square of the bounding-box diagonal
        # (relative, like the sizes: the same recipe plants as many on a 20 cm scan as on
        # a 20 m terrain)
        "density_unit": _F(str, "m2", choices=("m2", "diagonal")),
        "min_plants": _F(int, 0, 0, 100_000),  # floor when any surface is eligible
        "height": _F(float, 0.08, 0.0, 10.0, lo_open=True),  # relative
        "height_jitter": _F(float, 0.3, 0.0, 1.0, hi_open=True),
        "slope_max_deg": _F(float, 30.0, 0.0, 90.0),
        "altitude_range": _F(list, [0.0, 1.0], 0.0, 1.0, length=2),
        "variants": _F(int, 6, 1, 64),
        "steps": _F(int, None, 0, 12),
        "sides": _F(int, 6, 3, 32),
        "max_plants": _F(int, 400, 1, 100_000),
        "upright": _F(bool, True),
        "leaves": _F(int, _PLANTS["leaves"].default, 0, 16),        # per branch tip
        "leaf_size": _F(float, _PLANTS["leaf_size"].default, 0.0, 1.0, lo_open=True),
        "merge": _F(bool, True),
        "color": _F(list, [0.35, 0.5, 0.2], 0.0, 1.0, length=3),        # leaves
        "bark_color": _F(list, [0.42, 0.3, 0.2], 0.0, 1.0, length=3),
    },
    "sweep": {
        "count": _F(int, 12, 1, 10_000),
        "length": _F(float, 0.6, 0.0, 100.0, lo_open=True),   # relative
        "radius": _F(float, 0.004, 0.0, 0.1, lo_open=True),   # relative
        "step": _F(float, 0.01, 0.0, 0.1, lo_open=True),      # relative
        "wander_deg": _F(float, 25.0, 0.0, 180.0),
        "slope_max_deg": _F(float, 90.0, 0.0, 90.0),
        "slope_min_deg": _F(float, 0.0, 0.0, 90.0),   # start on walls (falls back)
        "climb": _F(float, 0.0, 0.0, 1.0),            # lean toward up each step
        "sides": _F(int, 6, 3, 32),
        "taper": _F(float, 0.6, 0.0, 1.0),
        "branches": _F(float, 0.0, 0.0, 1e4),       # side shoots per diagonal of stem
        "leaf_size": _F(float, 0.0, 0.0, 0.1),      # relative; 0: a bare vine
        "leaf_spacing": _F(float, 0.0, 0.0, 0.1),   # relative; 0: the leaf size
        "merge": _F(bool, True),
        "color": _F(list, [0.25, 0.45, 0.15], 0.0, 1.0, length=3),
        "leaf_color": _F(list, [0.16, 0.38, 0.12], 0.0, 1.0, length=3),
    },
    "snow": {
        "depth": _F(float, 0.01, 0.0, 1.0, lo_open=True),     # relative
        "slope_max_deg": _F(float, 60.0, 0.0, 90.0, lo_open=True),
        "drift": _F(float, 0.3, 0.0, 1.0),
        "merge": _F(bool, True),
        "color": _F(list, [0.95, 0.96, 0.98], 0.0, 1.0, length=3),
    },
    "hypertexture": {
        "noise": _F(str, "turbulence", choices=("turbulence", "fbm")),
        "amplitude": _F(float, 0.02, 0.0, 1.0),           # relative
        "frequency": _F(float, 8.0, 0.0, 1e4, lo_open=True),  # cycles per diagonal
        "octaves": _F(int, 4, 1, 12),
        "resolution": _F(int, 96, 8, 512),
        "bias": _F(float, 0.5, 0.0, 1.0, lo_open=True, hi_open=True),
        "gain": _F(float, 0.5, 0.0, 1.0, lo_open=True, hi_open=True),
    },
    "city": {
        # the city's map in city metres spans the ground's longer side (scale-free)
        "size": _F(float, 600.0, 100.0, 100_000.0),
        "centres": _F(int, _CITY.centres, 1, 50),
        "parks": _F(int, _CITY.parks, 0, 100),
        "river_width": _F(float, 0.0, 0.0, 10_000.0),           # city metres; 0: none
        "max_segments": _F(int, _CITY.max_segments, 1, 100_000),
        "max_slope_deg": _F(float, 20.0, 0.0, 90.0, hi_open=True),  # under a building
        "road_step": _F(float, 10.0, 0.0, 1000.0, lo_open=True),    # city metres
        "road_color": _F(list, [0.27, 0.27, 0.29], 0.0, 1.0, length=3),
        "building_color": _F(list, [0.82, 0.78, 0.7], 0.0, 1.0, length=3),
        "roof_color": _F(list, [0.62, 0.32, 0.25], 0.0, 1.0, length=3),
    },
    "animate": {
        "simulation": _F(str, ..., choices=("particles", "cloth", "boids")),
        "recipe": _F(str, ...),
        "frames": _F(int, None, 1, 100_000),
        "n": _F(int, None, 1, 1_000_000),
        "fit": _F(bool, True),
        "size": _F(float, None, 0.0, 1e6, lo_open=True),
        "width": _F(int, 320, 16, 4096),
        "height": _F(int, 240, 16, 4096),
        "render": _F(bool, True),
        # an open mesh collides as its closed shell, voxels along its longest side
        "collider_resolution": _F(int, 128, 16, 512),
    },
}

_RENDER = {
    "width": _F(int, 640, 16, 4096),
    "height": _F(int, 480, 16, 4096),
    "elevation_deg": _F(float, 30.0, -89.0, 89.0),
    "azimuth_deg": _F(float, -60.0, -360.0, 360.0),
    "fov_deg": _F(float, 45.0, 1.0, 170.0),
}


@dataclass
class Step:
    """One validated step: ``kind``, its ``params`` (defaults filled) and its position."""

    kind: str
    params: dict
    index: int


@dataclass
class Recipe:
    """A validated recipe."""

    name: str
    path: Path | None
    steps: list[Step]
    render: dict = field(default_factory=dict)
    description: str = ""
    seed: int | None = None

    def resolve(self, value: str) -> str:
        """A path named in the recipe, relative to the recipe's folder when it is a file."""
        p = Path(value)
        if self.path is not None and not p.is_absolute() and p.suffix and \
                (self.path.parent / p).exists():
            return str(self.path.parent / p)
        return value


def recipe_names() -> list[str]:
    """Names of the shipped recipes."""
    return sorted(p.stem for p in RECIPE_DIR.glob("*.toml"))


def _check_field(name: str, spec: _F, value: Any, path, prefix: str) -> Any:
    fld = f"{prefix}.{name}"
    if spec.kind is list:
        v = require({name: value}, name, list, path=path, prefix=prefix)
        if spec.length is not None and len(v) != spec.length:
            raise InputError(f"expected a list of {spec.length} numbers, got {v!r}", path=path,
                             field=fld)
        out = []
        for k, x in enumerate(v):
            x = require({name: x}, name, float, path=path, prefix=prefix)
            out.append(_bounded(float(x), spec, path, f"{fld}[{k}]"))
        return out
    v = require({name: value}, name, spec.kind, path=path, prefix=prefix)
    if spec.choices is not None and v not in spec.choices:
        raise InputError(f"expected one of {', '.join(spec.choices)}, got {v!r}", path=path,
                         field=fld)
    if spec.kind in (int, float):
        _bounded(v, spec, path, fld)
    return v


def _bounded(v, spec: _F, path, fld):
    import math

    if isinstance(v, float) and not math.isfinite(v):
        raise InputError(f"expected a finite number, got {v!r}", path=path, field=fld)
    low = spec.lo is not None and (v <= spec.lo if spec.lo_open else v < spec.lo)
    high = spec.hi is not None and (v >= spec.hi if spec.hi_open else v > spec.hi)
    if low or high:
        left = "(" if spec.lo_open else "["
        right = ")" if spec.hi_open else "]"
        lo = "-inf" if spec.lo is None else f"{spec.lo:g}"
        hi = "inf" if spec.hi is None else f"{spec.hi:g}"
        raise InputError(f"expected a value in {left}{lo}, {hi}{right}, got {v!r}", path=path,
                         field=fld)
    return v


def _check_table(table: Any, specs: dict[str, _F], path, prefix: str, *,
                 skip: tuple = ()) -> dict:
    if not isinstance(table, dict):
        raise InputError(f"expected a table, got {table!r}", path=path, field=prefix)
    for key in table:
        if key not in specs and key not in skip:
            raise InputError(f"unknown field; expected one of {', '.join(sorted(specs))}",
                             path=path, field=f"{prefix}.{key}")
    out = {}
    for name, spec in specs.items():
        if name in table:
            out[name] = _check_field(name, spec, table[name], path, prefix)
        elif spec.default is ...:
            raise InputError("missing", path=path, field=f"{prefix}.{name}")
        else:
            out[name] = copy.deepcopy(spec.default)
    return out


def _check_simulation(params: dict, path: Path | None, where, prefix: str) -> None:
    """Load the animate step's simulation recipe now, so a bad one fails before any work."""
    sub = params["recipe"]
    p = Path(sub)
    if path is not None and p.suffix and not p.is_absolute() and (path.parent / p).exists():
        sub = str(path.parent / p)
    try:
        if params["simulation"] == "boids":
            from simulate.boids import load_recipe as load_boids

            load_boids(sub)
        else:
            from simulate.recipes import load_recipe as load_sim

            table, sub_path = load_sim(sub)
            if table["kind"] != params["simulation"]:
                raise InputError(f"is a {table['kind']} recipe, not {params['simulation']}",
                                 path=sub_path)
    except InputError as exc:
        raise InputError(f"bad {params['simulation']} recipe: {exc}", path=where,
                         field=f"{prefix}.recipe") from None


def species_list(text: str) -> list[str]:
    """The comma-separated species of a scatter step, stripped ("" gives none)."""
    return [s.strip() for s in text.split(",") if s.strip()]


def _check_species(text: str, path, where, fld) -> None:
    from procgen.weber_penn import species_names

    known = species_names()
    for name in species_list(text):
        key = name.lower().replace(" ", "_").replace("-", "_")
        if not name.endswith(".toml") and key not in known:
            raise InputError(f"unknown species {name!r}; expected one of {', '.join(known)} "
                             "or a .toml parameter file", path=where, field=fld)
        if name.endswith(".toml") and path is not None and \
                not (Path(path).parent / name).is_file() and not Path(name).is_file():
            raise InputError(f"no such species file {name!r}", path=where, field=fld)


def parse_recipe(data: dict, *, path: str | os.PathLike | None = None,
                 name: str | None = None) -> Recipe:
    """Validate a parsed recipe table (``path`` names it in errors)."""
    path = Path(path) if path is not None else None
    where = path if path is not None else "<recipe>"
    if not isinstance(data, dict):
        raise InputError(f"expected a table, got {type(data).__name__}", path=where)
    known = {"step", "render", "description", "name", "seed"}
    for key in data:
        if key not in known:
            raise InputError(f"unknown field; expected one of {', '.join(sorted(known))}",
                             path=where, field=key)
    steps_t = require(data, "step", list, path=where)
    if not steps_t:
        raise InputError("expected at least one [[step]]", path=where, field="step")
    steps = []
    for i, t in enumerate(steps_t):
        prefix = f"step[{i}]"
        if not isinstance(t, dict):
            raise InputError(f"expected a table, got {t!r}", path=where, field=prefix)
        kind = require(t, "kind", str, path=where, prefix=prefix)
        if kind not in KINDS:
            raise InputError(f"unknown step kind {kind!r}; expected one of {', '.join(KINDS)}",
                             path=where, field=f"{prefix}.kind")
        params = _check_table(t, SPECS[kind], where, prefix, skip=("kind",))
        if kind == "displace" and params["mask_range"][1] < params["mask_range"][0]:
            raise InputError(f"expected lo <= hi, got {params['mask_range']}", path=where,
                             field=f"{prefix}.mask_range")
        if kind == "scatter" and params["altitude_range"][1] < params["altitude_range"][0]:
            raise InputError(f"expected lo <= hi, got {params['altitude_range']}", path=where,
                             field=f"{prefix}.altitude_range")
        if kind == "scatter" and params["species"].strip():
            _check_species(params["species"], path, where, f"{prefix}.species")
        if kind == "refine-terrain":
            m = params["control_size"] - 1
            if m & (m - 1):
                raise InputError(f"expected 2**k + 1 (3, 5, 9, 17, 33, ...), got "
                                 f"{params['control_size']}", path=where,
                                 field=f"{prefix}.control_size")
        if kind == "animate":
            _check_simulation(params, path, where, prefix)
        steps.append(Step(kind=kind, params=params, index=i))
    render = _check_table(require(data, "render", dict, path=where, default={}), _RENDER,
                          where, "render")
    desc = require(data, "description", str, path=where, default="")
    seed = require(data, "seed", int, path=where, default=None)
    if seed is not None and seed < 0:
        raise InputError(f"expected an integer >= 0, got {seed}", path=where, field="seed")
    nm = name or require(data, "name", str, path=where, default=None) or \
        (path.stem if path is not None else "recipe")
    return Recipe(name=nm, path=path, steps=steps, render=render, description=desc, seed=seed)


def load_recipe(recipe: str | os.PathLike | dict | Recipe) -> Recipe:
    """A shipped recipe by name, a TOML file, or an already-parsed table."""
    if isinstance(recipe, Recipe):
        return recipe
    if isinstance(recipe, dict):
        return parse_recipe(recipe)
    s = str(recipe)
    if s in recipe_names():
        path = RECIPE_DIR / f"{s}.toml"
    else:
        path = Path(s)
        if path.suffix.lower() != ".toml":
            raise InputError(f"expected a shipped recipe ({', '.join(recipe_names())}) or a "
                             ".toml file", path=s)
    return parse_recipe(read_toml(path), path=path)
