"""Scoring a stereo reconstruction against a capture's ground truth (for evaluation only:
the pipelines never read it to reconstruct): ground-truth disparity from rendered depth,
depth errors, calibration errors, and the mesh against the reference in the turntable
frame."""

from __future__ import annotations

import numpy as np

from acquire.camera import Camera
from acquire.capture_io import Capture
from core.frames import transform_points
from reconstruct.calibration.rectify import Rectification, StereoCalibration

__all__ = ["gt_disparity", "raw_depth_at", "reference_in_table", "depth_errors",
           "calib_errors", "coarse_align", "score_mesh"]


def raw_depth_at(depth: np.ndarray, mapx: np.ndarray, mapy: np.ndarray) -> np.ndarray:
    """Raw z-depth sampled at the raw pixels ``(mapx, mapy)`` (a rectification's remap
    table): inverse depth interpolated bilinearly (exact on planes); 0 where the four
    neighbours straddle a depth edge or the background."""
    import cv2

    inv = np.where(depth > 0, 1.0 / np.maximum(depth, 1e-9), 0).astype(np.float32)
    lin = cv2.remap(inv, mapx, mapy, cv2.INTER_LINEAR, borderValue=0)
    kmin = cv2.erode(inv, np.ones((3, 3), np.uint8))
    kmax = cv2.dilate(inv, np.ones((3, 3), np.uint8))
    mn = cv2.remap(kmin, mapx, mapy, cv2.INTER_NEAREST, borderValue=0)
    mx = cv2.remap(kmax, mapx, mapy, cv2.INTER_NEAREST, borderValue=0)
    ok = (mn > 0) & (mx - mn <= 0.02 * mx)
    return np.where(ok, 1.0 / np.maximum(lin, 1e-12), 0.0)


def gt_disparity(depth_left: np.ndarray, depth_right: np.ndarray, rect: Rectification,
                 left: Camera, right: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ground-truth disparity of the rectified left image, its non-occluded mask and the
    vertical residual, from the renderer's raw z-depth and the true cameras.

    Each rectified left pixel goes back to its raw pixel (the remap table), to the true
    surface point (true left camera and depth), forward into the true right camera, and
    into the *estimated* rectified right image (``rect``'s K2, D2, R2, P2). The disparity
    is the true correspondence in the images the matcher sees, whatever the calibration
    error; a calibration error shows as a vertical residual ``dy`` instead.

    Parameters
    ----------
    depth_left, depth_right : (H, W) float32
        True z-depth of each raw view (0 = background).
    rect : Rectification
        The rectification the matcher used (estimated calibration).
    left, right : Camera
        True cameras (only their relative pose matters).

    Returns
    -------
    disparity : (H, W) float64   ``x_left - x_right`` in rectified pixels, NaN where unknown
    nonoccluded : (H, W) bool    the point is visible in the right view too (its true depth
                                 there agrees) and inside its image
    dy : (H, W) float64          ``y_left - y_right``: rectification residual, pixels
    """
    import cv2

    m = rect.maps
    c = rect.calibration
    H, W = depth_left.shape
    z = raw_depth_at(depth_left, m[0], m[1])
    v, u = np.nonzero(z > 0)
    raw = np.stack([m[0][v, u], m[1][v, u]], 1).astype(np.float64)
    X = left.unproject(raw, z[v, u])
    q, zr = right.project(X)
    r = cv2.undistortPointsIter(q.reshape(-1, 1, 2), c.K2, c.D2, rect.R2, rect.P2,
                                (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 40, 1e-12)
                                ).reshape(-1, 2)
    disp = np.full((H, W), np.nan)
    dy = np.full((H, W), np.nan)
    disp[v, u] = u - r[:, 0]
    dy[v, u] = v - r[:, 1]
    iq = np.round(q).astype(np.int64)
    inside = (zr > 0) & (iq[:, 0] >= 0) & (iq[:, 0] < W) & (iq[:, 1] >= 0) & (iq[:, 1] < H)
    zd = np.zeros(len(q))
    zd[inside] = depth_right[iq[inside, 1], iq[inside, 0]]
    vis = inside & (np.abs(zd - zr) <= 0.002 + 0.005 * zr)
    mask = np.zeros((H, W), bool)
    mask[v, u] = vis
    return disp, mask, dy


def reference_in_table(cap: Capture, table_from_left: np.ndarray, *, mounted: bool = True):
    """GT mesh in the reconstruction's frame and a visibility mask function (scoring only).

    ``mounted``: the turntable frame was calibrated with the axis board's mount, so it
    *is* the world frame of the scene (the ground truth is used as is). Otherwise the
    calibrated frame's origin height and heading are tied to the world through the
    true left camera (an approximation: it inherits the calibration's camera datum).
    """
    from core.io.mesh import read_mesh
    from core.meshes import transform_mesh

    gt = cap.ground_truth
    mesh_rel = gt.get("mesh")
    if not mesh_rel:
        return None, None, None
    mesh = read_mesh(cap.path(mesh_rel))
    left = Camera.from_dict(gt["cameras"]["left"])
    right = Camera.from_dict(gt["cameras"]["right"])
    if mounted:
        world_from_table = np.eye(4)
        ref = mesh
    else:
        world_from_table = left.world_from_cam @ np.linalg.inv(table_from_left)
        ref = transform_mesh(mesh, np.linalg.inv(world_from_table))
    depths = [[np.load(cap.path(p)) for p in f["depth"]] for f in gt["frames"]]
    angles = [f["stage_angle_deg"] for f in cap.frames]

    def visible(points_table):
        pw = transform_points(world_from_table, points_table)
        vis = np.zeros(len(pw), bool)
        for a, (dl, dr) in zip(angles, depths, strict=True):
            c, s = np.cos(np.radians(a)), np.sin(np.radians(a))
            p = pw @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T
            both = np.ones(len(p), bool)
            for cam, d in ((left, dl), (right, dr)):
                px, z = cam.project(p)
                u, v = np.round(px[:, 0]).astype(int), np.round(px[:, 1]).astype(int)
                ok = (z > 0) & (u >= 0) & (u < cam.width) & (v >= 0) & (v < cam.height)
                zz = np.zeros(len(p))
                zz[ok] = d[v[ok], u[ok]]
                both &= ok & (np.abs(zz - z) < 0.003 + 0.01 * z)
            vis |= both
        return vis

    v = np.asarray(mesh.vertices)
    size = float(np.linalg.norm(v.max(0) - v.min(0)))
    obj_rel = gt.get("object_mesh")
    if obj_rel:
        vo = np.asarray(read_mesh(cap.path(obj_rel)).vertices)
        size = float(np.linalg.norm(vo.max(0) - vo.min(0)))
    return ref, visible, size


def depth_errors(disp: np.ndarray, gt: np.ndarray, mask: np.ndarray, rect) -> dict:
    """Per-pixel z error of the matching alone (the triangulation sigma_z = z^2/(f b) sigma_d):
    estimated and true disparity both turned into depth with the rig's own f*b, on
    non-occluded pixels; the RMS over the good matches (within 2 px, the bad-2.0 split) and
    the median absolute error over every estimate."""
    fb = rect.focal * rect.baseline
    v = mask & np.isfinite(disp) & (disp > 0) & np.isfinite(gt) & (gt > 0)
    if not v.any():
        return {"depth_rms_m": float("nan"), "depth_median_abs_m": float("nan")}
    dz = fb / disp[v] - fb / gt[v]
    good = np.abs(disp[v] - gt[v]) <= 2.0
    rms = float(np.sqrt(np.mean(dz[good] ** 2))) if good.any() else float("nan")
    return {"depth_rms_m": rms, "depth_median_abs_m": float(np.median(np.abs(dz)))}


def calib_errors(calib: StereoCalibration, gt: dict) -> dict:
    left = Camera.from_dict(gt["cameras"]["left"])
    right = Camera.from_dict(gt["cameras"]["right"])
    true = StereoCalibration.from_cameras(left, right)
    return {"baseline_rel_err": float(abs(calib.baseline - true.baseline) / true.baseline),
            "fx1_rel_err": float(abs(calib.K1[0, 0] - true.K1[0, 0]) / true.K1[0, 0]),
            "fx2_rel_err": float(abs(calib.K2[0, 0] - true.K2[0, 0]) / true.K2[0, 0])}


def coarse_align(mesh, ref, size):
    """Coarse-to-fine point-to-plane ICP (10 %, 3 %, 1 % of the object size) of the
    reconstruction onto the reference, so the final fine ICP starts in its basin."""
    import copy

    import open3d as o3d
    from scipy.spatial import cKDTree

    from core.sampling import sample_surface
    from reconstruct.registration.icp import icp

    rng = np.random.default_rng(0)
    pts = [sample_surface(np.asarray(m.vertices), np.asarray(m.triangles), 30000, rng=rng)
           for m in (mesh, ref)]
    src, dst = (o3d.geometry.PointCloud(o3d.utility.Vector3dVector(
        np.asarray(p[0] if isinstance(p, tuple) else p, np.float64))) for p in pts)
    dst.estimate_normals()
    # our point-to-plane ICP, not Open3D's: its multithreaded sums vary in the last bits
    # from run to run, and the same seed must give the same report
    p_dst = np.asarray(dst.points)
    tree = cKDTree(p_dst)
    T = np.eye(4)
    for frac in (0.1, 0.03, 0.01):
        T = icp(np.asarray(src.points), p_dst, T, frac * size,
                target_normals=np.asarray(dst.normals), tree=tree, iterations=50).transform
    out = copy.deepcopy(mesh)
    out.transform(T)
    return out, np.asarray(T)


def score_mesh(mesh, ref, visible, size, *, taus=(0.01,)):
    """F-score of ``mesh`` against ``ref`` as it lies (no alignment) at each fraction of
    the object size in ``taus`` (the first is the headline); a rigid ICP is run as a
    diagnostic only: the residual rigid offset it finds and the F-score it would give."""
    from reconstruct.evaluation.evaluate import evaluate

    if len(mesh.vertices) == 0:
        return {"fscore": 0.0, "note": "empty mesh"}
    res = [evaluate(mesh, ref, tau=t * size, reference_mask=visible) for t in taus]
    d = res[0].to_dict()
    d["tau_fraction_of_object_size"] = taus[0]
    d["object_size"] = size
    for t, r in zip(taus[1:], res[1:], strict=True):
        d[f"fscore_at_{100 * t:g}pct"] = r.fscore
        d[f"precision_at_{100 * t:g}pct"] = r.precision
        d[f"recall_at_{100 * t:g}pct"] = r.recall
    aligned, T = coarse_align(mesh, ref, size)
    fine = evaluate(aligned, ref, tau=taus[0] * size, reference_mask=visible, icp=True)
    T = np.asarray(fine.icp_reference_from_recon) @ T
    d["diagnostic_icp"] = {
        "note": "not part of the score: a rigid ICP onto the ground truth measures the "
                "residual offset of the calibrated frame chain",
        "fscore": fine.fscore, "translation_mm": float(1e3 * np.linalg.norm(T[:3, 3])),
        "rotation_deg": float(np.degrees(np.arccos(np.clip((np.trace(T[:3, :3]) - 1) / 2,
                                                            -1, 1)))),
        "reference_from_recon": T}
    return d
