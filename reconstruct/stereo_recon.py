"""Stereo reconstruction pipelines: a turntable capture, or a user's own pair.

Capture pipeline (:func:`run_capture`): stereo calibration from the board views
(``cv2.stereoCalibrate``), the turntable frame from the board mounted on the turntable,
then per stage angle: rectify, SGBM (+ LR check, + WLS), disparity to depth, and TSDF
fusion of all depth maps into one mesh in the turntable (= world) frame, object at stage
angle 0. Rig poses come from that calibration and the reported stage angles; ground
truth is read only to score (disparity metrics, mesh F-score as the mesh lies).

Pair pipeline (:func:`run_pair`): a rectified disparity, depth and points from two
images and a ``stereo.yaml`` (see :mod:`reconstruct.calib_io`).
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from acquire.camera import Camera
from acquire.capture_io import Capture, load_capture
from acquire.targets import target_from_dict
from core.config import Config, option
from core.files import atomic_dir, write_json
from core.image_io import read_image
from core.mesh_io import write_mesh, write_points
from core.progress import track
from core.validate import InputError, check_choice
from reconstruct.calibrate_camera import detect_board, to_gray
from reconstruct.disparity_metrics import disparity_metrics
from reconstruct.stereo import (
    MatchOptions,
    Rectification,
    StereoCalibration,
    depth_to_points,
    disparity_range,
    disparity_to_depth,
    match,
    rectify,
    rectify_pair,
)
from reconstruct.stereo_calib import (
    calibrate_pair,
    calibrate_turntable_axis,
    calibrate_turntable_mount,
    detect_pair_views,
    world_from_cam_at,
)
from reconstruct.tsdf import fuse_depth_maps


def _frame_name(axis_report: dict) -> str:
    if axis_report.get("method") == "mount":
        return "world (the turntable frame fixed by the axis board's mount; object at stage 0)"
    return "turntable axis frame (origin height and heading from the axis board)"


__all__ = ["StereoOptions", "run_capture", "run_pair", "read_disparity", "calibrate_capture",
           "gt_disparity", "detect_board", "to_gray"]  # the last two from calibrate_camera

_log = logging.getLogger(__name__)


@dataclass
class StereoOptions(Config):
    """Options of the stereo pipelines (``scanamp reconstruct stereo``); the matcher's are
    :class:`reconstruct.stereo.MatchOptions`'s."""

    mode: str = option("auto", choices=("auto", "passive", "active"),
                       help="which images to match ('auto': the dot-pattern images when "
                            "present)")
    compare: bool = option(True, help="with a capture holding both, also reconstruct and "
                                      "score the other mode")
    block_size: int = option(5, unit="px", range="[1, 31]", help="SGBM window (odd)")
    wls: bool = option(False, help="WLS disparity filter (ximgproc)")
    lr_check: bool = option(False, help="left-right consistency check")
    lr_tol: float = option(1.0, unit="px", range="(0, inf)",
                           help="left-right disagreement tolerated by the check")
    uniqueness: int = option(5, unit="%", range="[0, 100]", help="SGBM uniqueness ratio")
    sgbm_mode: str = option("sgbm", choices=("sgbm", "hh", "3way"), help="OpenCV SGBM mode")
    voxel_size: float | None = option(None, unit="m", range="(0, inf)",
                                      help="TSDF voxel (default: far working distance / 500)")
    min_disparity: int | None = option(None, unit="px",
                                       help="search range start (default from the rig's "
                                            "working range)")
    num_disparities: int | None = option(None, unit="px", range="[16, 4096]",
                                         help="search range, a multiple of 16 (default from "
                                              "the rig's working range)")

    def match_options(self, lo: int, num: int) -> MatchOptions:
        return MatchOptions(min_disparity=lo, num_disparities=num, block_size=self.block_size,
                            wls=self.wls, lr_check=self.lr_check, lr_tol=self.lr_tol,
                            uniqueness=self.uniqueness, mode=self.sgbm_mode)


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
    is fixed completely (:func:`reconstruct.stereo_calib.calibrate_turntable_mount`):
    the reconstruction lands in the world frame. Without it only the axis is known
    (:func:`reconstruct.stereo_calib.calibrate_turntable_axis`): origin height and
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


def _raw_depth_at(depth: np.ndarray, mapx: np.ndarray, mapy: np.ndarray) -> np.ndarray:
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
    z = _raw_depth_at(depth_left, m[0], m[1])
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


def _frame_depth(L, R, rect, mopts):
    lr, rr = rectify_pair(to_gray(L), to_gray(R), rect)
    disp = match(lr, rr, mopts)
    return disp, disparity_to_depth(disp, rect)


def _reference_in_table(cap: Capture, table_from_left: np.ndarray, *, mounted: bool = True):
    """GT mesh in the reconstruction's frame and a visibility mask function (scoring only).

    ``mounted``: the turntable frame was calibrated with the axis board's mount, so it
    *is* the world frame of the scene (the ground truth is used as is). Otherwise the
    calibrated frame's origin height and heading are tied to the world through the
    true left camera (an approximation: it inherits the calibration's camera datum).
    """
    from core.mesh_io import read_mesh
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
        pw = points_table @ world_from_table[:3, :3].T + world_from_table[:3, 3]
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


def _depth_errors(disp: np.ndarray, gt: np.ndarray, mask: np.ndarray, rect) -> dict:
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
                m.update(_depth_errors(disp, gdl, mask, rect))
            except ValueError as exc:
                m = {"error": str(exc)}
            metrics.append(m)
    return depths, cams, pts_all, metrics, t_match


def run_capture(capture_path, out_dir, options: StereoOptions | None = None) -> Path:
    """Reconstruct a stereo capture folder into ``out_dir`` (points.ply, mesh.ply,
    report.json, disparity/ maps)."""
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
        ref, visible, size = _reference_in_table(
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
        t_fuse = time.perf_counter() - t0
        res = {"frames": len(depths), "timings_s": {"match": t_match, "fuse": t_fuse},
               "points": int(sum(len(p) for p in pts)), "mesh_vertices": len(mesh.vertices),
               "mesh_triangles": len(mesh.triangles)}
        if metrics:
            res["disparity_metrics"] = metrics
            ok = [m for m in metrics if "error" not in m]
            if ok:
                keys = ("bad1.0", "bad2.0", "avgerr", "invalid", "density", "bad2.0_sparse",
                        "rectification_dy_px", "depth_rms_m", "depth_median_abs_m")
                res["disparity_mean"] = {k: float(np.mean([m[k] for m in ok])) for k in keys}
        if ref is not None:
            res["evaluation"] = _score(mesh, ref, visible, size)
        results[md] = res
        if md == mode:
            mesh_main, pts_main, depth_main = mesh, pts, depths
    out = Path(out_dir)
    with atomic_dir(out) as tmp:
        P = np.concatenate(pts_main) if pts_main else np.zeros((0, 3))
        if len(P):
            write_points(tmp / "points.ply", P)
        if len(mesh_main.vertices):
            write_mesh(tmp / "mesh.ply", mesh_main)
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
            report["calibration"]["truth_errors"] = _calib_errors(calib, gt)
        write_json(tmp / "report.json", report)
    return out


def _calib_errors(calib: StereoCalibration, gt: dict) -> dict:
    left = Camera.from_dict(gt["cameras"]["left"])
    right = Camera.from_dict(gt["cameras"]["right"])
    true = StereoCalibration.from_cameras(left, right)
    return {"baseline_rel_err": float(abs(calib.baseline - true.baseline) / true.baseline),
            "fx1_rel_err": float(abs(calib.K1[0, 0] - true.K1[0, 0]) / true.K1[0, 0]),
            "fx2_rel_err": float(abs(calib.K2[0, 0] - true.K2[0, 0]) / true.K2[0, 0])}


def _coarse_align(mesh, ref, size):
    """Coarse-to-fine point-to-plane ICP (10 %, 3 %, 1 % of the object size) of the
    reconstruction onto the reference, so the final fine ICP starts in its basin."""
    import copy

    import open3d as o3d

    from core.sampling import sample_surface

    rng = np.random.default_rng(0)
    pts = [sample_surface(np.asarray(m.vertices), np.asarray(m.triangles), 30000, rng=rng)
           for m in (mesh, ref)]
    src, dst = (o3d.geometry.PointCloud(o3d.utility.Vector3dVector(
        np.asarray(p[0] if isinstance(p, tuple) else p, np.float64))) for p in pts)
    dst.estimate_normals()
    T = np.eye(4)
    reg = o3d.pipelines.registration
    for frac in (0.1, 0.03, 0.01):
        r = reg.registration_icp(src, dst, frac * size, T,
                                 reg.TransformationEstimationPointToPlane(),
                                 reg.ICPConvergenceCriteria(max_iteration=50))
        T = r.transformation
    out = copy.deepcopy(mesh)
    out.transform(T)
    return out, np.asarray(T)


def _score(mesh, ref, visible, size, *, taus=(0.01,)):
    """F-score of ``mesh`` against ``ref`` as it lies (no alignment) at each fraction of
    the object size in ``taus`` (the first is the headline); a rigid ICP is run as a
    diagnostic only: the residual rigid offset it finds and the F-score it would give."""
    from reconstruct.evaluate import evaluate

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
    aligned, T = _coarse_align(mesh, ref, size)
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


def read_disparity(path: Path, *, scale: float | None = None) -> np.ndarray:
    """A ground-truth disparity map as float64, NaN where unknown (0, inf or NaN).

    ``.npy``/``.pfm``: disparities as stored (Middlebury 2014 is PFM). ``.png``: the stored
    value divided by ``scale``, by default 256 for a 16-bit PNG (KITTI) and 1 for an 8-bit
    one (Middlebury 2001-2006 at full size; a reduced size may scale, see its readme).
    """
    import cv2

    if not path.is_file():
        raise InputError("file not found", path=path)
    if path.suffix.lower() == ".npy":
        g = np.load(path, allow_pickle=False)
    else:
        g = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if g is None:
            raise InputError("unreadable disparity (expected .npy, .pfm or .png)", path=path)
    if g.ndim != 2:
        raise InputError(f"expected a single-channel disparity map, got shape {g.shape}",
                         path=path)
    if scale is None:
        scale = 256.0 if g.dtype == np.uint16 else 1.0
    if not scale > 0:
        raise InputError(f"disparity scale: expected a positive number, got {scale}", path=path)
    g = g.astype(np.float64) / (scale if g.dtype in (np.uint8, np.uint16) else 1.0)
    return np.where(np.isfinite(g) & (g > 0), g, np.nan)


def run_pair(left_path, right_path, calibration_path, out_dir, *, options: StereoOptions | None
             = None, disparity_gt=None, disparity_gt_scale: float | None = None) -> Path:
    """Disparity, depth and points of a user's own pair (see :mod:`reconstruct.calib_io`).

    Writes ``disparity.npy`` (rectified left, NaN = none), ``depth.npy`` (z in the
    rectified left camera), ``points.ply`` (rectified left camera frame),
    ``left_rect.png``/``right_rect.png`` and ``report.json`` (with Middlebury metrics
    when ``disparity_gt`` — a ``.npy``, ``.pfm`` or ``.png`` in the rectified left frame,
    read by :func:`read_disparity` — is given).
    """

    from reconstruct.calib_io import read_stereo_yaml

    opts = options or StereoOptions()
    calib = read_stereo_yaml(calibration_path)
    L = read_image(left_path)
    R = read_image(right_path)
    if L.shape[:2] != R.shape[:2]:
        raise InputError(f"expected the left image's size {L.shape[1]}x{L.shape[0]}, got "
                         f"{R.shape[1]}x{R.shape[0]}", path=right_path)
    if (L.shape[1], L.shape[0]) != calib.image_size:
        raise InputError(f"expected the calibration's image_size {calib.image_size[0]}x"
                         f"{calib.image_size[1]}, got {L.shape[1]}x{L.shape[0]}", path=left_path)
    rect = rectify(calib)
    lo = opts.min_disparity if opts.min_disparity is not None else 0
    num = opts.num_disparities if opts.num_disparities is not None else 128
    t0 = time.perf_counter()
    lr, rr = rectify_pair(to_gray(L), to_gray(R), rect)
    disp = match(lr, rr, opts.match_options(lo, num))
    t = time.perf_counter() - t0
    if not np.isfinite(disp).any():
        raise RuntimeError(f"{left_path}: empty disparity (no match at all)")
    depth = disparity_to_depth(disp, rect)
    cam = rect.left_camera()
    pts, px = depth_to_points(depth, cam)
    report = {"kind": "stereo-pair", "left": str(left_path), "right": str(right_path),
              "calibration": str(calibration_path), "options": asdict(opts),
              "valid_fraction": float(np.isfinite(disp).mean()), "points": len(pts),
              "timings_s": {"rectify_match": t}}
    if disparity_gt is not None:
        gtp = Path(disparity_gt)
        g = read_disparity(gtp, scale=disparity_gt_scale)
        if g.shape != disp.shape:
            raise InputError(f"expected shape {disp.shape}, got {g.shape}", path=gtp)
        try:
            report["disparity_metrics"] = disparity_metrics(disp, g)
        except ValueError as exc:
            raise InputError(str(exc), path=gtp) from None
    out = Path(out_dir)
    with atomic_dir(out) as tmp:
        np.save(tmp / "disparity.npy", disp)
        np.save(tmp / "depth.npy", depth)
        if len(pts):
            write_points(tmp / "points.ply", pts)
        from core.image_io import write_image

        write_image(tmp / "left_rect.png", lr)
        write_image(tmp / "right_rect.png", rr)
        write_json(tmp / "report.json", report)
    return out
