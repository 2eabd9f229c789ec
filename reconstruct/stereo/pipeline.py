"""Stereo reconstruction pipelines: a turntable capture, or a user's own pair.

Capture pipeline (:func:`run_capture`): stereo calibration from the board views
(``cv2.stereoCalibrate``), the turntable frame from the board mounted on the turntable,
then per stage angle: rectify, SGBM (+ LR check, + WLS), disparity to depth, and TSDF
fusion of all depth maps into one mesh in the turntable (= world) frame, object at stage
angle 0. Rig poses come from that calibration and the reported stage angles; ground
truth is read only to score (disparity metrics, mesh F-score as the mesh lies).

The pair pipeline is :mod:`reconstruct.stereo.pair` (``run_pair``, ``read_disparity``),
the options of both :mod:`reconstruct.stereo.options`, the scoring against ground truth
:mod:`reconstruct.stereo.scoring`.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from acquire.capture_io import Capture, load_capture
from acquire.targets import target_from_dict
from core.files import atomic_dir, json_data, write_json
from core.io.image import read_image
from core.io.mesh import write_mesh, write_points
from core.meshes import sorted_mesh
from core.progress import track
from core.validate import InputError, check_choice
from reconstruct.calibration.camera import detect_board, to_gray
from reconstruct.calibration.rectify import StereoCalibration, rectify, rectify_pair
from reconstruct.calibration.stereo import (
    calibrate_pair,
    calibrate_turntable_axis,
    calibrate_turntable_mount,
    detect_pair_views,
    world_from_cam_at,
)
from reconstruct.evaluation.disparity import disparity_metrics
from reconstruct.result import ReconstructionResult
from reconstruct.stereo.matching import depth_to_points, disparity_range, disparity_to_depth, match
from reconstruct.stereo.options import StereoOptions
from reconstruct.stereo.scoring import (
    calib_errors,
    depth_errors,
    gt_disparity,
    reference_in_table,
    score_mesh,
)
from reconstruct.surface.tsdf import fuse_depth_maps


def _frame_name(axis_report: dict) -> str:
    if axis_report.get("method") == "mount":
        return "world (the turntable frame fixed by the axis board's mount; object at stage 0)"
    return "turntable axis frame (origin height and heading from the axis board)"


__all__ = ["run_capture", "calibrate_capture"]

_log = logging.getLogger(__name__)


def _read(cap: Capture, rel: str, field: str) -> np.ndarray:
    try:
        return read_image(cap.path(rel))
    except InputError as exc:
        raise InputError(exc.message, path=cap.root / "capture.json", field=field) from None


def calibrate_capture(cap: Capture) -> tuple[StereoCalibration, np.ndarray, dict]:
    """Stereo calibration and turntable axis from a capture's calibration entries.

    Returns ``(calibration, table_from_left (4, 4), report)``.
    """
    jpath = cap.root / "capture.json"
    entries = {c["kind"]: (i, c) for i, c in enumerate(cap.calibration)}
    if "stereo" not in entries:
        raise InputError("no calibration entry of kind 'stereo'", path=jpath, field="calibration")
    ci, st = entries["stereo"]
    target = target_from_dict(st["target"])

    def pairs():
        for j, pair in enumerate(st["images"]):
            if not isinstance(pair, list) or len(pair) != 2:
                raise InputError("expected [left, right] image pairs", path=jpath,
                                 field=f"calibration[{ci}].images[{j}]")
            yield (cap.path(pair[0]), _read(cap, pair[0], f"calibration[{ci}].images[{j}][0]"),
                   cap.path(pair[1]), _read(cap, pair[1], f"calibration[{ci}].images[{j}][1]"))

    views = detect_pair_views(target, pairs())
    missed = [os.path.relpath(m, cap.root) for m in views.missed]
    if missed:
        _log.warning("board not detected in %d calibration images: %s", len(missed),
                     ", ".join(missed[:5]))
    if len(views.common) < 3:
        raise InputError(f"board detected in both images of only {len(views.common)} views "
                         f"(need 3); not detected in: {', '.join(missed) or 'none'}",
                         path=jpath, field=f"calibration[{ci}].images")
    calib, rep = calibrate_pair(views.obj1, views.img1, views.obj2, views.img2, views.common,
                                views.image_size)
    report = {"stereo": rep, "undetected": missed}
    if "axis" not in entries:
        raise InputError("no calibration entry of kind 'axis' (board on the turntable)",
                         path=jpath, field="calibration")
    table_from_left, arep = calibrate_axis_entry(cap, *entries["axis"], calib.K1, calib.D1)
    report["axis"] = arep
    return calib, table_from_left, report


def calibrate_axis_entry(cap: Capture, index: int, entry: dict, K: np.ndarray, D: np.ndarray
                         ) -> tuple[np.ndarray, dict]:
    """``table_from_cam (4, 4)`` and a report from a capture's ``kind = "axis"`` entry.

    With the board's mount on the platter (``table_from_target``) the turntable frame
    is fixed completely (:func:`reconstruct.calibration.stereo.calibrate_turntable_mount`):
    the reconstruction lands in the world frame. Without it only the axis is known
    (:func:`reconstruct.calibration.stereo.calibrate_turntable_axis`): origin height and
    heading are the board's.
    """
    jpath = cap.root / "capture.json"
    angles = entry.get("stage_angles_deg")
    if not isinstance(angles, list) or len(angles) != len(entry.get("images", [])):
        raise InputError("expected one stage angle per image", path=jpath,
                         field=f"calibration[{index}].stage_angles_deg")
    target = target_from_dict(entry["target"])
    ao, ap, aa = [], [], []
    for j, rel in enumerate(entry["images"]):
        d = detect_board(target, _read(cap, rel, f"calibration[{index}].images[{j}]"))
        if d is None:
            _log.warning("board not detected in axis image %s", rel)
            continue
        ao.append(d[0])
        ap.append(d[1])
        aa.append(angles[j])
    mount = entry.get("table_from_target")
    need = 3 if mount is None else 1  # a known mount: one view already fixes the frame
    if len(ao) < need:
        raise InputError(f"board detected in only {len(ao)} axis views (need {need})",
                         path=jpath, field=f"calibration[{index}].images")
    if mount is None:
        table_from_cam, rep = calibrate_turntable_axis(ao, ap, aa, K, D)
        rep["method"] = "axis only (no mount: origin and heading from the board)"
        return table_from_cam, rep
    try:
        mount = np.asarray(mount, float).reshape(4, 4)
    except (TypeError, ValueError):
        raise InputError("expected a 4x4 matrix", path=jpath,
                         field=f"calibration[{index}].table_from_target") from None
    return calibrate_turntable_mount(ao, ap, aa, mount, K, D)


def _frame_depth(L, R, rect, mopts):
    lr, rr = rectify_pair(to_gray(L), to_gray(R), rect)
    disp = match(lr, rr, mopts)
    return disp, disparity_to_depth(disp, rect)


def _reconstruct_mode(cap, calib, rect, table_from_left, key, opts, lo, num, gt_ok):
    mopts = opts.match_options(lo, num)
    depths, cams, metrics, pts_all = [], [], [], []
    t_match = 0.0
    if gt_ok:
        true_cams = [Camera.from_dict(cap.ground_truth["cameras"][k]) for k in ("left", "right")]
    for i, fr in enumerate(track(cap.frames, f"stereo ({key})", total=len(cap.frames))):
        imgs = fr.get(key)
        if not isinstance(imgs, list) or len(imgs) != 2:
            raise InputError("expected [left, right] images", path=cap.root / "capture.json",
                             field=f"frames[{i}].{key}")
        L = _read(cap, imgs[0], f"frames[{i}].{key}[0]")
        R = _read(cap, imgs[1], f"frames[{i}].{key}[1]")
        if L.shape[:2] != R.shape[:2] or (L.shape[1], L.shape[0]) != calib.image_size:
            raise InputError(f"image size {R.shape[1]}x{R.shape[0]} / {L.shape[1]}x{L.shape[0]} "
                             f"differs from the calibration's {calib.image_size[0]}x"
                             f"{calib.image_size[1]}", path=cap.path(imgs[1]))
        t0 = time.perf_counter()
        disp, depth = _frame_depth(L, R, rect, mopts)
        t_match += time.perf_counter() - t0
        if not np.isfinite(disp).any():
            raise RuntimeError(f"frame {i} ({imgs[0]}): empty disparity (no match at all)")
        Wl = world_from_cam_at(table_from_left, fr.get("stage_angle_deg", 0.0))
        cam = rect.left_camera(Wl)
        depths.append(depth)
        cams.append(cam)
        pts_all.append(depth_to_points(depth, cam)[0])
        if gt_ok:
            g = cap.ground_truth["frames"][i]["depth"]
            gdl, mask, dy = gt_disparity(np.load(cap.path(g[0])), np.load(cap.path(g[1])), rect,
                                         *true_cams)
            try:
                m = disparity_metrics(disp, gdl, mask=mask)
                m["rectification_dy_px"] = float(np.nanmedian(np.abs(dy[mask])))
                m.update(depth_errors(disp, gdl, mask, rect))
            except ValueError as exc:
                m = {"error": str(exc)}
            metrics.append(m)
    return depths, cams, pts_all, metrics, t_match


def _mode_result(mesh, depths, pts, metrics, timings) -> dict:
    """One mode's entry of the report: counts, timings, disparity metrics and their means."""
    res = {"frames": len(depths), "timings_s": timings,
           "points": int(sum(len(p) for p in pts)), "mesh_vertices": len(mesh.vertices),
           "mesh_triangles": len(mesh.triangles)}
    if metrics:
        res["disparity_metrics"] = metrics
        ok = [m for m in metrics if "error" not in m]
        if ok:
            keys = ("bad1.0", "bad2.0", "avgerr", "invalid", "density", "bad2.0_sparse",
                    "rectification_dy_px", "depth_rms_m", "depth_median_abs_m")
            res["disparity_mean"] = {k: float(np.mean([m[k] for m in ok])) for k in keys}
    return res


def run_capture(capture_path, out_dir, options: StereoOptions | None = None
                ) -> ReconstructionResult:
    """Reconstruct a stereo capture folder into ``out_dir`` (points.ply, mesh.ply,
    report.json, disparity/ maps); the folder and its report."""
    opts = options or StereoOptions()
    check_choice(opts.mode, "mode", {"auto", "passive", "active"})
    cap = load_capture(capture_path)
    if cap.kind != "stereo":
        raise InputError(f"expected a stereo capture, got kind {cap.kind!r}",
                         path=cap.root / "capture.json", field="kind")
    if not cap.frames:
        raise InputError("no frames", path=cap.root / "capture.json", field="frames")
    t_start = time.perf_counter()
    calib, table_from_left, cal_report = calibrate_capture(cap)
    rect = rectify(calib)
    has_active = all("active_images" in f for f in cap.frames)
    mode = ("active" if has_active else "passive") if opts.mode == "auto" else opts.mode
    if mode == "active" and not has_active:
        raise InputError("mode 'active' needs frames[].active_images (a dot projector)",
                         path=cap.root / "capture.json", field="frames")
    near, far = cap.rig.get("working_range", [0.2, 2.0])
    lo, num = disparity_range(rect, near, far)
    lo = opts.min_disparity if opts.min_disparity is not None else lo
    num = opts.num_disparities if opts.num_disparities is not None else num
    voxel = opts.voxel_size or far / 500.0
    gt = cap.ground_truth
    gt_ok = bool(gt) and "frames" in gt
    ref = visible = size = None
    if gt_ok:
        ref, visible, size = reference_in_table(
            cap, table_from_left, mounted=cal_report["axis"].get("method") == "mount")
    modes = [mode] + ([m for m in ("passive", "active") if m != mode]
                      if opts.compare and has_active else [])
    results = {}
    mesh_main = pts_main = None
    for md in modes:
        key = "active_images" if md == "active" else "images"
        depths, cams, pts, metrics, t_match = _reconstruct_mode(cap, calib, rect, table_from_left,
                                                                key, opts, lo, num, gt_ok)
        t0 = time.perf_counter()
        mesh = fuse_depth_maps(depths, cams, voxel_size=voxel, sdf_trunc=4 * voxel,
                               depth_max=far)
        res = _mode_result(mesh, depths, pts, metrics,
                           {"match": t_match, "fuse": time.perf_counter() - t0})
        if ref is not None:
            res["evaluation"] = score_mesh(mesh, ref, visible, size)
        results[md] = res
        if md == mode:
            mesh_main, pts_main, depth_main = mesh, pts, depths
    out = Path(out_dir)
    with atomic_dir(out) as tmp:
        P = np.concatenate(pts_main) if pts_main else np.zeros((0, 3))
        if len(P):
            write_points(tmp / "points.ply", P)
        if len(mesh_main.vertices):
            write_mesh(tmp / "mesh.ply", sorted_mesh(mesh_main))  # canonical order
        (tmp / "depth").mkdir()
        for i, d in enumerate(depth_main):
            np.save(tmp / "depth" / f"{i:03d}.npy", d)
        report = {"kind": "stereo", "capture": str(cap.root), "mode": mode,
                  "options": asdict(opts), "calibration": {
                      **cal_report, "K1": calib.K1, "D1": calib.D1, "K2": calib.K2,
                      "D2": calib.D2, "R": calib.R, "T": calib.T,
                      "table_from_left": table_from_left},
                  "disparity_search": {"min": lo, "num": num}, "voxel_size": voxel,
                  "frame": _frame_name(cal_report["axis"]),
                  "results": results, "points": int(len(P)),
                  "mesh_vertices": len(mesh_main.vertices),
                  "timings_s": {"total": time.perf_counter() - t_start}}
        if mode in results and "evaluation" in results[mode]:
            report["evaluation"] = results[mode]["evaluation"]
        if gt_ok:
            report["calibration"]["truth_errors"] = calib_errors(calib, gt)
        write_json(tmp / "report.json", report)
    return ReconstructionResult(out, json_data(report))
