"""Structure-from-motion captures: a camera moved along a path around a scene.

:func:`capture` renders every pose of a path (:mod:`acquire.sfm.paths`), passes the
radiance through the sensor model and writes a capture folder: ``capture.json``
(kind ``"sfm"``), ``images/``, ``gt/`` (z-depth per frame, the scene mesh) and a
nerfstudio ``transforms.json`` (OpenGL convention, see :mod:`acquire.sfm.nerfstudio`).

What a real photographer knows goes to ``cameras`` (image size and the nominal lens
intrinsics, as EXIF would give them, optionally perturbed by ``nominal_focal_error``);
the true poses and intrinsics go to ``ground_truth`` for evaluation only.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from acquire.capture_io import write_capture
from acquire.render.renderer import render
from acquire.sensor import Sensor
from acquire.sfm import paths as _paths
from acquire.sfm.nerfstudio import write_transforms
from core.config import Config, option, to_dict
from core.files import atomic_dir
from core.io.image import write_image
from core.io.mesh import write_mesh
from core.progress import track
from core.validate import check_positive

__all__ = ["PathConfig", "SfmCaptureConfig", "capture", "PATH_KINDS"]

log = logging.getLogger(__name__)

PATH_KINDS = ("orbit", "hemisphere", "walk")


@dataclass
class PathConfig(Config):
    """How the camera moves and what it is (a capture TOML's top-level keys; ``[sensor]``)."""

    kind: str = option("orbit", choices=PATH_KINDS, help="camera path")
    views: int = option(24, range="[3, 100000]", help="frames (orbit: split over the rings)")
    elevations_deg: tuple[float, ...] = option(
        (25.0, 45.0), unit="deg", range="[-89, 89]",
        help="orbit ring elevations (the walk's mean elevation is the first)")
    distance: float | None = option(
        None, unit="m", range="(0, inf)",
        help="camera to the scene centre (none: frame the bounding sphere)")
    distance_factor: float = option(0.8, range="(0, inf)",
                                    help="framing of the bounding sphere when distance is none")
    width: int = option(640, unit="px", range="[16, 16384]", help="image width")
    height: int = option(480, unit="px", range="[16, 16384]", help="image height")
    fov_deg: float = option(50.0, unit="deg", range="(0, 170]", help="horizontal field of view")
    nominal_focal_error: float = option(
        0.0, range="(-1, 1)", help="relative error of the nominal (EXIF-like) focal length")
    walk_position_jitter: float = option(0.03, range="[0, inf)",
                                         help="hand-held position jitter (of the distance)")
    walk_aim_jitter: float = option(0.03, range="[0, inf)",
                                    help="hand-held aim jitter (of the distance)")
    walk_roll_deg: float = option(3.0, unit="deg", range="[0, 90]", help="hand-held roll")
    blur_subframes: int = option(1, range="[1, 64]",
                                 help="sub-frames averaged per frame for motion blur (1: none)")
    shutter: float = option(0.5, range="(0, 1]",
                            help="fraction of the time between frames the shutter is open")
    supersample: int = option(2, range="[1, 8]", help="anti-aliasing rays per pixel side")
    auto_exposure: bool = option(
        True, help="scale radiance so the first frame's 99th percentile sits at 85 % of range")
    texture_boost: float = option(
        4.0, range="(0, inf)",
        help="texture frequency factor of solid procedural materials (1: as in the scene)")
    sensor: Sensor = option(default_factory=Sensor, help="the camera's sensor")


@dataclass
class SfmCaptureConfig(PathConfig):
    """Everything ``scanamp capture sfm`` reads: the path, the camera, the seed."""

    seed: int = option(0, range="[0, inf)", help="path jitter and sensor noise seed")


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

    from acquire.render.scene import RenderScene

    check_positive(factor, "texture_boost")
    objs = []
    for o in render_scene.objects:
        m = o.material
        if m.kind == "solid":   # finer texture, full contrast; its reflectance model kept
            m = dataclasses.replace(m, scale=m.scale * factor, contrast=1.0)
        objs.append(dataclasses.replace(o, material=m))
    return RenderScene(objs, list(render_scene.lights), render_scene.ambient,
                       render_scene.background)


def _render_view(render_scene, config: PathConfig, base: Camera, poses, i: int):
    """Radiance (motion-blurred over sub-frames when asked) and true depth of view ``i``."""
    cam = base.with_pose(poses[i])
    if config.blur_subframes > 1:
        nxt = poses[i + 1] if i + 1 < len(poses) else poses[i - 1]
        sub = _paths.subframe_poses(poses[i], nxt, config.blur_subframes,
                                    shutter=config.shutter)
        rad = np.mean([render(render_scene, base.with_pose(T),
                              supersample=config.supersample).radiance for T in sub], 0)
        return rad, render(render_scene, cam, supersample=1).depth
    r = render(render_scene, cam, supersample=config.supersample)
    return r.radiance, r.depth


def capture(render_scene, config: PathConfig, out_dir: str | os.PathLike, *,
            rng: np.random.Generator, scene_ref: dict | None = None, gt_mesh=None,
            seed: int | None = None) -> Path:
    """Render an SfM capture folder.

    Parameters
    ----------
    render_scene : acquire.render.scene.RenderScene
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
            rad, depth = _render_view(render_scene, config, base, poses, i)
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
            "rig": {"path": {k: v for k, v in to_dict(config).items() if k != "seed"},
                    "order": "path order (sequential)",
                    "target": target.tolist(), "distance": radius,
                    "exposure_scale": gain},
            "frames": frames,
            "ground_truth": gt,
        })
        write_transforms(tmp / "transforms.json", cams, [f["image"] for f in frames])
    return Path(out_dir)
