"""Rendering helpers shared by the stereo and structured-light captures (private)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from acquire.render.lights import PointLight
from acquire.render.renderer import albedo, cast, shade, subsurface_angular, subsurface_spread
from acquire.render.scene import RenderScene
from acquire.stereo.rig import RigConfig, rot_z

__all__ = ["write_gt_meshes", "turntable_scene", "render_light_sets", "rig_lamp", "board_scene",
           "calibration_board_poses", "axis_board_poses",
           "axis_board_mount"]


def turntable_scene(scene: RenderScene, angle_rad: float) -> RenderScene:
    """Every object turned by ``angle_rad`` about the turntable axis (world +Z)."""
    R = rot_z(angle_rad)
    objs = [dataclasses.replace(o, world_from_object=R @ o.world_from_object)
            for o in scene.objects]
    return RenderScene(objs, list(scene.lights), scene.ambient, scene.background)


def rig_lamp(cfg: RigConfig, intensity: float = 0.12) -> PointLight:
    """A lamp just above the rig centre (a ring light, in effect)."""
    Wr = cfg.world_from_rig()
    return PointLight(Wr[:3, 3] + np.array([0.0, 0.0, 0.05]), intensity)


def render_light_sets(scene: RenderScene, camera: Camera, light_sets, *, supersample: int = 2,
                      ambient: float | None = None, bounces: int = 0, rng=None):
    """Render one view under several light sets, casting the camera rays once; surfaces
    reflect by their material toward this camera (glossy highlights move between the
    two cameras of a pair), with ``bounces = 1`` one bounce of indirect light (``rng``);
    light on subsurface materials spreads under them (a projected pattern blurs,
    :func:`acquire.render.renderer.subsurface_spread`).

    Returns
    -------
    radiances : list of (H, W, 3) float32
    depth : (H, W) float32   ground-truth z-depth (centre ray), 0 = background
    """
    s = int(supersample)
    H, W = camera.height, camera.width
    o, d = camera.rays(camera.pixel_grid(supersample=s))
    hits = cast(scene, o, d)
    translucent = any(o.material.brdf == "subsurface" for o in scene.objects)
    alb = albedo(scene, hits) if translucent else None
    rads = [subsurface_spread(scene, camera, hits, s,
                              shade(scene, hits, lights=ls, ambient=ambient, view_dirs=d,
                                    bounces=bounces, rng=rng), alb,
                              angular=subsurface_angular(scene, hits, d, lights=ls, alb=alb)
                              if translucent else None
                              ).reshape(H, W, s * s, 3).mean(axis=2).astype(np.float32)
            for ls in light_sets]
    if s == 1:
        centre = hits
    else:
        o, d = camera.rays(camera.pixel_grid(supersample=1))
        centre = cast(scene, o, d)
    depth = np.where(centre.hit, centre.t, 0.0).reshape(H, W).astype(np.float32)
    return rads, depth


def board_scene(cfg: RigConfig, world_from_target: np.ndarray, lights, ambient: float
                ) -> RenderScene:
    obj = cfg.target().scene_object("board", world_from_target, px_per_square=48)
    return RenderScene([obj], list(lights), ambient)


def _board_pose(cfg: RigConfig, centre: np.ndarray, tilt_x: float, tilt_y: float, roll: float
                ) -> np.ndarray:
    """world_from_target of a board centred at ``centre`` facing the rig, then tilted."""
    from acquire.stereo.rig import rot_y

    Wr = cfg.world_from_rig()
    R = Wr[:3, :3]  # rig axes: board z along the viewing direction (printed face to the rig)
    cx, sx = np.cos(tilt_x), np.sin(tilt_x)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = rot_y(tilt_y)[:3, :3]
    cr, sr = np.cos(roll), np.sin(roll)
    Rz = np.array([[cr, -sr, 0], [sr, cr, 0], [0, 0, 1]])
    Rb = R @ Rx @ Ry @ Rz
    w, h = cfg.target().size_m()
    T = np.eye(4)
    T[:3, :3] = Rb
    T[:3, 3] = centre - Rb @ np.array([w / 2, h / 2, 0.0])
    return T


# board centres across the field of view (in units of the half field at the working
# distance): corners first, so that even a few views constrain the distortion and the
# principal point, which a board kept in the middle of the image leaves loose
_CAL_GRID = ((-1, -1), (1, 1), (1, -1), (-1, 1), (0, 0), (-1, 0), (1, 0), (0, -1), (0, 1))


def calibration_board_poses(cfg: RigConfig, n: int, rng: np.random.Generator) -> list:
    """``n`` board poses in front of the rig, spread over the field of view and tilted.

    The centres cycle through a 3 x 3 grid over the central ~90 % of the image (jittered),
    at depths within the working distance -0.08..+0.06 m, tilted up to 35 degrees.
    """
    Wr = cfg.world_from_rig()
    aim = Wr[:3, 3] + cfg.rig.distance * Wr[:3, 2]
    half_x = cfg.rig.distance * np.tan(np.radians(cfg.camera.fov_deg) / 2)
    half_y = half_x * cfg.camera.height / cfg.camera.width
    out = []
    for i in range(n):
        gx, gy = _CAL_GRID[i % len(_CAL_GRID)]
        off = Wr[:3, :3] @ np.array([(0.45 * gx + rng.uniform(-0.05, 0.05)) * half_x,
                                     (0.45 * gy + rng.uniform(-0.05, 0.05)) * half_y,
                                     rng.uniform(-0.08, 0.06)])
        # tilt away from the image border so the board stays readable there
        tx = np.radians(rng.uniform(-35, 35) if gy == 0 else -gy * rng.uniform(10, 35))
        ty = np.radians(rng.uniform(-35, 35) if gx == 0 else gx * rng.uniform(10, 35))
        out.append(_board_pose(cfg, aim + off, tx, ty, np.radians(rng.uniform(-15, 15))))
    return out


def axis_board_mount(cfg: RigConfig) -> np.ndarray:
    """``table_from_target (4, 4)``: the axis board's jig on the platter at stage angle 0
    (the world frame is the turntable frame: Z on the axis, origin on the platter)."""
    return _board_pose(cfg, np.array([0.02, 0.01, cfg.rig.aim_height]), np.radians(-10.0),
                       np.radians(10.0), 0.0)


def axis_board_poses(cfg: RigConfig, n: int) -> tuple[list, list]:
    """A board fixed on the turntable (:func:`axis_board_mount`), seen at ``n`` stage
    angles in [-40, 40] degrees.

    Returns ``(world_from_target list, angles_deg list)``.
    """
    base = axis_board_mount(cfg)
    angles = np.linspace(-40.0, 40.0, n)
    return [rot_z(np.radians(a)) @ base for a in angles], [float(a) for a in angles]


def write_gt_meshes(out: Path, scene: RenderScene, object_name: str | None) -> dict:
    """World-frame ground-truth meshes (stage angle 0): ``gt/mesh.ply``, ``gt/object.ply``."""
    from core.io.mesh import write_mesh
    from core.meshes import merge_meshes, transform_mesh

    meshes = {o.name: transform_mesh(o.mesh, o.world_from_object) for o in scene.objects}
    write_mesh(out / "gt" / "mesh.ply", merge_meshes(list(meshes.values())))
    info = {"mesh": "gt/mesh.ply"}
    if object_name is not None:
        scene.object(object_name)
        write_mesh(out / "gt" / "object.ply", meshes[object_name])
        info["object_mesh"] = "gt/object.ply"
    return info
