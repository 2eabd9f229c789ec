"""Scenes: a TOML spec -> render scene + ground-truth meshes, and scene folders.

Spec (see ``data_synth/scene_specs/*.toml`` for the built-in ones)::

    [scene]
    name = "mine"          # optional
    seed = 0               # noise of procedural shapes and textures
    ambient = 0.1
    [[lights]]             # type = "point" (position) or "directional" (direction)
    type = "point"
    position = [0.5, -0.5, 1.0]
    intensity = 1.0
    [[objects]]
    name = "ball"
    shape = "sphere"       # sphere | box | cylinder | torus | plane | blob | terrain |
                           # lsystem | shell | mesh | charuco | chessboard
    radius = 0.05          # shape parameters (see data_synth.shapes)
    position = [0, 0, 0.05]
    rotation_deg = [0, 0, 0]   # extrinsic X, then Y, then Z rotations, degrees
    scale = 1.0
    rest_on = 0.0          # optional: translate so the lowest point sits at this z
    material = { kind = "solid", texture = "fbm", albedo = [0.8, 0.5, 0.3], scale = 40 }

A scene folder holds ``scene.toml`` (the full spec, seed included: it rebuilds the
scene bit for bit), ``mesh.ply`` (all objects, world frame, the ground truth),
``objects/NAME.ply`` and ``materials.json``.
"""

from __future__ import annotations

import copy
import os
from importlib import resources
from pathlib import Path

import numpy as np

from acquire.render.lights import DirectionalLight, PointLight
from acquire.render.materials import Material
from acquire.render.scene import RenderScene, SceneObject
from acquire.targets import target_from_dict
from core.files import atomic_dir, read_toml, require, write_json, write_toml
from core.frames import euler_xyz_deg
from core.io.mesh import read_mesh, write_mesh
from core.meshes import transform_mesh
from core.validate import InputError
from data_synth import shapes
from data_synth.bundle import SceneBundle

__all__ = ["build_scene", "load_scene", "write_scene", "scene_names", "scene_spec_path"]

SHAPES = ("sphere", "box", "cylinder", "torus", "plane", "blob", "terrain", "lsystem", "shell",
          "mesh", "charuco", "chessboard")


def scene_names() -> list[str]:
    """Names of the built-in scenes."""
    return sorted(p.name[:-5] for p in resources.files("data_synth.scene_specs").iterdir()
                  if p.name.endswith(".toml"))


def _vec(table, key, n, *, path, prefix, default=None):
    v = require(table, key, list, path=path, prefix=prefix,
                default=None if default is None else list(default))
    if v is None:
        raise InputError("missing", path=path, field=f"{prefix}.{key}")
    if len(v) != n or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
        raise InputError(f"expected {n} numbers, got {v!r}", path=path, field=f"{prefix}.{key}")
    return np.asarray(v, float)


def _material(tbl, *, path, prefix, seed) -> Material:
    if tbl is None:
        tbl = {}
    if not isinstance(tbl, dict):
        raise InputError("expected a table", path=path, field=prefix)
    kw = {}
    kw["kind"] = require(tbl, "kind", str, path=path, prefix=prefix, default="constant")
    if "albedo" in tbl:
        kw["albedo"] = _vec(tbl, "albedo", 3, path=path, prefix=prefix)
    for key in ("scale", "contrast"):
        if key in tbl:
            kw[key] = require(tbl, key, float, path=path, prefix=prefix)
    if "texture" in tbl:
        kw["texture"] = require(tbl, "texture", str, path=path, prefix=prefix)
    if "brdf" in tbl:
        kw["brdf"] = require(tbl, "brdf", str, path=path, prefix=prefix)
    for key in ("roughness", "ior", "mfp", "transmission", "anisotropy"):
        if key in tbl:
            kw[key] = require(tbl, key, float, path=path, prefix=prefix)
    known = {"kind", "albedo", "scale", "contrast", "texture", "seed", "brdf", "roughness",
             "ior", "mfp", "transmission", "anisotropy"}
    for key in tbl:
        if key not in known:
            raise InputError(f"unknown key; expected one of {', '.join(sorted(known))}",
                             path=path, field=f"{prefix}.{key}")
    kw["seed"] = require(tbl, "seed", int, path=path, prefix=prefix, default=seed)
    try:
        return Material(**kw)
    except ValueError as exc:
        raise InputError(str(exc), path=path, field=prefix) from None


def _shape(obj, shape, *, path, prefix, seed, base_dir):
    def num(key, default=...):
        return require(obj, key, float, path=path, prefix=prefix, default=default)

    def integer(key, default=...):
        return require(obj, key, int, path=path, prefix=prefix, default=default)

    try:
        if shape == "sphere":
            return shapes.sphere(num("radius"))
        if shape == "box":
            return shapes.box(_vec(obj, "size", 3, path=path, prefix=prefix))
        if shape == "cylinder":
            return shapes.cylinder(num("radius"), num("height"))
        if shape == "torus":
            return shapes.torus(num("radius"), num("tube"))
        if shape == "plane":
            return shapes.plane(_vec(obj, "size", 2, path=path, prefix=prefix))
        if shape == "blob":
            return shapes.blob(num("radius"), amplitude=num("amplitude", 0.18),
                               frequency=num("frequency", 1.4),
                               subdivisions=require(obj, "subdivisions", int, path=path,
                                                    prefix=prefix, default=5),
                               seed=require(obj, "seed", int, path=path, prefix=prefix,
                                            default=seed))
        if shape == "terrain":
            return shapes.terrain(num("size"), samples=integer("samples", 65),
                                  height=num("height", 0.005),
                                  method=require(obj, "method", str, path=path, prefix=prefix,
                                                 default="fbm"),
                                  hurst=num("hurst", 0.8), frequency=num("frequency", 3.0),
                                  seed=integer("seed", seed))
        if shape == "lsystem":
            n = require(obj, "n", int, path=path, prefix=prefix, default=-1)
            return shapes.lsystem_plant(require(obj, "grammar", str, path=path, prefix=prefix),
                                        height=num("height"), n=None if n < 0 else n,
                                        seed=integer("seed", seed),
                                        min_radius=num("min_radius", 0.0),
                                        sides=integer("sides", 8),
                                        leaves=require(obj, "leaves", bool, path=path,
                                                       prefix=prefix, default=False))
        if shape == "shell":
            return shapes.seashell(require(obj, "preset", str, path=path, prefix=prefix,
                                           default="spherical"),
                                   size=num("size"), n_theta=integer("n_theta", 240),
                                   n_s=integer("n_s", 32))
        if shape == "mesh":
            rel = require(obj, "path", str, path=path, prefix=prefix)
            p = Path(rel) if Path(rel).is_absolute() or base_dir is None else base_dir / rel
            mesh = read_mesh(p)
            mesh.compute_vertex_normals()
            return mesh, None
    except ValueError as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(str(exc), path=path, field=prefix) from None
    raise InputError(f"expected one of {', '.join(SHAPES)}, got {shape!r}", path=path,
                     field=f"{prefix}.shape")


def scene_spec_path(name) -> Path:
    """The spec file of a built-in scene name, a ``.toml`` spec or a scene folder."""
    s = str(name)
    if s in scene_names():
        return Path(str(resources.files("data_synth.scene_specs") / f"{s}.toml"))
    path = Path(s)
    if path.is_dir():
        path = path / "scene.toml"
    if path.suffix != ".toml":
        names = ", ".join(scene_names())
        raise InputError(f"unknown scene; expected a built-in name ({names}) "
                         "or a .toml spec or scene folder", path=s)
    return path


def build_scene(spec_or_name, *, seed: int | None = None) -> SceneBundle:
    """Build a scene from a built-in name, a spec file path, or a spec dict.

    Parameters
    ----------
    spec_or_name : str, path or dict
    seed : int, optional
        Overrides ``[scene].seed``.
    """
    path = None
    base_dir = None
    if isinstance(spec_or_name, dict):
        spec = copy.deepcopy(spec_or_name)
    else:
        path = scene_spec_path(spec_or_name)
        spec = read_toml(path)
        base_dir = path.parent
    head = spec.setdefault("scene", {})
    if not isinstance(head, dict):
        raise InputError("expected a table", path=path, field="scene")
    if seed is not None:
        head["seed"] = int(seed)
    if "forest" in spec:  # a stand of trees on a terrain (data_synth.forest)
        from data_synth.forest import forest_from_spec

        require(head, "seed", int, path=path, prefix="scene", default=0)
        return forest_from_spec(spec, path=path, base_dir=base_dir)
    scene_seed = require(head, "seed", int, path=path, prefix="scene", default=0)
    head["seed"] = scene_seed
    ambient = require(head, "ambient", float, path=path, prefix="scene", default=0.1)

    lights = []
    for i, lt in enumerate(require(spec, "lights", list, path=path, default=[])):
        pre = f"lights[{i}]"
        kind = require(lt, "type", str, path=path, prefix=pre)
        inten = require(lt, "intensity", float, path=path, prefix=pre, default=1.0)
        color = _vec(lt, "color", 3, path=path, prefix=pre, default=(1, 1, 1))
        try:
            if kind == "point":
                lights.append(PointLight(_vec(lt, "position", 3, path=path, prefix=pre),
                                         inten, color))
            elif kind == "directional":
                lights.append(DirectionalLight(_vec(lt, "direction", 3, path=path, prefix=pre),
                                               inten, color))
            else:
                raise InputError(f"expected 'point' or 'directional', got {kind!r}", path=path,
                                 field=f"{pre}.type")
        except InputError:
            raise
        except ValueError as exc:
            raise InputError(str(exc), path=path, field=pre) from None

    objs_spec = require(spec, "objects", list, path=path)
    if not objs_spec:
        raise InputError("expected at least one object", path=path, field="objects")
    objects, meshes = [], {}
    for i, obj in enumerate(objs_spec):
        pre = f"objects[{i}]"
        if not isinstance(obj, dict):
            raise InputError("expected a table", path=path, field=pre)
        name = require(obj, "name", str, path=path, prefix=pre, default=f"object{i}")
        if name in meshes:
            raise InputError(f"duplicate object name {name!r}", path=path, field=f"{pre}.name")
        shape = require(obj, "shape", str, path=path, prefix=pre)
        obj_seed = scene_seed * 1009 + i
        T = np.eye(4)
        T[:3, :3] = euler_xyz_deg(_vec(obj, "rotation_deg", 3, path=path, prefix=pre,
                                       default=(0, 0, 0)))
        T[:3, 3] = _vec(obj, "position", 3, path=path, prefix=pre, default=(0, 0, 0))
        if shape in ("charuco", "chessboard"):
            params = {k: v for k, v in obj.items() if k not in
                      ("name", "shape", "position", "rotation_deg", "material")}
            try:
                target = target_from_dict({"type": shape, **params})
            except ValueError as exc:
                raise InputError(str(exc), path=path, field=pre) from None
            so = target.scene_object(name, T, object_id=i)
        else:
            mesh, analytic = _shape(obj, shape, path=path, prefix=pre, seed=obj_seed,
                                    base_dir=base_dir)
            scale = require(obj, "scale", float, path=path, prefix=pre, default=1.0)
            if scale <= 0:
                raise InputError(f"expected a positive number, got {scale}", path=path,
                                 field=f"{pre}.scale")
            if scale != 1.0:
                mesh.scale(scale, center=np.zeros(3))
                if analytic and analytic["type"] == "sphere":
                    analytic = {**analytic, "radius": analytic["radius"] * scale}
            if "rest_on" in obj:
                z0 = require(obj, "rest_on", float, path=path, prefix=pre)
                zmin = (np.asarray(mesh.vertices) @ T[:3, :3].T)[:, 2].min()
                T[2, 3] = z0 - zmin
            mat = _material(obj.get("material"), path=path, prefix=f"{pre}.material",
                            seed=obj_seed)
            so = SceneObject(name, mesh, mat, T, i, analytic=analytic)
        objects.append(so)
        meshes[name] = transform_mesh(so.mesh, so.world_from_object)
    rs = RenderScene(objects, lights, ambient)
    return SceneBundle(spec=spec, render_scene=rs, meshes=meshes, base_dir=base_dir)


def write_scene(bundle: SceneBundle, out_dir: str | os.PathLike) -> Path:
    """Write a scene folder atomically (scene.toml, mesh.ply, objects/, materials.json); a
    forest's folder holds its truth instead of objects/ (:func:`data_synth.forest.write_forest`)."""
    if "forest" in bundle.spec:
        from data_synth.forest import write_forest

        return write_forest(bundle, out_dir)
    out = Path(out_dir)
    spec = copy.deepcopy(bundle.spec)
    for obj in spec.get("objects", []):  # make external mesh paths absolute
        if obj.get("shape") == "mesh" and bundle.base_dir is not None:
            p = Path(obj["path"])
            if not p.is_absolute():
                obj["path"] = str((bundle.base_dir / p).resolve())
    with atomic_dir(out) as tmp:
        write_toml(tmp / "scene.toml", spec)
        write_mesh(tmp / "mesh.ply", bundle.gt_mesh())
        (tmp / "objects").mkdir()
        for name, mesh in bundle.meshes.items():
            write_mesh(tmp / "objects" / f"{name}.ply", mesh)
        mats = {}
        for o in bundle.render_scene.objects:
            m = o.material
            mats[o.name] = {"object_id": o.object_id, "kind": m.kind,
                            "albedo": m.albedo.tolist(), "texture": m.texture,
                            "scale": m.scale, "seed": m.seed}
        write_json(tmp / "materials.json", mats)
    return out


def load_scene(path: str | os.PathLike) -> SceneBundle:
    """Rebuild a scene from a scene folder (or its scene.toml) or a built-in name."""
    return build_scene(path)
