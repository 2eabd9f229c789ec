"""Virtual capture of a sheet-of-light scan: scan frames plus calibration captures.

Moving the camera instead of the object
---------------------------------------
A turntable turns the object by ``phi_k`` about its axis: the camera sees
``cam_from_world @ R(phi_k) @ p_object``. Keeping the object still and moving the
camera to ``cam_from_world_k = cam_from_world @ R(phi_k)`` and the laser by
``R(phi_k)^-1`` gives exactly the same image (every ray, shadow and incidence angle is
the same up to one rigid motion of the whole configuration), while the Embree scene is
built once for the whole scan and solid textures stay attached to the object. The
same holds for a linear stage with a translation. The whole scene rides on the stage
(the object and the platter it stands on).

Folder layout (``acquire.capture_io``): ``images/scan_0000.png`` (8- or 16-bit, the
laser's colour channel), ``images/calib_*``, ``capture.json``, and for evaluation only
``gt/stripe.npy`` (``(k, 3)``: frame, row, true sub-pixel column of the sheet),
``gt/mesh.ply`` (the scene surface at frame 0) and optional ``gt/depth_0000.npy``.

What a real bench knows goes into the capture proper: image size, the stage reading of
each frame, the target's geometry. The true camera, laser plane and axis go into
``ground_truth`` only.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from acquire.capture_io import write_capture
from acquire.laser.rig import LaserCaptureConfig, LaserRig
from acquire.render.laser_sheet import LaserRenderer, camera_directions
from acquire.render.scene import RenderScene
from core.config import to_dict
from core.files import atomic_dir
from core.progress import track

log = logging.getLogger(__name__)

__all__ = ["capture", "board_poses_camera", "board_poses_laser", "board_pose_axis"]

_CALIB_AMBIENT = 0.8  # room light on while the calibration target is imaged


def _write_png(path: Path, img: np.ndarray):
    import cv2

    if not cv2.imwrite(str(path), img, [cv2.IMWRITE_PNG_COMPRESSION, 1]):
        raise RuntimeError(f"could not write {path}")


def _facing(center: np.ndarray, eye: np.ndarray, target, tilt_x: float, tilt_y: float,
            spin: float) -> np.ndarray:
    """``world_from_target`` of a board centred at ``center`` facing ``eye``, then tilted."""
    import cv2

    z = center - eye
    z /= np.linalg.norm(z)
    x = np.cross([0.0, 0.0, -1.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=1) @ cv2.Rodrigues(np.array([tilt_x, tilt_y, spin]))[0]
    w, h = target.size_m()
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = center - R @ np.array([w / 2, h / 2, 0.0])
    return T


def board_poses_camera(camera: Camera, target, n: int, rng: np.random.Generator,
                       distance: float) -> list[np.ndarray]:
    """``n`` board poses spread over the image and tilted up to 35 degrees (Zhang's advice:
    many orientations, corners of the image covered)."""
    Tw = camera.world_from_cam
    out = []
    grid = [(gx, gy) for gy in (-1, 0, 1) for gx in (-1, 0, 1)]
    for i in range(n):
        gx, gy = grid[i % len(grid)] if i < len(grid) else rng.uniform(-1, 1, 2)
        d = distance * rng.uniform(0.85, 1.15)
        px = np.array([camera.cx + gx * 0.28 * camera.width, camera.cy + gy * 0.26 * camera.height])
        xy = camera.normalized(px[None])[0]
        c = Tw[:3, :3] @ (np.array([xy[0], xy[1], 1.0]) * d) + Tw[:3, 3]
        tilt = np.radians(rng.uniform(15, 35)) * np.sign(rng.uniform(-1, 1, 2))
        out.append(_facing(c, camera.center, target, tilt[0], tilt[1],
                           np.radians(rng.uniform(-15, 15))))
    return out


def board_poses_laser(rig: LaserRig, target, camera: Camera, n: int,
                      rng: np.random.Generator) -> list[np.ndarray]:
    """``n`` board poses crossing the laser sheet at different depths and tilts."""
    aim = rig.aim
    view = aim - camera.center
    view /= np.linalg.norm(view)
    out = []
    for i in range(n):
        f = (i / max(n - 1, 1)) - 0.5
        c = aim + view * (0.08 * f) + np.array([0, 0, 0.02 * rng.uniform(-1, 1)])
        out.append(_facing(c, camera.center, target, np.radians(rng.uniform(-20, 20)),
                           np.radians(25 * (-1) ** i + rng.uniform(-5, 5)),
                           np.radians(rng.uniform(-10, 10))))
    return out


def board_pose_axis(rig: LaserRig, target, camera: Camera) -> np.ndarray:
    """``object_from_target``: the board standing on the platter, facing the camera at 0."""
    c = rig.aim + np.array([0.05, 0.0, 0.0])
    eye = np.array([camera.center[0], camera.center[1], c[2]])  # upright board
    return _facing(c, eye, target, 0.0, 0.0, 0.0)


def _hires(camera: Camera, s: int) -> Camera:
    """The camera with s x s pixels per pixel: box-averaging its image supersamples."""
    return Camera(camera.width * s, camera.height * s, camera.fx * s, camera.fy * s,
                  camera.cx * s + (s - 1) / 2, camera.cy * s + (s - 1) / 2, camera.dist,
                  camera.cam_from_world)


def _calib_image(target, world_from_target, cam_hi, dirs_hi, s, laser, ambient, sensor, rng):
    scene = RenderScene([target.scene_object("target", world_from_target)], [], ambient=ambient)
    rend = LaserRenderer(scene, cam_hi, dirs_cam=dirs_hi)
    fr = rend.frame(cam_hi.cam_from_world, laser, rng=rng)
    H, W = cam_hi.height // s, cam_hi.width // s
    rad = fr.radiance.reshape(H, s, W, s).mean(axis=(1, 3))
    return sensor.apply(rad, rng)


def _scan_frames(scene, rig, cam0, laser0, sensor, positions, gt_depth, rng, tmp: Path):
    """The scan: one frame per stage reading, and the true stripe (for evaluation)."""
    # -- scan frames --------------------------------------------------------------------
    renderer = LaserRenderer(scene, cam0, bounces=rig.bounces)
    frames, stripes, lit_counts = [], [], []
    key = "angle_deg" if rig.motion == "turntable" else "position_m"
    for k, pos in enumerate(track(positions, "laser scan")):
        W = rig.world_from_object(pos)
        fr = renderer.frame(cam0.cam_from_world @ W, laser0.transformed(np.linalg.inv(W)),
                            rng=rng)
        img = sensor.apply(fr.radiance, rng)
        rel = f"images/scan_{k:04d}.png"
        _write_png(tmp / rel, img)
        entry = {"image": rel, "camera": "cam0", key: float(pos)}
        if gt_depth:
            np.save(tmp / "gt" / f"depth_{k:04d}.npy", fr.depth)
            entry["gt_depth"] = f"gt/depth_{k:04d}.npy"
        frames.append(entry)
        if len(fr.stripe):
            stripes.append(np.column_stack([np.full(len(fr.stripe), k), fr.stripe]))
        lit_counts.append(fr.lit)
    stripe = np.concatenate(stripes) if stripes else np.zeros((0, 3))
    np.save(tmp / "gt" / "stripe.npy", stripe.astype(np.float64))
    return frames, stripe, lit_counts, key


def _calibration_captures(rig, cam0, laser0, sensor, target, positions, rng, tmp: Path):
    """The camera, laser-plane and axis (or stage) calibration captures."""
    # -- calibration captures -------------------------------------------------------------
    s = rig.calib_supersample
    cam_hi = _hires(cam0, s)
    dirs_hi = camera_directions(cam_hi)
    calib, gt_calib = [], {}
    # a little nearer than the object: the board fills more of the image, which pins
    # the focal length and principal point down better (measured: 0.8x halves their std)
    cam_poses = board_poses_camera(cam0, target, rig.camera_views, rng,
                                   0.8 * rig.working_distance)
    names = []
    for i, T in enumerate(track(cam_poses, "camera calibration")):
        img = _calib_image(target, T, cam_hi, dirs_hi, s, None, _CALIB_AMBIENT, sensor, rng)
        rel = f"images/calib_camera_{i:02d}.png"
        _write_png(tmp / rel, img)
        names.append(rel)
    calib.append({"kind": "camera", "camera": "cam0", "images": names,
                  "target": target.to_dict()})
    gt_calib["camera_target_poses"] = [(cam0.cam_from_world @ T).tolist() for T in cam_poses]
    pairs = []
    laser_poses = board_poses_laser(rig, target, cam0, rig.laser_views, rng)
    for i, T in enumerate(track(laser_poses, "laser-plane calibration")):
        off = _calib_image(target, T, cam_hi, dirs_hi, s, None, _CALIB_AMBIENT, sensor, rng)
        on = _calib_image(target, T, cam_hi, dirs_hi, s, laser0, rig.ambient, sensor, rng)
        pair = [f"images/calib_laser_{i:02d}_off.png", f"images/calib_laser_{i:02d}_on.png"]
        _write_png(tmp / pair[0], off)
        _write_png(tmp / pair[1], on)
        pairs.append(pair)
    calib.append({"kind": "laser_plane", "camera": "cam0", "images": pairs,
                  "image_roles": ["laser_off", "laser_on"], "target": target.to_dict()})
    gt_calib["laser_target_poses"] = [(cam0.cam_from_world @ T).tolist()
                                      for T in laser_poses]
    obj_from_target = board_pose_axis(rig, target, cam0)
    if rig.motion == "turntable":
        readings = np.linspace(-rig.axis_span_deg / 2, rig.axis_span_deg / 2, rig.axis_views)
        kind, rkey = "axis", "angles_deg"
    else:
        travel = min(abs(positions[-1] - positions[0]), 0.06)
        readings = np.linspace(-travel / 2, travel / 2, rig.stage_views)
        kind, rkey = "stage", "positions_m"
    names = []
    for i, r in enumerate(track(readings, f"{kind} calibration")):
        T = rig.world_from_object(r) @ obj_from_target
        img = _calib_image(target, T, cam_hi, dirs_hi, s, None, _CALIB_AMBIENT, sensor, rng)
        rel = f"images/calib_{kind}_{i:02d}.png"
        _write_png(tmp / rel, img)
        names.append(rel)
    calib.append({"kind": kind, "camera": "cam0", "images": names,
                  rkey: [float(r) for r in readings], "target": target.to_dict()})
    return calib, gt_calib


def capture(scene: RenderScene, config: LaserCaptureConfig, out_dir, rng: np.random.Generator,
            *, scene_info: dict | None = None, seed: int | None = None,
            gt_mesh=None) -> Path:
    """Render a laser scan of ``scene`` and its calibration captures into ``out_dir``.

    Parameters
    ----------
    scene : acquire.render.scene.RenderScene
        The scene at stage reading 0, in world coordinates (Z up, turntable axis along
        Z through ``config.rig.axis_center``). Its lights are ignored (laser plus ambient).
    config : LaserCaptureConfig
        Rig, sensor, calibration board; ``gt_depth`` also writes each frame's
        ground-truth z-depth (``gt/depth_0000.npy``).
    out_dir : path
        Written atomically (replaced if it exists).
    rng : numpy.random.Generator
        Sensor noise, speckle, calibration poses.
    scene_info : dict, optional
        ``{"path", "name", "seed"}`` recorded in capture.json.
    seed : int, optional
        Recorded in capture.json.
    gt_mesh : open3d.geometry.TriangleMesh, optional
        The ground-truth surface to store as ``gt/mesh.ply`` (default: the scene's
        objects merged).

    Returns
    -------
    Path
        ``out_dir``.
    """
    from core.io.mesh import write_mesh
    from core.meshes import merge_meshes, transform_mesh

    rig = config.rig
    cam0, laser0, sensor = rig.camera(), rig.laser(), config.sensor
    out_dir = Path(out_dir)
    with atomic_dir(out_dir) as tmp:
        (tmp / "images").mkdir()
        (tmp / "gt").mkdir()
        positions = rig.frame_positions()
        frames, _, lit_counts, key = _scan_frames(scene, rig, cam0, laser0, sensor,
                                                       positions, config.gt_depth, rng, tmp)
        calib, gt_calib = _calibration_captures(rig, cam0, laser0, sensor, config.target_obj,
                                                positions, rng, tmp)
        if gt_mesh is None:  # ground truth, for evaluation only
            gt_mesh = merge_meshes([transform_mesh(o.mesh, o.world_from_object)
                                    for o in scene.objects])
        write_mesh(tmp / "gt" / "mesh.ply", gt_mesh)
        data = {
            "kind": "laser",
            "seed": seed,
            "scene": scene_info or {},
            "sensor": sensor.to_dict(),
            "cameras": {"cam0": {"width": cam0.width, "height": cam0.height}},
            "projectors": {"laser0": {"type": "line_laser",
                                      "channel": int(np.argmax(laser0.color))}},
            "rig": {"motion": rig.motion, "readings_key": key,
                    "laser_channel": int(np.argmax(laser0.color)),
                    "bit_depth": sensor.bit_depth},
            "frames": frames,
            "calibration": calib,
            "ground_truth": _ground_truth(config, cam0, laser0, lit_counts, gt_calib),
        }
        write_capture(tmp, data)
    log.info("laser capture: %d frames, %d calibration images -> %s", len(frames),
             sum(len(c["images"]) * (2 if c["kind"] == "laser_plane" else 1) for c in calib),
             out_dir)
    return out_dir


def _ground_truth(config: LaserCaptureConfig, cam0: Camera, laser0, lit_counts,
                  gt_calib: dict) -> dict:
    """capture.json's ``ground_truth`` (evaluation only: no reconstruction reads it)."""
    rig = config.rig
    n_w, d_w = laser0.plane
    axis_dir = np.array([0.0, 0.0, 1.0]) if rig.motion == "turntable" else (
        np.asarray(rig.stage_direction, float) / np.linalg.norm(rig.stage_direction))
    return {
        "camera": cam0.to_dict(),
        "world_from_object_at_reading": "turntable about axis" if
        rig.motion == "turntable" else "translation along direction",
        "laser_plane_world": [*n_w.tolist(), d_w],
        "laser": laser0.to_dict(),
        "axis_point_world": list(map(float, rig.axis_center)),
        "axis_direction_world": axis_dir.tolist(),
        "rig": {**to_dict(rig), "target": dict(config.target)},
        "stripe": "gt/stripe.npy",
        "mesh": "gt/mesh.ply",
        "lit_pixels": lit_counts,
        **gt_calib,
    }


def transform_for_reading(rig: LaserRig, reading: float) -> np.ndarray:
    """``world_from_object`` at a stage reading (helper for evaluation code)."""
    return rig.world_from_object(reading)


__all__ += ["transform_for_reading"]
