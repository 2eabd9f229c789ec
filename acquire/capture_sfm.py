"""Structure-from-motion captures: a camera moved along a path around a scene.

:func:`capture` renders every pose of a path (:mod:`acquire.paths`), passes the
radiance through the sensor model and writes a capture folder: ``capture.json``
(kind ``"sfm"``), ``images/``, ``gt/`` (z-depth per frame, the scene mesh) and a
nerfstudio ``transforms.json`` (OpenGL convention, see :mod:`acquire.nerfstudio`).

What a real photographer knows goes to ``cameras`` (image size and the nominal lens
intrinsics, as EXIF would give them, optionally perturbed by ``nominal_focal_error``);
the true poses and intrinsics go to ``ground_truth`` for evaluation only.
"""

from __future__ import annotations

import logging
import os
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np

from acquire import paths as _paths
from acquire.camera import Camera
from acquire.capture_io import write_capture
from acquire.nerfstudio import write_transforms
from acquire.render import render
from acquire.sensor import Sensor
from core.files import atomic_dir, require
from core.image_io import write_image
from core.mesh_io import write_mesh
from core.progress import track
from core.validate import InputError, check_choice, check_int, check_positive

__all__ = ["PathConfig", "capture", "path_config_from_toml", "PATH_KINDS"]

log = logging.getLogger(__name__)

PATH_KINDS = ("orbit", "hemisphere", "walk")


@dataclass
class PathConfig:
    """How the camera moves and what it is.

    Attributes
    ----------
    kind : {'orbit', 'hemisphere', 'walk'}
    views : int
        Number of frames (orbit: split evenly over the rings).
    elevations_deg : list of float
        Orbit ring elevations; the walk uses the first as its mean elevation.
    distance : float or None
        Camera distance from the scene centre in metres; None frames the scene's
        bounding sphere in the vertical field of view (times ``distance_factor``).
    distance_factor : float
    auto_exposure : bool
        Scale the radiance so that the first frame's 99th percentile sits at 85 % of
        the sensor's range (as a camera's metering would), recorded in ``rig``.
    width, height : int
    fov_deg : float
        Horizontal field of view.
    nominal_focal_error : float
        Relative error of the focal length written as the nominal (EXIF-like) one.
    walk_position_jitter, walk_aim_jitter, walk_roll_deg : float
        Hand-held jitter (fractions of the distance; degrees).
    blur_subframes : int
        Sub-frame renders averaged per frame for motion blur (1 = none).
    shutter : float
        Fraction of the time between frames the shutter is open.
    supersample : int
        Anti-aliasing rays per pixel side.
    texture_boost : float
        Feature-rich textures for SfM: every solid procedural material gets this many
        times its texture frequency at full contrast (1 keeps the scene's materials).
    sensor : Sensor
    """

    kind: str = "orbit"
    views: int = 24
    elevations_deg: list = field(default_factory=lambda: [25.0, 45.0])
    distance: float | None = None
    distance_factor: float = 0.8
    width: int = 640
    height: int = 480
    fov_deg: float = 50.0
    nominal_focal_error: float = 0.0
    walk_position_jitter: float = 0.03
    walk_aim_jitter: float = 0.03
    walk_roll_deg: float = 3.0
    blur_subframes: int = 1
    shutter: float = 0.5
    supersample: int = 2
    auto_exposure: bool = True
    texture_boost: float = 4.0
    sensor: Sensor = field(default_factory=Sensor)

    def __post_init__(self):
        check_choice(self.kind, "kind", PATH_KINDS)
        for name in ("views", "width", "height", "blur_subframes", "supersample"):
            check_int(getattr(self, name), name)
        if self.views < 3:
            raise ValueError(f"views: expected at least 3 views for SfM, got {self.views}")
        check_positive(self.fov_deg, "fov_deg")
        if self.distance is not None:
            check_positive(self.distance, "distance")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["sensor"] = self.sensor.to_dict()
        return d


def path_config_from_toml(data: dict, *, path=None) -> PathConfig:
    """A :class:`PathConfig` from a TOML table (keys as the attributes; ``[sensor]``)."""
    known = {f.name for f in fields(PathConfig)}
    kw = {}
    for key, value in data.items():
        if key not in known:
            raise InputError(f"unknown key; expected one of {', '.join(sorted(known))}",
                             path=path, field=key)
        if key == "sensor":
            tbl = require(data, "sensor", dict, path=path)
            try:
                value = Sensor(**tbl)
            except TypeError as exc:
                raise InputError(str(exc), path=path, field="sensor") from None
            except ValueError as exc:
                raise InputError(str(exc), path=path, field="sensor") from None
        kw[key] = value
    try:
        return PathConfig(**kw)
    except ValueError as exc:
        raise InputError(str(exc), path=path) from None


def _poses(cfg: PathConfig, target, radius, rng) -> np.ndarray:
    if cfg.kind == "orbit":
        rings = len(cfg.elevations_deg)
        if cfg.views % rings:
            raise ValueError(f"views: expected a multiple of the {rings} orbit rings, "
                             f"got {cfg.views}")
        return _paths.orbit_rings(target, radius, elevations_deg=cfg.elevations_deg,
                                  views_per_ring=cfg.views // rings)
    if cfg.kind == "hemisphere":
        return _paths.hemisphere(target, radius, cfg.views)
    return _paths.handheld_walk(target, radius, cfg.views, rng=rng,
                                elevation_deg=cfg.elevations_deg[0],
                                position_jitter=cfg.walk_position_jitter,
                                aim_jitter=cfg.walk_aim_jitter,
                                roll_jitter_deg=cfg.walk_roll_deg)


def _boost_textures(render_scene, factor: float):
    import dataclasses

    from acquire.materials import Material
    from acquire.scene import RenderScene

    check_positive(factor, "texture_boost")
    objs = []
    for o in render_scene.objects:
        m = o.material
        if m.kind == "solid":
            m = Material("solid", albedo=m.albedo, texture=m.texture, scale=m.scale * factor,
                         contrast=1.0, seed=m.seed)
        objs.append(dataclasses.replace(o, material=m))
    return RenderScene(objs, list(render_scene.lights), render_scene.ambient,
                       render_scene.background)


def capture(render_scene, config: PathConfig, out_dir: str | os.PathLike, *,
            rng: np.random.Generator, scene_ref: dict | None = None, gt_mesh=None,
            seed: int | None = None) -> Path:
    """Render an SfM capture folder.

    Parameters
    ----------
    render_scene : acquire.scene.RenderScene
    config : PathConfig
    out_dir : path
        Written atomically.
    rng : numpy.random.Generator
        Path jitter and sensor noise.
    scene_ref : dict, optional
        ``{"path", "name", "seed"}`` recorded in capture.json.
    gt_mesh : open3d.geometry.TriangleMesh, optional
        Ground-truth surface, written to ``gt/mesh.ply`` for evaluation.
    seed : int, optional
        Recorded in capture.json.

    Returns
    -------
    Path
    """
    if config.texture_boost != 1.0:
        render_scene = _boost_textures(render_scene, config.texture_boost)
    bounds = render_scene.bounds()
    target = bounds.mean(axis=0)
    bradius = 0.5 * float(np.linalg.norm(bounds[1] - bounds[0]))
    base = Camera.look_at([1.0, 0, 0], [0, 0, 0], width=config.width, height=config.height,
                          fov_deg=config.fov_deg)
    vfov = 2 * np.arctan(0.5 * config.height / base.fy)
    radius = config.distance or config.distance_factor * bradius / np.sin(vfov / 2)
    poses = _poses(config, target, radius, rng)
    nominal_f = base.fx * (1.0 + config.nominal_focal_error)
    frames, gt_cams, cams = [], {}, []
    with atomic_dir(out_dir) as tmp:
        (tmp / "images").mkdir()
        (tmp / "gt").mkdir()
        for i in track(range(len(poses)), "render SfM views", total=len(poses)):
            cam = base.with_pose(poses[i])
            if config.blur_subframes > 1:
                nxt = poses[min(i + 1, len(poses) - 1)] if i + 1 < len(poses) else poses[i - 1]
                sub = _paths.subframe_poses(poses[i], nxt, config.blur_subframes,
                                            shutter=config.shutter)
                rad = np.mean([render(render_scene, base.with_pose(T),
                                      supersample=config.supersample).radiance for T in sub], 0)
                depth = render(render_scene, cam, supersample=1).depth
            else:
                r = render(render_scene, cam, supersample=config.supersample)
                rad, depth = r.radiance, r.depth
            if i == 0:
                p99 = float(np.percentile(rad, 99))
                gain = 0.85 / p99 if (config.auto_exposure and p99 > 0) else 1.0
            img = config.sensor.apply(rad * gain, rng)
            name = f"images/{i:04d}.png"
            write_image(tmp / name, img)
            np.save(tmp / "gt" / f"depth_{i:04d}.npy", depth.astype(np.float32))
            frames.append({"image": name, "camera": "cam0", "depth": f"gt/depth_{i:04d}.npy"})
            gt_cams[name] = cam.to_dict()
            cams.append(cam)
        gt = {"cameras": gt_cams,
              "scene_size": float(np.linalg.norm(bounds[1] - bounds[0])),
              "scene_size_definition": "bounding-box diagonal of the scene (metres)",
              "scene_bounds": bounds.tolist()}
        if gt_mesh is not None:
            write_mesh(tmp / "gt" / "mesh.ply", gt_mesh)
            gt["mesh"] = "gt/mesh.ply"
        # per-frame GT depth lives under ground_truth so a reconstruction never sees it
        for fr in frames:
            fr.pop("depth")
        gt["depth"] = [f"gt/depth_{i:04d}.npy" for i in range(len(poses))]
        write_capture(tmp, {
            "kind": "sfm",
            "seed": seed,
            "scene": scene_ref or {},
            "sensor": config.sensor.to_dict(),
            "cameras": {"cam0": {"width": config.width, "height": config.height,
                                 "fx": nominal_f, "fy": nominal_f, "cx": base.cx, "cy": base.cy,
                                 "dist": [0.0] * 5, "nominal": True}},
            "rig": {"path": config.to_dict(), "order": "path order (sequential)",
                    "target": target.tolist(), "distance": radius,
                    "exposure_scale": gain},
            "frames": frames,
            "ground_truth": gt,
        })
        write_transforms(tmp / "transforms.json", cams, [f["image"] for f in frames])
    return Path(out_dir)
