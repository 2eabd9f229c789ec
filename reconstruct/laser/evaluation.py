"""Scoring a laser reconstruction against the capture's ground truth (evaluation only).

Reads ``capture.json``'s ``ground_truth`` (true camera, laser, axis) and ``gt/``
files. Nothing here feeds back into the reconstruction.

* calibration errors: intrinsics, laser-plane normal angle and offset, axis angle and
  offset;
* peak errors: each detected sub-pixel column against the true crossing of the sheet's
  central plane on that row (``gt/stripe.npy``);
* depth errors: each triangulated point (estimated calibration) against the true point
  (true camera ray through the true crossing, met with the true plane), in the camera
  frame, beside the error-propagation prediction for the same points: the peak-only part
  (detected columns through the true calibration) against the peak-localisation
  prediction, the total against the total prediction (peak localisation, laser plane by
  jackknife, camera intrinsics by Monte Carlo recalibration);
* F-score of the mesh against the ground-truth surface that the camera sees lit by the
  laser in at least one frame (ray casts per frame near the sheet).
"""

from __future__ import annotations

import numpy as np

from acquire.camera import Camera
from acquire.render.laser_sheet import LaserSheet
from core.frames import rotation_about
from reconstruct.laser.calibration import intersect_rays_plane, pixel_rays

__all__ = ["evaluate_laser", "visible_lit_mask"]


def _angle_deg(a, b) -> float:
    c = abs(float(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b)))
    return float(np.degrees(np.arccos(min(c, 1.0))))


def _world_from_object(gt: dict, motion: str, reading: float) -> np.ndarray:
    if motion == "turntable":
        return rotation_about(np.asarray(gt["axis_direction_world"]), np.radians(reading),
                              np.asarray(gt["axis_point_world"]))
    T = np.eye(4)
    T[:3, 3] = reading * np.asarray(gt["axis_direction_world"])
    return T


def visible_lit_mask(points: np.ndarray, mesh, cam0: Camera, laser0: LaserSheet,
                     readings: np.ndarray, gt: dict, motion: str, step: float) -> np.ndarray:
    """``(n,) bool``: surface points seen by the camera while lit by the laser in at least
    one frame. ``step`` is the reading step (degrees or metres) setting the sheet's band."""
    import open3d as o3d

    rs = o3d.t.geometry.RaycastingScene()
    tm = o3d.t.geometry.TriangleMesh.from_legacy(mesh)
    tm.vertex.positions = tm.vertex.positions.to(o3d.core.float32)
    tm.triangle.indices = tm.triangle.indices.to(o3d.core.int32)
    rs.add_triangles(tm)
    cp = rs.compute_closest_points(o3d.core.Tensor(points.astype(np.float32)))
    nrm = cp["primitive_normals"].numpy().astype(np.float64)
    seen = np.zeros(len(points), bool)
    if motion == "turntable":
        a = np.asarray(gt["axis_direction_world"], float)
        c = np.asarray(gt["axis_point_world"], float)
        v = points - c
        r = np.linalg.norm(v - (v @ a)[:, None] * a, axis=1)
        band = 0.5 * r * np.radians(step) * 1.05 + 2 * laser0.thickness
    else:
        band = np.full(len(points), 0.5 * step * 1.05 + 2 * laser0.thickness)
    eps = 2e-5
    for reading in readings:
        W = _world_from_object(gt, motion, reading)
        Winv = np.linalg.inv(W)
        las = laser0.transformed(Winv)
        n_pl, d_pl = las.plane
        sel = np.flatnonzero(~seen & (np.abs(points @ n_pl - d_pl) < band))
        if sel.size == 0:
            continue
        p, n = points[sel], nrm[sel]
        cam = cam0.with_pose(cam0.cam_from_world @ W)
        C = cam.center
        to_c = C - p
        to_l = las.origin - p
        px, z = cam.project(p)
        ok = ((np.einsum("ij,ij->i", n, to_c) > 0) & (z > 0) & (px[:, 0] > -0.5)
              & (px[:, 0] < cam.width - 0.5) & (px[:, 1] > -0.5) & (px[:, 1] < cam.height - 0.5)
              & (np.einsum("ij,ij->i", n, to_l) > 0))
        # in the fan: the profile without the Gaussian factor
        d = p - las.origin
        along = d @ las.direction
        lat = d @ np.cross(las.normal, las.direction)
        ok &= (along > 0) & (np.abs(np.arctan2(lat, along)) <= 0.5 * las.fan_angle)
        idx = np.flatnonzero(ok)
        if idx.size == 0:
            continue
        o = p[idx] + eps * n[idx]
        rays = np.concatenate([np.concatenate([o, to_c[idx]], 1),
                               np.concatenate([o, to_l[idx]], 1)]).astype(np.float32)
        occ = rs.test_occlusions(o3d.core.Tensor(rays), tnear=0.0, tfar=1.0 - 1e-6).numpy()
        occ = occ.astype(bool)
        vis = ~occ[:idx.size] & ~occ[idx.size:]
        seen[sel[idx[vis]]] = True
    return seen


def evaluate_laser(cap, cam_cal, plane, axis_cal, obj_from_cam, mesh, meas: dict, *,
                   tau: float) -> dict:
    """Evaluation figures of one reconstruction (see the module docstring)."""
    gt = cap.ground_truth
    motion = cap.rig["motion"]
    cam_gt = Camera.from_dict(gt["camera"])
    out, plane_gt = _calibration_errors(gt, motion, cam_gt, cam_cal.camera, plane, axis_cal)
    out.update(_stripe_errors(cap, gt, cam_cal.camera, cam_gt, plane_gt, meas))
    out["surface"] = _surface_score(cap, gt, motion, cam_gt, obj_from_cam, mesh, tau)
    return out


def _calibration_errors(gt, motion, cam_gt, cam, plane, axis_cal) -> tuple[dict, np.ndarray]:
    """Intrinsics, laser-plane and axis (or stage) errors; and the true plane (camera frame)."""
    R, t = cam_gt.cam_from_world[:3, :3], cam_gt.cam_from_world[:3, 3]
    out: dict = {}
    out["intrinsics_error"] = {
        "fx_px": cam.fx - cam_gt.fx, "fy_px": cam.fy - cam_gt.fy,
        "cx_px": cam.cx - cam_gt.cx, "cy_px": cam.cy - cam_gt.cy,
        "dist": (cam.dist - cam_gt.dist).tolist(),
    }
    pw = np.asarray(gt["laser_plane_world"], float)
    n_c = R @ pw[:3]
    plane_gt = np.append(n_c, pw[3] + n_c @ t)
    if plane_gt[3] < 0:
        plane_gt = -plane_gt
    out["laser_plane_error"] = {"normal_deg": _angle_deg(plane[:3], plane_gt[:3]),
                                "offset_m": float(plane[3] - plane_gt[3])}
    a_gt = R @ np.asarray(gt["axis_direction_world"], float)
    if motion == "turntable":
        p_gt = R @ np.asarray(gt["axis_point_world"], float) + t
        v = axis_cal.point - p_gt
        out["axis_error"] = {"direction_deg": _angle_deg(axis_cal.direction, a_gt),
                             "offset_m": float(np.linalg.norm(v - (v @ a_gt) * a_gt))}
    else:
        out["stage_error"] = {"direction_deg": _angle_deg(axis_cal.direction, a_gt),
                              "scale": axis_cal.scale - 1.0}
    return out, plane_gt


def _stripe_errors(cap, gt, cam, cam_gt, plane_gt, meas) -> dict:
    """Peak errors against the true stripe, and the depth errors they and the calibration
    make (with the error model's predictions beside them)."""
    out: dict = {}
    st = np.load(cap.path(gt["stripe"]))
    H = cam.height
    kk, rr, uu = meas["frame"], meas["row"], meas["col"]
    if len(st) and len(kk):
        keys = st[:, 0].astype(np.int64) * H + st[:, 1].astype(np.int64)
        order = np.argsort(keys, kind="stable")
        ks, us = keys[order], st[order, 2]
        q = kk.astype(np.int64) * H + rr
        lo = np.searchsorted(ks, q, "left")
        hi = np.searchsorted(ks, q, "right")
        du = np.full(len(q), np.nan)
        for off in range(0, 4):  # up to 4 crossings per row: take the nearest
            j = lo + off
            okj = j < hi
            cand = np.where(okj, us[np.minimum(j, len(us) - 1)] - uu, np.nan)
            better = okj & (~np.isfinite(du) | (np.abs(cand) < np.abs(du)))
            du = np.where(better, cand, du)
        m = np.isfinite(du) & (np.abs(du) < 2.0)
        u_true = uu[m] + du[m]
        e = -du[m]  # detected minus true
        out["peak_error"] = {"matched": int(m.sum()), "of": int(len(q)),
                             "rms_px": float(np.sqrt(np.mean(e ** 2))) if m.any() else None,
                             "bias_px": float(np.mean(e)) if m.any() else None,
                             "std_px": float(np.std(e)) if m.any() else None}
        true_pts = intersect_rays_plane(
            pixel_rays(cam_gt.with_pose(np.eye(4)), np.stack([u_true, rr[m].astype(float)], 1)),
            plane_gt)
        dz = meas["points_cam"][m, 2] - true_pts[:, 2]
        dz = dz[np.isfinite(dz)]
        # the peak-localization part alone: detected columns through the TRUE calibration
        det_true = intersect_rays_plane(
            pixel_rays(cam_gt.with_pose(np.eye(4)), np.stack([uu[m], rr[m].astype(float)], 1)),
            plane_gt)
        dzn = det_true[:, 2] - true_pts[:, 2]
        dzn = dzn[np.isfinite(dzn)]
        noise = float(np.sqrt(np.mean(dzn ** 2))) if dzn.size else None
        pred_peak = float(np.sqrt(np.mean(meas.get("sigma_z_peak", meas["sigma_z"])[m] ** 2)))
        pred = float(np.sqrt(np.mean(meas["sigma_z"][m] ** 2)))
        rms = float(np.sqrt(np.mean(dz ** 2))) if dz.size else None
        out["depth_error"] = {"rms_m": rms, "bias_m": float(np.mean(dz)) if dz.size else None,
                              "std_m": float(np.std(dz)) if dz.size else None,
                              "peak_only_rms_m": noise,
                              "predicted_rms_m": pred_peak,
                              "predicted_total_rms_m": pred,
                              "predicted_parts_rms_m": {
                                  k: float(np.sqrt(np.mean(meas[f"sigma_z_{k}"][m] ** 2)))
                                  for k in ("peak", "plane", "intrinsics")
                                  if f"sigma_z_{k}" in meas},
                              "ratio_to_prediction": noise / pred_peak
                              if noise and pred_peak else None,
                              "total_ratio_to_prediction": rms / pred if rms and pred else None}
    return out


def _surface_score(cap, gt, motion, cam_gt, obj_from_cam, mesh, tau) -> dict:
    """The mesh against the scene's, in the world frame, over the surface the rig lit."""
    from core.io.mesh import read_mesh
    from core.meshes import transform_mesh
    from reconstruct.evaluation.evaluate import evaluate

    ref = read_mesh(cap.path(gt["mesh"]))
    world_from_obj = cam_gt.world_from_cam @ np.linalg.inv(obj_from_cam)
    recon_w = transform_mesh(mesh, world_from_obj)
    readings = np.asarray([f["angle_deg" if motion == "turntable" else "position_m"]
                           for f in cap.frames], float)
    step = float(np.median(np.abs(np.diff(readings)))) if len(readings) > 1 else 1.0
    laser0 = LaserSheet.from_dict(gt["laser"])
    res = evaluate(recon_w, ref, tau=tau, reference_mask=lambda p: visible_lit_mask(
        p, ref, cam_gt, laser0, readings, gt, motion, step))
    return res.to_dict() if hasattr(res, "to_dict") else dict(vars(res))
