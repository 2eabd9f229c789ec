"""Virtual structured-light capture: a camera and a Gray-code + phase-shift projector.

Pattern sequence per view (``projectors.proj.sequence`` in capture.json): white, black,
the Gray-code images of :func:`acquire.stereo.patterns.gray_code_patterns` (columns then rows,
pattern and inverse per bit), then ``n_steps`` phase-shift images along x and
``n_steps`` along y. The rendering casts the camera rays once per view and evaluates
the projector's footprint and shadows once; each pattern is then a lookup.
Calibration entries: ``kind = "projector"`` (a board at several poses, each with the
full sequence) and ``kind = "axis"`` (a board on the turntable, white light).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from acquire.capture_io import write_capture
from acquire.render.projector import PatternProjector, sample_bilinear
from acquire.render.renderer import albedo, cast, visibility
from acquire.render.scene import RenderScene
from acquire.stereo._rig_render import (
    axis_board_mount,
    axis_board_poses,
    board_scene,
    calibration_board_poses,
    rig_lamp,
    turntable_scene,
    write_gt_meshes,
)
from acquire.stereo.patterns import (
    gray_code_bits,
    gray_code_patterns,
    phase_shift_patterns,
    white_black,
)
from acquire.stereo.rig import RigConfig
from core.config import to_dict
from core.files import atomic_dir
from core.io.image import write_image
from core.progress import track

__all__ = ["capture", "pattern_sequence"]


def pattern_sequence(rig: RigConfig) -> tuple[list, dict]:
    """All projected images and their description (stored in capture.json)."""
    pj = rig.projector
    w, h, period, steps = pj.width, pj.height, pj.period_px, pj.n_steps
    nc, nr = gray_code_bits(w, h)
    pats = (white_black(w, h) + gray_code_patterns(w, h)
            + phase_shift_patterns(w, h, period_px=period, n_steps=steps, axis="x")
            + phase_shift_patterns(w, h, period_px=period, n_steps=steps, axis="y"))
    info = {"width": w, "height": h, "n_col_bits": nc, "n_row_bits": nr,
            "period_px": period, "n_steps": steps,
            "sequence": ["white", "black", f"gray[{2 * (nc + nr)}]", f"phase_x[{steps}]",
                         f"phase_y[{steps}]"]}
    return pats, info


def _render_patterns(scene: RenderScene, camera: Camera, proj: PatternProjector, patterns,
                     sensor, rng, *, supersample: int, ambient: float, bounces: int = 0):
    """Sensor images of one view under each pattern, and the GT depth.

    Each surface reflects the projector by its material toward the camera
    (:func:`acquire.render.renderer.reflect_toward`); with ``bounces = 1`` light of the pattern
    that reached another surface comes back once more (inter-reflections): the bounce
    rays are drawn once per view (:func:`acquire.render.renderer.bounce_rays`), and each pattern
    only changes what the surfaces they meet receive. On subsurface materials each
    pattern spreads under the surface (:func:`acquire.render.renderer.subsurface_spread`)."""
    from acquire.render.renderer import (
        SubsurfaceAngular,
        bounce_rays,
        exit_weights,
        reflect_toward,
        subsurface_spread,
        subsurface_weights,
    )

    s = int(supersample)
    H, W = camera.height, camera.width
    o, d = camera.rays(camera.pixel_grid(supersample=s))
    hits = cast(scene, o, d)
    h = np.flatnonzero(hits.hit)
    alb3 = albedo(scene, hits)[h]
    alb = alb3.mean(axis=1)  # a monochrome sensor
    px, factor = _lit_footprint(scene, proj, hits, h)
    refl = reflect_toward(scene, hits, h, proj.camera.center, d[h], alb=alb3).mean(axis=1)
    base = np.zeros(len(hits.hit))
    base[h] = alb * ambient
    second = None
    if bounces:
        b = bounce_rays(scene, hits, h, d[h], rng=rng)
        k = np.flatnonzero(b.hits.hit)
        px2, f2 = _lit_footprint(scene, proj, b.hits, k)
        r2 = reflect_toward(scene, b.hits, k, proj.camera.center, b.wi[k]).mean(axis=1)
        second = (h[b.rows[k]], b.weight[k].mean(axis=1) * r2 * f2, px2)
    translucent = any(o.material.brdf == "subsurface" for o in scene.objects)
    alb_all = np.zeros(len(hits.hit))
    alb_all[h] = alb
    entry = once = exit_w = None
    if translucent:   # the angular parts of the pattern's light (per white pixel)
        wi = proj.camera.center - hits.points[h]
        wi /= np.linalg.norm(wi, axis=1, keepdims=True)
        wo = -d[h] / np.linalg.norm(d[h], axis=1, keepdims=True)
        e, s1 = subsurface_weights(scene, hits, h, wi, wo)
        entry, once = e.mean(axis=1) * factor, (alb3 * s1).mean(axis=1) * factor
        exit_w = exit_weights(scene, hits, d).mean(axis=1)
    out = []
    for pat in patterns:
        rad = base.copy()
        rad[h] += refl * sample_bilinear(pat, px) * factor
        if second is not None:
            np.add.at(rad, second[0], second[1] * sample_bilinear(pat, second[2]))
        if translucent:   # the pattern blurs under marble, wax, skin
            lit = sample_bilinear(pat, px)
            ang = SubsurfaceAngular(np.zeros(len(hits.hit)), exit_w, np.zeros(len(hits.hit)))
            ang.entry[h], ang.single[h] = entry * lit, once * lit
            rad = subsurface_spread(scene, camera, hits, s, rad, alb_all, angular=ang)
        img = rad.reshape(H, W, s * s).mean(axis=2)
        out.append(sensor.apply(img, rng))
    o, d = camera.rays(camera.pixel_grid())
    c = cast(scene, o, d)
    depth = np.where(c.hit, c.t, 0.0).reshape(H, W).astype(np.float32)
    return out, depth


def _lit_footprint(scene: RenderScene, proj: PatternProjector, hits, rows):
    """Projector pixels of the hits ``rows`` and the light a white pixel brings them
    (0 in the projector's shadow)."""
    px, factor = proj.footprint(hits.points[rows], hits.normals[rows])
    lit = factor > 0
    vis = np.zeros(len(rows), bool)
    if lit.any():
        vis[lit] = visibility(scene, proj, hits.points[rows][lit],
                              hits.geo_normals[rows][lit])
    return px, factor * vis


def capture(scene: RenderScene, rig: RigConfig, out_dir, rng: np.random.Generator, *,
            scene_info: dict | None = None, seed: int | None = None,
            object_name: str | None = None) -> Path:
    """Render a structured-light capture folder (see the module docstring)."""
    sensor = dataclasses.replace(rig.sensor, mono=True)
    shade = {"supersample": rig.render.supersample, "ambient": rig.render.ambient,
             "bounces": rig.render.bounces}
    cam, pcam = rig.sl_devices()
    pats, info = pattern_sequence(rig)
    proj = PatternProjector(pcam, pats[0], rig.projector.intensity)
    lamp = rig_lamp(rig)
    out_dir = Path(out_dir)
    with atomic_dir(out_dir) as tmp:
        (tmp / "images").mkdir()
        (tmp / "gt").mkdir()

        def save(prefix, imgs):
            rels = []
            for k, im in enumerate(imgs):
                rel = f"images/{prefix}_{k:02d}.png"
                write_image(tmp / rel, im)
                rels.append(rel)
            return rels

        cal = []
        poses = calibration_board_poses(rig, rig.calibration.views, rng)
        for i, T in enumerate(track(poses, "projector calibration views", total=len(poses))):
            sc = board_scene(rig, T, [], rig.render.ambient)
            imgs, _ = _render_patterns(sc, cam, proj, pats, sensor, rng,
                                       **shade)
            cal.append(save(f"cal_{i:03d}", imgs))
        axis_imgs = []
        aposes, angles = axis_board_poses(rig, rig.calibration.axis_views)
        for i, T in enumerate(aposes):
            sc = board_scene(rig, T, [lamp], rig.render.ambient)
            imgs, _ = _render_patterns(sc, cam, proj, pats[:1], sensor, rng,
                                       **shade)
            axis_imgs += save(f"axis_{i:03d}", imgs)
        frames, gt_frames = [], []
        for i, ang in enumerate(track(rig.rig.stage_angles_deg, "structured-light frames",
                                      total=len(rig.rig.stage_angles_deg))):
            sc = turntable_scene(scene, np.radians(ang))
            imgs, depth = _render_patterns(sc, cam, proj, pats, sensor, rng,
                                           **shade)
            _, pdepth = _render_patterns(sc, pcam, proj, [], sensor, rng, supersample=1,
                                         ambient=0.0, bounces=0)
            frames.append({"stage_angle_deg": float(ang), "camera": "cam",
                           "images": save(f"pose_{i:03d}", imgs)})
            g = [f"gt/pose_{i:03d}_cam_depth.npy", f"gt/pose_{i:03d}_proj_depth.npy"]
            np.save(tmp / g[0], depth)
            np.save(tmp / g[1], pdepth)
            gt_frames.append({"depth": g})
        data = {
            "kind": "structured-light", "seed": seed, "scene": scene_info or {},
            "sensor": sensor.to_dict(),
            "cameras": {"cam": {"width": rig.camera.width, "height": rig.camera.height}},
            "projectors": {"proj": info},
            "rig": {"kind": "turntable-structured-light",
                    "stage_angles_deg": list(rig.rig.stage_angles_deg),
                    "working_range": list(rig.rig.working_range)},
            "frames": frames,
            "calibration": [
                {"kind": "projector", "images": cal, "camera": "cam", "projector": "proj",
                 "target": rig.target().to_dict()},
                {"kind": "axis", "images": axis_imgs, "camera": "cam",
                 "stage_angles_deg": angles, "target": rig.target().to_dict(),
                 # the board's jig on the platter (stage angle 0): a drawing, not a
                 # measurement; it fixes the turntable frame's origin and heading
                 "table_from_target": axis_board_mount(rig).tolist()},
            ],
            "ground_truth": {
                # "left"/"right" = camera/projector, as for stereo (the projector's depth
                # map is its shadow map: what it lights)
                "cameras": {"left": cam.to_dict(), "right": pcam.to_dict()},
                "frames": gt_frames, "rig_config": to_dict(rig),
                "calibration_board_poses": [T.tolist() for T in poses],
            },
        }
        data["ground_truth"].update(write_gt_meshes(tmp, scene, object_name))
        write_capture(tmp, data)
    return out_dir
