"""Virtual capture with a stereo rig on a turntable (passive and active stereo).

For each stage angle the rig records a left/right pair under the lamp (passive)
and, with the projector enabled, a second pair with the random-dot pattern on
(active). Calibration captures: a ChArUco board at several poses seen by both
cameras (``kind = "stereo"``) and a board fixed on the turntable at several stage
angles seen by the left camera (``kind = "axis"``). Ground truth (true cameras,
per-view z-depth) goes under ``ground_truth`` for scoring only.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from acquire.capture_io import write_capture
from acquire.render.projector import PatternProjector
from acquire.render.scene import RenderScene
from acquire.stereo._rig_render import (
    axis_board_mount,
    axis_board_poses,
    board_scene,
    calibration_board_poses,
    render_light_sets,
    rig_lamp,
    turntable_scene,
    write_gt_meshes,
)
from acquire.stereo.patterns import random_dots
from acquire.stereo.rig import RigConfig
from core.config import to_dict
from core.files import atomic_dir
from core.io.image import write_image
from core.progress import track

__all__ = ["capture"]

_log = logging.getLogger(__name__)


def _calibration_views(rig, left, right, lamp, sensor, rng, tmp: Path):
    """The board seen by both cameras (stereo calibration), then on the turntable (axis)."""
    # -- calibration: board seen by both cameras ---------------------------------
    cal_pairs, cal_gt = [], []
    for i, T in enumerate(track(calibration_board_poses(rig, rig.calibration.views, rng),
                                "stereo calibration views", total=rig.calibration.views)):
        sc = board_scene(rig, T, [lamp], rig.render.ambient)
        pair = []
        for name, cam in (("L", left), ("R", right)):
            (rad,), _ = render_light_sets(sc, cam, [[lamp]], supersample=rig.render.supersample,
                                          ambient=rig.render.ambient)
            rel = f"images/cal_{i:03d}_{name}.png"
            write_image(tmp / rel, sensor.apply(rad, rng))
            pair.append(rel)
        cal_pairs.append(pair)
        cal_gt.append(T)
    # -- calibration: board on the turntable (axis) --------------------------------
    axis_imgs = []
    poses, angles = axis_board_poses(rig, rig.calibration.axis_views)
    for i, T in enumerate(poses):
        sc = board_scene(rig, T, [lamp], rig.render.ambient)
        (rad,), _ = render_light_sets(sc, left, [[lamp]], supersample=rig.render.supersample,
                                      ambient=rig.render.ambient)
        rel = f"images/axis_{i:03d}_L.png"
        write_image(tmp / rel, sensor.apply(rad, rng))
        axis_imgs.append(rel)
    return cal_pairs, cal_gt, axis_imgs, poses, angles


def _object_frames(scene, rig, left, right, lamps, proj, sensor, rng, tmp: Path):
    """The object at every stage angle, with and without the dot projector."""
    # -- object frames ------------------------------------------------------------
    frames, gt_frames = [], []
    sets = [lamps] + ([lamps + [proj]] if proj is not None else [])
    for i, ang in enumerate(track(rig.rig.stage_angles_deg, "stereo frames",
                                  total=len(rig.rig.stage_angles_deg))):
        sc = turntable_scene(scene, np.radians(ang))
        fr = {"stage_angle_deg": float(ang), "images": [], "camera": "left"}
        if proj is not None:
            fr["active_images"] = []
        gt = {"depth": []}
        for name, cam in (("L", left), ("R", right)):
            rads, depth = render_light_sets(sc, cam, sets, supersample=rig.render.supersample,
                                            ambient=rig.render.ambient,
                                            bounces=rig.render.bounces, rng=rng)
            rel = f"images/pose_{i:03d}_{name}.png"
            write_image(tmp / rel, sensor.apply(rads[0], rng))
            fr["images"].append(rel)
            if proj is not None:
                rel = f"images/pose_{i:03d}_{name}_dots.png"
                write_image(tmp / rel, sensor.apply(rads[1], rng))
                fr["active_images"].append(rel)
            drel = f"gt/pose_{i:03d}_{name}_depth.npy"
            np.save(tmp / drel, depth)
            gt["depth"].append(drel)
        frames.append(fr)
        gt_frames.append(gt)
    return frames, gt_frames


def capture(scene: RenderScene, rig: RigConfig, out_dir, rng: np.random.Generator, *,
            scene_info: dict | None = None, seed: int | None = None,
            object_name: str | None = None) -> Path:
    """Render a stereo capture folder.

    Parameters
    ----------
    scene : RenderScene
        The object (and its base) standing on the turntable at angle 0.
    rig : RigConfig
    out_dir : path
        Written atomically.
    rng : numpy.random.Generator
        Calibration board poses, dot pattern and sensor noise.
    scene_info : dict, optional
        Stored as capture.json "scene" (path, name, seed).
    object_name : str, optional
        The scanned object among the scene's objects: its mesh is stored as ground
        truth ``gt/object.ply`` (its size sets the evaluation threshold).

    Returns
    -------
    Path of the capture folder.
    """
    sensor = rig.sensor
    left, right = rig.stereo_cameras()
    lamp = rig_lamp(rig)
    lamps = list(scene.lights) or [lamp]
    proj = None
    if rig.projector.enabled:
        pattern = random_dots(rig.projector.width, rig.projector.height, rng=rng,
                              density=rig.projector.density,
                              dot_sigma_px=rig.projector.dot_sigma_px)
        proj = PatternProjector(rig.dot_projector_camera(), pattern, rig.projector.intensity)
    out_dir = Path(out_dir)
    with atomic_dir(out_dir) as tmp:
        (tmp / "images").mkdir()
        (tmp / "gt").mkdir()
        cal_pairs, cal_gt, axis_imgs, poses, angles = _calibration_views(
            rig, left, right, lamp, sensor, rng, tmp)
        frames, gt_frames = _object_frames(scene, rig, left, right, lamps, proj, sensor, rng,
                                           tmp)
        data = {
            "kind": "stereo",
            "seed": seed,
            "scene": scene_info or {},
            "sensor": sensor.to_dict(),
            "cameras": {"left": {"width": rig.camera.width, "height": rig.camera.height},
                        "right": {"width": rig.camera.width, "height": rig.camera.height}},
            "projectors": ({"dots": {"width": rig.projector.width,
                                     "height": rig.projector.height, "pattern": "random_dots"}}
                           if proj is not None else {}),
            "rig": {"kind": "turntable-stereo", "stage_angles_deg": list(rig.rig.stage_angles_deg),
                    "working_range": list(rig.rig.working_range),
                    "nominal_baseline": rig.rig.baseline},
            "frames": frames,
            "calibration": [
                {"kind": "stereo", "images": cal_pairs, "cameras": ["left", "right"],
                 "target": rig.target().to_dict()},
                {"kind": "axis", "images": axis_imgs, "camera": "left",
                 "stage_angles_deg": angles, "target": rig.target().to_dict(),
                 # the board's jig on the platter (stage angle 0): a drawing, not a
                 # measurement; it fixes the turntable frame's origin and heading
                 "table_from_target": axis_board_mount(rig).tolist()},
            ],
            "ground_truth": {
                "cameras": {"left": left.to_dict(), "right": right.to_dict()},
                "projector": None if proj is None else proj.camera.to_dict(),
                "axis": {"point": [0.0, 0.0, 0.0], "direction": [0.0, 0.0, 1.0]},
                "frames": gt_frames,
                "calibration_board_poses": [T.tolist() for T in cal_gt],
                "axis_board_poses": [T.tolist() for T in poses],
                "rig_config": to_dict(rig),
            },
        }
        data["ground_truth"].update(write_gt_meshes(tmp, scene, object_name))
        write_capture(tmp, data)
    return out_dir
