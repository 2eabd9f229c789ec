"""Recipes: TOML descriptions of particle systems and cloth, and the shipped ones.

Shipped (``simulate/recipes/*.toml``): ``fireworks``, ``fountain`` (wind, bounces on
the mesh), ``snow`` (settles on the mesh), ``smoke`` (turbulence), ``fire`` (coloured
by temperature) and ``drape`` (cloth over the mesh). :func:`load_recipe` takes one of
these names or a path; :func:`build_particles` / :func:`build_cloth` turn the table
into a system. Errors name the file and the field (:class:`core.validate.InputError`).
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import numpy as np

from core.files import read_toml, require
from core.validate import InputError
from simulate.cloth.mass_spring import Cloth, ClothSpec
from simulate.collisions import ContactParams
from simulate.forces import (
    Attractor,
    Buoyancy,
    Damping,
    ForceSet,
    Gravity,
    Pairwise,
    Turbulence,
    Vortex,
    Wind,
)
from simulate.integrators import METHODS
from simulate.particles.emitters import (
    BoxShape,
    DiscShape,
    Emitter,
    MeshSurface,
    PointShape,
    VelocityDist,
)
from simulate.particles.system import KillPlane, Look, ParticleSystem, Ramp, Sink

__all__ = ["RECIPES", "load_recipe", "build_particles", "build_cloth", "procedural_scan",
           "recipe_kind"]

RECIPES = ("fireworks", "fountain", "snow", "smoke", "fire", "drape")
_DIR = Path(__file__).parent / "recipes"
_FORCES = {"gravity": Gravity, "wind": Wind, "damping": Damping, "turbulence": Turbulence,
           "attractor": Attractor, "vortex": Vortex, "buoyancy": Buoyancy,
           "pairwise": Pairwise}
_SHAPES = {"point": PointShape, "disc": DiscShape, "box": BoxShape}


def load_recipe(name_or_path: str | os.PathLike) -> tuple[dict, Path]:
    """Read a shipped recipe by name or a TOML file; returns ``(table, path)``."""
    s = str(name_or_path)
    path = _DIR / f"{s}.toml" if s in RECIPES else Path(s)
    if s not in RECIPES and path.suffix.lower() != ".toml":
        raise InputError(f"expected a recipe name ({', '.join(RECIPES)}) or a .toml file",
                         path=path)
    table = read_toml(path)
    kind = require(table, "kind", str, path=path)
    if kind not in ("particles", "cloth"):
        raise InputError(f"expected 'particles' or 'cloth', got {kind!r}", path=path,
                         field="kind")
    return table, path


def recipe_kind(table: dict) -> str:
    return table["kind"]


def _make(cls, table: dict, path, prefix: str, *, rename: dict | None = None, **extra):
    """Build dataclass ``cls`` from a TOML table; unknown keys and bad values name the field."""
    if not isinstance(table, dict):
        raise InputError(f"expected a table, got {table!r}", path=path, field=prefix)
    names = {f.name for f in dataclasses.fields(cls)}
    rename = rename or {}
    kwargs = {}
    for key, value in table.items():
        name = rename.get(key, key)
        if name not in names:
            allowed = ", ".join(sorted([rename.get(n, n) for n in names]))
            raise InputError(f"unknown field (allowed: {allowed})", path=path,
                             field=f"{prefix}.{key}")
        kwargs[name] = tuple(map(_tuple, value)) if isinstance(value, list) and value and \
            isinstance(value[0], list) else _tuple(value)
    kwargs.update(extra)
    try:
        obj = cls(**kwargs)
        if hasattr(obj, "pack"):
            obj.pack()  # validates the parameters
        return obj
    except (ValueError, TypeError) as exc:
        raise InputError(str(exc), path=path, field=prefix) from None


def _tuple(v):
    return tuple(v) if isinstance(v, list) else v


def _forces(table, path):
    out = []
    for k, f in enumerate(require(table, "forces", list, path=path, default=[])):
        prefix = f"forces[{k}]"
        f = dict(f)
        kind = require(f, "kind", str, path=path, prefix=prefix)
        f.pop("kind")
        if kind not in _FORCES:
            raise InputError(f"expected one of {', '.join(sorted(_FORCES))}, got {kind!r}",
                             path=path, field=f"{prefix}.kind")
        out.append(_make(_FORCES[kind], f, path, prefix, rename={"noise": "kind"}))
    return out


def _ramp(t, path, prefix):
    return None if t is None else _make(Ramp, t, path, prefix)


def procedural_scan(*, seed: int = 0, radius: float = 0.5, resolution: int = 48):
    """A closed, lumpy stand-in for a scanned object resting on z = 0: the
    :func:`simulate.stand_ins.lumpy_sphere` blob, squashed to 80 % of its height."""
    from core.meshes import make_mesh, mesh_arrays
    from simulate.stand_ins import lumpy_sphere

    v, f = mesh_arrays(lumpy_sphere(radius, resolution=resolution, amplitude=0.25, seed=seed))
    v = v.copy()
    v[:, 2] *= 0.8
    v[:, 2] -= v[:, 2].min()
    return make_mesh(v, f)


def _common(table, path):
    frames = require(table, "frames", int, path=path, default=96)
    fps = require(table, "fps", (int, float), path=path, default=24)
    if frames < 1:
        raise InputError(f"expected an integer >= 1, got {frames}", path=path, field="frames")
    if not fps > 0:
        raise InputError(f"expected a positive number, got {fps}", path=path, field="fps")
    method = require(table, "method", str, path=path, default="rk4")
    if method not in METHODS:
        raise InputError(f"expected one of {', '.join(METHODS)}, got {method!r}", path=path,
                         field="method")
    contact = _make(ContactParams, require(table, "contact", dict, path=path, default={}),
                    path, "contact")
    return frames, float(fps), method, contact


def build_particles(table: dict, path, *, mesh=None, collider=None, rng=None) -> ParticleSystem:
    """A :class:`ParticleSystem` from a recipe table (``mesh`` for mesh emitters)."""
    frames, fps, method, contact = _common(table, path)
    substeps = require(table, "substeps", int, path=path, default=4)
    if substeps < 1:
        raise InputError(f"expected an integer >= 1, got {substeps}", path=path,
                         field="substeps")
    seed = require(table, "seed", int, path=path, default=0)
    rng = np.random.default_rng(seed) if rng is None else rng
    emitters, looks = [], {}
    raw = require(table, "emitters", list, path=path)
    if not raw:
        raise InputError("expected at least one emitter", path=path, field="emitters")
    for k, e in enumerate(raw):
        prefix = f"emitters[{k}]"
        e = dict(e)
        shape_t = dict(e.pop("shape", {"kind": "point"}))
        skind = require(shape_t, "kind", str, path=path, prefix=f"{prefix}.shape")
        shape_t.pop("kind")
        if skind == "mesh":
            if mesh is None:
                raise InputError("a mesh emitter needs a mesh", path=path, field=f"{prefix}.shape")
            shape = MeshSurface.from_mesh(mesh, offset=float(shape_t.get("offset", 0.0)))
        elif skind in _SHAPES:
            shape = _make(_SHAPES[skind], shape_t, path, f"{prefix}.shape")
        else:
            raise InputError(f"expected one of box, disc, mesh, point, got {skind!r}",
                             path=path, field=f"{prefix}.shape.kind")
        vel = _make(VelocityDist, e.pop("velocity", {}), path, f"{prefix}.velocity")
        look_t = dict(e.pop("look", {}))
        name = e.get("name", f"emitter{k}")
        look = Look(color=_ramp(look_t.pop("color", None), path, f"{prefix}.look.color"),
                    size=_ramp(look_t.pop("size", None), path, f"{prefix}.look.size"),
                    alpha=_ramp(look_t.pop("alpha", None), path, f"{prefix}.look.alpha"),
                    mass=_ramp(look_t.pop("mass", None), path, f"{prefix}.look.mass"),
                    palette=tuple(map(tuple, look_t.pop("palette", []))) or None)
        if look_t:
            raise InputError("unknown field (allowed: alpha, color, mass, palette, size)",
                             path=path, field=f"{prefix}.look.{next(iter(look_t))}")
        looks[name] = look
        emitters.append(_make(Emitter, e, path, prefix, shape=shape, velocity=vel, name=name))
    forces = ForceSet(_forces(table, path))
    planes = [_make(KillPlane, p, path, f"kill_planes[{i}]")
              for i, p in enumerate(require(table, "kill_planes", list, path=path, default=[]))]
    sinks = [_make(Sink, p, path, f"sinks[{i}]")
             for i, p in enumerate(require(table, "sinks", list, path=path, default=[]))]
    use_collider = require(table, "collide", bool, path=path, default=False)
    try:
        return ParticleSystem(
            emitters, forces, rng, dt=1.0 / fps, substeps=substeps, method=method,
            collider=collider if use_collider else None, contact=contact, sinks=sinks,
            kill_planes=planes, looks=looks,
            cooling_time=require(table, "cooling_time", float, path=path, default=float("inf")),
            ambient=require(table, "ambient", float, path=path, default=0.0),
            max_particles=require(table, "max_particles", int, path=path, default=2_000_000))
    except ValueError as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(str(exc), path=path) from None


def build_cloth(table: dict, path, *, mesh=None, collider=None) -> tuple[Cloth, int]:
    """A :class:`Cloth` and its substeps per frame from a recipe table.

    ``cloth.height_above_mesh`` centres the sheet over ``mesh`` at that height above
    its top; ``pin`` is ``"none"``, ``"corners"``, ``"edge"`` or a list of indices;
    ``substeps = "auto"`` picks the smallest count within the stable step.
    """
    frames, fps, method, contact = _common(table, path)
    c = dict(require(table, "cloth", dict, path=path))
    pin = c.pop("pin", "none")
    above = c.pop("height_above_mesh", None)
    nx, ny = int(c.get("nx", 20)), int(c.get("ny", 20))
    spacing = float(c.get("spacing", 0.05))
    if above is not None:
        if mesh is None:
            raise InputError("height_above_mesh needs a mesh", path=path,
                             field="cloth.height_above_mesh")
        v = np.asarray(mesh.vertices)
        centre = 0.5 * (v.min(0) + v.max(0))
        c["origin"] = [centre[0] - spacing * (nx - 1) / 2, centre[1] - spacing * (ny - 1) / 2,
                       float(v[:, 2].max()) + float(above)]
    if pin == "corners":
        c["pinned"] = [0, nx - 1]
    elif pin == "edge":
        c["pinned"] = list(range(nx))
    elif isinstance(pin, list):
        c["pinned"] = pin
    elif pin != "none":
        raise InputError(f"expected 'none', 'corners', 'edge' or a list, got {pin!r}",
                         path=path, field="cloth.pin")
    spec = _make(ClothSpec, c, path, "cloth")
    use_collider = require(table, "collide", bool, path=path, default=False)
    try:
        cloth = Cloth(spec, ForceSet(_forces(table, path)), method=method,
                      collider=collider if use_collider else None, contact=contact)
    except ValueError as exc:
        raise InputError(str(exc), path=path) from None
    sub = table.get("substeps", "auto")
    if sub == "auto":
        limit = cloth.stable_step()
        sub = max(1, int(np.ceil(1.0 / fps / (0.8 * limit)))) if np.isfinite(limit) and \
            limit > 0 else 8
    elif not isinstance(sub, int) or isinstance(sub, bool) or sub < 1:
        raise InputError(f"expected an integer >= 1 or 'auto', got {sub!r}", path=path,
                         field="substeps")
    return cloth, int(sub)
