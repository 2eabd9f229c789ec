"""Boid recipes: a named simulation's behaviour parameters (:class:`simulate.boids.BoidParams`)
and run settings, from the shipped ``boid_recipes/*.toml`` or a user's TOML file."""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path

from core.files import read_toml, require
from core.validate import InputError, check_array
from simulate.boids.flock import BoidParams

__all__ = ["Recipe", "load_recipe", "recipe_names"]

# --- recipes -----------------------------------------------------------------------------
_RECIPES = Path(__file__).parent / "recipes"
_FIELDS = {f.name: f for f in dataclasses.fields(BoidParams)}
_OBSTACLES = ("none", "sphere", "torus", "scan")


@dataclass(frozen=True)
class Recipe:
    """A named simulation: behaviour parameters and run settings.

    Attributes
    ----------
    name : str
    params : BoidParams
    n, steps, seed : int
    init_radius : float
        Boids start in a ball of this radius about ``init_centre``.
    init_centre : (3,) float
    frame_every : int
        Write a frame (VTP, animation) every this many steps.
    group_radius : float
        Two boids closer than this are in one group (metrics).
    obstacle : {"none", "sphere", "torus", "scan"}
        Procedural stand-in used when no mesh is given.
    obstacle_size : float
        Its radius (m).
    """

    name: str
    params: BoidParams
    n: int = 200
    steps: int = 500
    seed: int = 0
    init_radius: float = 10.0
    init_centre: tuple = (0.0, 0.0, 0.0)
    frame_every: int = 5
    group_radius: float = 4.0
    obstacle: str = "none"
    obstacle_size: float = 5.0


def recipe_names() -> list[str]:
    """Names of the shipped recipes."""
    return sorted(p.stem for p in _RECIPES.glob("*.toml"))


def _int(table, key, path, prefix, default, lo=1):
    v = require(table, key, int, path=path, prefix=prefix, default=default)
    if v < lo:
        raise InputError(f"expected an integer >= {lo}, got {v}", path=path,
                         field=f"{prefix}.{key}")
    return v


def load_recipe(name_or_path: str | os.PathLike) -> Recipe:
    """A shipped recipe by name (see :func:`recipe_names`) or a TOML file.

    The file holds ``[boids]`` (fields of :class:`BoidParams`) and ``[run]`` (the other
    fields of :class:`Recipe`). Errors name the file and the field.
    """
    s = str(name_or_path)
    path = Path(s)
    if not path.suffix and (_RECIPES / f"{s}.toml").is_file():
        path = _RECIPES / f"{s}.toml"
    elif not path.is_file():
        raise InputError(f"expected a shipped recipe ({', '.join(recipe_names())}) or a "
                         "TOML file", path=s)
    data = read_toml(path)
    unknown = set(data) - {"boids", "run"}
    if unknown:
        raise InputError(f"unknown table(s) {sorted(unknown)}; expected [boids] and [run]",
                         path=path)
    boids = require(data, "boids", dict, path=path, default={})
    run = require(data, "run", dict, path=path, default={})
    kwargs = {}
    for key in boids:
        if key not in _FIELDS:
            raise InputError(f"unknown field; expected one of {', '.join(sorted(_FIELDS))}",
                             path=path, field=f"boids.{key}")
        if key in ("leaders", "probe_rays"):
            kwargs[key] = _int(boids, key, path, "boids", None, lo=0)
        elif key == "model":
            kwargs[key] = require(boids, key, str, path=path, prefix="boids")
        elif key in ("goal", "bounds"):  # an empty list: none (open world, no goal)
            kwargs[key] = require(boids, key, list, path=path, prefix="boids") or None
        else:
            kwargs[key] = require(boids, key, float, path=path, prefix="boids")
    try:
        params = BoidParams(**kwargs)
    except ValueError as exc:
        msg = str(exc)
        fld = msg.split(":", 1)[0]
        raise InputError(msg.split(": ", 1)[-1], path=path, field=f"boids.{fld}") from None
    known = {"n", "steps", "seed", "init_radius", "init_centre", "frame_every",
             "group_radius", "obstacle", "obstacle_size"}
    for key in run:
        if key not in known:
            raise InputError(f"unknown field; expected one of {', '.join(sorted(known))}",
                             path=path, field=f"run.{key}")
    centre = require(run, "init_centre", list, path=path, prefix="run", default=[0.0, 0, 0])
    try:
        centre = tuple(check_array(centre, "init_centre", shape=(3,)).tolist())
    except ValueError as exc:
        raise InputError(str(exc).split(": ", 1)[-1], path=path, field="run.init_centre") \
            from None
    obstacle = require(run, "obstacle", str, path=path, prefix="run", default="none")
    if obstacle not in _OBSTACLES:
        raise InputError(f"expected one of {', '.join(_OBSTACLES)}, got {obstacle!r}",
                         path=path, field="run.obstacle")
    pos = {}
    for key, default in (("init_radius", 10.0), ("group_radius", 4.0),
                         ("obstacle_size", 5.0)):
        pos[key] = require(run, key, float, path=path, prefix="run", default=default)
        if not (math.isfinite(pos[key]) and pos[key] > 0):
            raise InputError(f"expected a number > 0, got {pos[key]}", path=path,
                             field=f"run.{key}")
    return Recipe(name=path.stem, params=params,
                  n=_int(run, "n", path, "run", 200),
                  steps=_int(run, "steps", path, "run", 500),
                  seed=_int(run, "seed", path, "run", 0, lo=0),
                  frame_every=_int(run, "frame_every", path, "run", 5),
                  init_centre=centre, obstacle=obstacle, **pos)
