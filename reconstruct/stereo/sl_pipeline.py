"""Structured-light reconstruction of a turntable capture.

1. Camera intrinsics from the board under white light; projector coordinates at the
   board corners from the decoded patterns (local homographies, Moreno and Taubin
   2012); the projector calibrated as a camera; ``cv2.stereoCalibrate`` of the pair.
2. Turntable axis from the board on the turntable (as for stereo).
3. Per pose: Gray code + phase shift -> sub-pixel projector column (and row), camera
   ray / projector column-plane triangulation -> z-depth map; TSDF fusion; mesh.
"""

from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from acquire.capture_io import Capture, load_capture
from acquire.targets import target_from_dict
from core.config import Config, option
from core.files import atomic_dir, json_data, write_json
from core.frames import transform_points
from core.io.mesh import write_mesh, write_points
from core.meshes import sorted_mesh
from core.progress import track
from core.validate import InputError
from reconstruct.calibration.camera import detect_board
from reconstruct.calibration.stereo import calibrate_pair, world_from_cam_at
from reconstruct.result import ReconstructionResult
from reconstruct.stereo.pipeline import _frame_name, _read, calibrate_axis_entry
from reconstruct.stereo.scoring import reference_in_table, score_mesh
from reconstruct.stereo.structured_light import (
    decode_gray_code,
    decode_phase,
    projector_coords_at,
    triangulate_columns,
    unwrap_with_gray,
)
from reconstruct.surface.tsdf import fuse_depth_maps

__all__ = ["SLOptions", "decode_stack", "run_capture"]

_log = logging.getLogger(__name__)


@dataclass
class SLOptions(Config):
    """Options of the structured-light reconstruction (``scanamp reconstruct
    structured-light``)."""

    min_contrast: float = option(12.0, unit="DN", range="[0, inf)",
                                 help="white - black below which a pixel is in shadow")
    min_modulation: float = option(4.0, unit="DN", range="[0, inf)",
                                   help="amplitude of the phase sinusoid below which a pixel "
                                        "is rejected")
    voxel_size: float | None = option(None, unit="m", range="(0, inf)",
                                      help="TSDF voxel (default: far working distance / 1000)")


def decode_stack(images: list, info: dict, opts: SLOptions):
    """Sub-pixel projector column and row per camera pixel from one view's sequence.

    Returns ``col (H, W)``, ``row (H, W)`` float64 (NaN where invalid) and ``valid``.
    """
    nc, nr, n = int(info["n_col_bits"]), int(info["n_row_bits"]), int(info["n_steps"])
    expected = 2 + 2 * (nc + nr) + 2 * n
    if len(images) != expected:
        raise ValueError(f"images: expected {expected} pattern images, got {len(images)}")
    imgs = [np.asarray(i, np.float64) for i in images]
    white, black = imgs[0], imgs[1]
    g = imgs[2:2 + 2 * (nc + nr)]
    px_imgs = imgs[2 + 2 * (nc + nr):2 + 2 * (nc + nr) + n]
    py_imgs = imgs[2 + 2 * (nc + nr) + n:]
    col_i, row_i, valid = decode_gray_code(g, n_col_bits=nc, n_row_bits=nr, white=white,
                                           black=black, min_contrast=opts.min_contrast,
                                           min_bit_contrast=1.0)
    P = float(info["period_px"])
    phx, mx = decode_phase(px_imgs)
    phy, my = decode_phase(py_imgs)
    valid &= (mx > opts.min_modulation) & (my > opts.min_modulation)
    col = unwrap_with_gray(phx, np.where(valid, col_i, -1), period_px=P)
    row = unwrap_with_gray(phy, np.where(valid, row_i, -1), period_px=P)
    valid &= np.isfinite(col) & np.isfinite(row) & (np.abs(col - col_i) <= 1.5) & \
        (np.abs(row - row_i) <= 1.5)
    return np.where(valid, col, np.nan), np.where(valid, row, np.nan), valid


def _calibrate(cap: Capture, opts: SLOptions):
    jpath = cap.root / "capture.json"
    entries = {c["kind"]: (i, c) for i, c in enumerate(cap.calibration)}
    if "projector" not in entries or "axis" not in entries:
        raise InputError("expected calibration entries of kind 'projector' and 'axis'",
                         path=jpath, field="calibration")
    ci, pc = entries["projector"]
    info = cap.data["projectors"][pc.get("projector", "proj")]
    target = target_from_dict(pc["target"])
    oc, ic, op, ip, common, missed = [], [], [], [], [], []
    size = None
    for j, stack in enumerate(track(pc["images"], "projector calibration")):
        imgs = [_read(cap, rel, f"calibration[{ci}].images[{j}][{k}]")
                for k, rel in enumerate(stack)]
        size = (imgs[0].shape[1], imgs[0].shape[0])
        det = detect_board(target, imgs[0])
        if det is None:
            missed.append(stack[0])
            continue
        obj, px, _ = det
        oc.append(obj)
        ic.append(px)
        col, row, valid = decode_stack(imgs, info, opts)
        pp, ok = projector_coords_at(px, col, row, valid)
        if ok.sum() >= 6:
            op.append(obj[ok])
            ip.append(pp[ok])
            common.append((obj[ok], px[ok], pp[ok]))
    if len(common) < 3:
        raise InputError(f"board found with decoded projector coordinates in only "
                         f"{len(common)} views (need 3); board not detected in: "
                         f"{', '.join(missed) or 'none'}", path=jpath,
                         field=f"calibration[{ci}].images")
    calib, rep = calibrate_pair(oc, ic, op, ip, common, size,
                                image_size2=(int(info["width"]), int(info["height"])))
    table_from_cam, arep = calibrate_axis_entry(cap, *entries["axis"], calib.K1, calib.D1)
    rep = {"pair": rep, "axis": arep, "undetected": missed}
    w, h = size
    cam = Camera(w, h, calib.K1[0, 0], calib.K1[1, 1], calib.K1[0, 2], calib.K1[1, 2], calib.D1)
    proj_from_cam = np.eye(4)
    proj_from_cam[:3, :3], proj_from_cam[:3, 3] = calib.R, calib.T
    proj = Camera(int(info["width"]), int(info["height"]), calib.K2[0, 0], calib.K2[1, 1],
                  calib.K2[0, 2], calib.K2[1, 2], calib.D2, proj_from_cam)
    return cam, proj, table_from_cam, rep, info


def run_capture(capture_path, out_dir, options: SLOptions | None = None
                ) -> ReconstructionResult:
    """Reconstruct a structured-light capture into ``out_dir`` (mesh.ply, points.ply,
    report.json); the folder and its report."""
    opts = options or SLOptions()
    cap = load_capture(capture_path)
    if cap.kind != "structured-light":
        raise InputError(f"expected a structured-light capture, got kind {cap.kind!r}",
                         path=cap.root / "capture.json", field="kind")
    t0 = time.perf_counter()
    cam, proj, table_from_cam, cal_rep, info = _calibrate(cap, opts)
    near, far = cap.rig.get("working_range", [0.2, 2.0])
    depths, cams, pts_all = [], [], []
    H, W = cam.height, cam.width
    v, u = np.mgrid[0:H, 0:W]
    for i, fr in enumerate(track(cap.frames, "structured light")):
        imgs = [_read(cap, rel, f"frames[{i}].images[{k}]") for k, rel in enumerate(fr["images"])]
        if imgs[0].shape[:2] != (H, W):
            raise InputError(f"expected {W}x{H} images, got {imgs[0].shape[1]}x"
                             f"{imgs[0].shape[0]}", path=cap.path(fr["images"][0]))
        col, row, valid = decode_stack(imgs, info, opts)
        if not valid.any():
            raise RuntimeError(f"frames[{i}] ({fr['images'][0]}): no pixel decoded")
        px = np.stack([u[valid], v[valid]], 1).astype(np.float64)
        P = triangulate_columns(cam, px, np.stack([col[valid], row[valid]], 1), proj)
        z = P[:, 2]
        ok = np.isfinite(z) & (z > near) & (z < far)
        depth = np.zeros((H, W), np.float32)
        depth[v[valid][ok], u[valid][ok]] = z[ok]
        Wc = world_from_cam_at(table_from_cam, fr.get("stage_angle_deg", 0.0))
        depths.append(depth)
        cams.append(cam.with_pose(np.linalg.inv(Wc)))
        pts_all.append(transform_points(Wc, P[ok]))
    voxel = opts.voxel_size or far / 1000.0
    mesh = fuse_depth_maps(depths, cams, voxel_size=voxel, sdf_trunc=4 * voxel, depth_max=far)
    report = {"kind": "structured-light", "capture": str(cap.root), "options": asdict(opts),
              "calibration": {**cal_rep, "K_cam": cam.K, "D_cam": cam.dist, "K_proj": proj.K,
                              "D_proj": proj.dist, "proj_from_cam": proj.cam_from_world,
                              "table_from_cam": table_from_cam},
              "frames": len(depths), "voxel_size": voxel,
              "points": int(sum(len(p) for p in pts_all)), "mesh_vertices": len(mesh.vertices),
              "frame": _frame_name(cal_rep["axis"])}
    gt = cap.ground_truth
    if gt and gt.get("mesh"):
        ref, visible, size = reference_in_table(
            cap, table_from_cam, mounted=cal_rep["axis"].get("method") == "mount")
        ev = score_mesh(mesh, ref, visible, size, taus=(0.01, 0.005))
        report["evaluation"] = ev
        true_p = Camera.from_dict(gt["cameras"]["right"])
        true_c = Camera.from_dict(gt["cameras"]["left"])
        rfl = true_p.cam_from_world @ true_c.world_from_cam
        report["calibration"]["truth_errors"] = {
            "baseline_rel_err": float(abs(np.linalg.norm(proj.cam_from_world[:3, 3])
                                          - np.linalg.norm(rfl[:3, 3]))
                                      / np.linalg.norm(rfl[:3, 3])),
            "fx_cam_rel_err": float(abs(cam.fx - true_c.fx) / true_c.fx),
            "fx_proj_rel_err": float(abs(proj.fx - true_p.fx) / true_p.fx)}
    report["timings_s"] = {"total": time.perf_counter() - t0}
    out = Path(out_dir)
    with atomic_dir(out) as tmp:
        P = np.concatenate(pts_all)
        write_points(tmp / "points.ply", P)
        if len(mesh.vertices):
            write_mesh(tmp / "mesh.ply", sorted_mesh(mesh))  # canonical order
        write_json(tmp / "report.json", report)
    return ReconstructionResult(out, json_data(report))
