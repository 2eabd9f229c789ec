"""Laser-triangulation reconstruction: calibrations, stripes, points, mesh, report.

``run(config, capture_dir, out_dir) -> Path`` reads a laser capture folder (virtual or
real), calibrates the camera, the laser plane and the turntable axis (or stage
direction) from the calibration captures, extracts the stripe of every frame with a
sub-pixel detector, triangulates (undistorted pixel ray meets the laser plane), moves
every frame's points into the object frame, removes outliers, orients normals toward
the sensor, meshes (screened Poisson with density trimming), and writes
``points.ply``, ``mesh.ply`` and ``report.json``. Ground truth, when the capture has
it, is read only afterwards to score the result (:mod:`reconstruct.laser.evaluation`).

Output frame: the turntable frame (origin on the axis level with the camera's optical
axis, z along the axis, x toward the camera); for a stage, the camera frame at reading 0.
"""

from __future__ import annotations

import logging
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from acquire.capture_io import load_capture
from acquire.targets import target_from_dict
from core.config import Config, option
from core.files import atomic_dir, json_data, write_json
from core.frames import rotation_about, transform_points
from core.progress import track
from core.validate import InputError
from reconstruct.calibration.camera import DIST_MODELS, calibrate_camera
from reconstruct.laser.calibration import (
    calibrate_laser_plane,
    calibrate_stage,
    calibrate_turntable_axis,
    intersect_rays_plane,
    pixel_rays,
)
from reconstruct.laser.error_model import (
    PeakErrorAccumulator,
    closed_form_sigma_z,
    depth_sigma,
    estimate_peak_sigma,
)
from reconstruct.laser.stripe import DETECTORS, StripeOptions, detect_peaks
from reconstruct.result import ReconstructionResult
from reconstruct.surface.meshing import MeshingOptions, points_to_mesh

log = logging.getLogger(__name__)

__all__ = ["LaserReconConfig", "run", "extract_frames", "DEFAULT_DETECTOR", "STAGES"]

#: the most accurate detector measured on rendered scans (benchmarks/bench_laser.py)
DEFAULT_DETECTOR = "gaussian"


@dataclass
class LaserReconConfig(Config):
    """Options of the laser reconstruction (``scanamp reconstruct laser``)."""

    detector: str = option(DEFAULT_DETECTOR, choices=DETECTORS,
                           help="sub-pixel stripe peak detector")
    threshold: float = option(8.0, unit="8-bit", range="[0, inf)",
                              help="minimum stripe peak above the row's background")
    min_contrast: float = option(6.0, unit="8-bit", range="(0, inf)",
                                 help="minimum peak contrast against its neighbourhood")
    max_width: float = option(12.0, unit="px", range="(0, inf)",
                              help="widest accepted stripe profile (FWHM)")
    max_steepness: float = option(1.5, range="[0, inf)",
                                  help="profile-steepness test: flanks steeper than a "
                                       "Gaussian of the measured width by this factor are "
                                       "rejected as lit plateaus or edges (0 = off)")
    dist_model: str = option("k1k2", choices=DIST_MODELS,
                             help="lens distortion estimated by the camera calibration")
    meshing: MeshingOptions = option(
        default_factory=lambda: MeshingOptions(depth=9, density_quantile=0.03,
                                               trim_distance=0.002),
        help="Poisson depth, density trimming, outliers")
    max_range: float = option(0.0, unit="m", range="[0, inf)",
                              help="drop points farther than this from the axis (0 = off)")
    speckle: float = option(0.0, range="[0, 2]",
                            help="the laser's speckle contrast as known on the bench (feeds "
                                 "the error model only)")
    speckle_grain: float = option(0.0, unit="px", range="[0, inf)",
                                  help="speckle grain on the sensor, 2.44 x wavelength x "
                                       "f-number / pixel pitch (error model only; 0: "
                                       "independent pixels)")
    max_camera_rms_px: float = option(1.0, unit="px", range="(0, inf)",
                                      help="sanity limit of the camera calibration RMS")
    max_plane_rms_m: float = option(0.5e-3, unit="m", range="(0, inf)",
                                    help="sanity limit of the laser-plane fit RMS")
    max_axis_rms_px: float = option(2.0, unit="px", range="(0, inf)",
                                    help="sanity limit of the turntable-axis fit RMS")
    min_stripe_fraction: float = option(0.2, range="[0, 1]",
                                        help="frames whose stripe has fewer points than "
                                             "this fraction of the median frame are named "
                                             "in the report's warnings")
    evaluate: bool = option(True, help="score against the capture's ground truth when "
                                       "present")
    tau: float = option(0.0005, unit="m", range="(0, inf)", help="F-score threshold")
    calibration_draws: int = option(32, range="[0, 10000]",
                                    help="Monte Carlo recalibrations propagating the camera "
                                         "intrinsics' uncertainty into depth (0 = off)")
    seed: int = option(0, range="[0, inf)", help="seeds those draws (same seed, same report)")

    def stripe_options(self, bit_depth: int = 8) -> StripeOptions:
        k = 1.0 if bit_depth == 8 else 257.0
        return StripeOptions(method=self.detector, threshold=self.threshold * k,
                             min_contrast=self.min_contrast * k, max_width=self.max_width,
                             max_steepness=self.max_steepness, saturation=255.0 * k)


def _read(path: Path, channel: int | None = None) -> np.ndarray:
    """One frame, upright (core.io.image), as grey or one colour channel (0 = red)."""
    import cv2

    from core.io.image import read_image

    img = read_image(path)
    if img.ndim == 3:
        img = img[:, :, channel] if channel is not None else cv2.cvtColor(
            np.ascontiguousarray(img[:, :, :3]), cv2.COLOR_RGB2GRAY)
    return img


def extract_frames(images, options: StripeOptions):
    """Stripe columns ``(f, h)`` (NaN = none) and saturated-peak counts ``(f,)``."""
    cols, sat = [], []
    for img in images:
        c, _ = detect_peaks(img, options=options)
        r = np.flatnonzero(np.isfinite(c))
        ci = np.clip(np.round(c[r]).astype(int), 0, img.shape[1] - 1)
        sat.append(int(np.count_nonzero(img[r, ci] >= options.saturation)))
        cols.append(c)
    return np.stack(cols), np.asarray(sat)


#: the named stages of :func:`run`, in order (``scanamp reconstruct laser --from STAGE``)
STAGES = ("calibrate", "extract", "triangulate", "mesh", "evaluate")
_STRIPE_FIELDS = ("detector", "threshold", "min_contrast", "max_width", "max_steepness")


def run(config: LaserReconConfig, capture_dir, out_dir, *,
        from_stage: str | None = None) -> ReconstructionResult:
    """Reconstruct a laser capture into ``out_dir`` (see the module docstring); the folder
    and its report.

    The work is five named stages (:data:`STAGES`), each cached in ``out_dir/stages``
    (:class:`core.runs.stages.Stages`): run again into the same folder, only the stages whose
    options or inputs changed are recomputed (a new Poisson depth re-runs ``mesh`` and
    ``evaluate``, not the calibrations). ``from_stage`` forces a stage and the later ones.
    """
    from core.io.mesh import write_mesh, write_points
    from core.runs.stages import Stages, files_key

    cfg = config
    t_all = time.perf_counter()
    cap = load_capture(capture_dir)
    prep = _prepare(cap)
    out_dir = Path(out_dir)
    opts = {k: v for k, v in asdict(cfg).items() if k != "meshing"}
    stripe_opts = {k: opts[k] for k in _STRIPE_FIELDS}
    with atomic_dir(out_dir) as tmp:
        st = Stages(tmp, STAGES, from_stage=from_stage,
                    reuse=out_dir if out_dir.is_dir() else None)
        inputs = files_key([cap.root / "capture.json"])
        calib = st.run("calibrate", _calibrate, cap, prep, cfg, depends={
            "capture": inputs, "dist_model": cfg.dist_model, "stripe": stripe_opts,
            "limits": [cfg.max_camera_rms_px, cfg.max_plane_rms_m, cfg.max_axis_rms_px]})
        stripes = st.run("extract", _extract, cap, prep, cfg, depends={
            "capture": inputs, "stripe": stripe_opts, "speckle": cfg.speckle,
            "speckle_grain": cfg.speckle_grain,
            "min_stripe_fraction": cfg.min_stripe_fraction})
        tri = st.run("triangulate", _triangulate, cap, prep, calib, stripes, cfg,
                     depends={"max_range": cfg.max_range})
        m = _with_mesh(st.run("mesh", _mesh, tri["P"], tri["V"], cfg.meshing,
                              depends={"meshing": asdict(cfg.meshing)}))
        report = st.run("evaluate", _report, cap, prep, calib, stripes, tri, m, cfg,
                        depends={k: opts[k] for k in ("calibration_draws", "seed", "evaluate",
                                                      "tau")})
        report = {**report, "stages": {"ran": st.ran, "reused": st.skipped}}
        report["timings"] = {**report["timings"], "total_s": time.perf_counter() - t_all}
        write_points(tmp / "points.ply", m["points"], normals=m["normals"])
        write_mesh(tmp / "mesh.ply", m["mesh"])
        for w in report["warnings"]:
            log.warning("%s", w)
        write_json(tmp / "report.json", report)
    return ReconstructionResult(out_dir, json_data(report))


def _prepare(cap) -> dict:
    """The capture's motion, stage readings, channels and calibration entries, checked."""
    jpath = cap.root / "capture.json"
    if cap.kind != "laser":
        raise InputError(f"expected a laser capture, got kind {cap.kind!r}", path=jpath,
                         field="kind")
    frames = cap.frames
    if not frames:
        raise InputError("no frames", path=jpath, field="frames")
    rig = cap.rig
    motion = rig.get("motion")
    if motion not in ("turntable", "stage"):
        raise InputError(f"expected 'turntable' or 'stage', got {motion!r}", path=jpath,
                         field="rig.motion")
    key = "angle_deg" if motion == "turntable" else "position_m"
    readings = []
    for i, fr in enumerate(frames):
        if not isinstance(fr.get(key), (int, float)):
            raise InputError(f"expected the stage reading {key!r}", path=jpath,
                             field=f"frames[{i}].{key}")
        readings.append(float(fr[key]))
    calib = {c["kind"]: (i, c) for i, c in enumerate(cap.calibration)}
    for need in ("camera", "laser_plane", "axis" if motion == "turntable" else "stage"):
        if need not in calib:
            raise InputError(f"missing a {need!r} calibration capture", path=jpath,
                             field="calibration")
    return {"jpath": jpath, "frames": frames, "motion": motion,
            "readings": np.asarray(readings), "channel": rig.get("laser_channel", 0),
            "bit_depth": int(rig.get("bit_depth", 8)), "calib": calib}


def _calibrate(cap, prep, cfg) -> dict:
    """Stage ``calibrate``: the camera, the laser plane, the turntable axis (or stage)."""
    jpath, calib, warnings, timings = prep["jpath"], prep["calib"], [], {}
    t = time.perf_counter()
    ci, cc = calib["camera"]
    cam_cal = calibrate_camera([_read(cap.path(p)) for p in cc["images"]], _target(cc, jpath, ci),
                               dist_model=cfg.dist_model, names=cc["images"])
    cam = cam_cal.camera
    _check_calibration("camera calibration", cam_cal.rms, cfg.max_camera_rms_px, "px",
                       cam_cal.per_view_errors, [cc["images"][i] for i in cam_cal.used_views],
                       warnings)
    if cam_cal.rejected_views:
        warnings.append("camera calibration: target not detected in "
                        + ", ".join(cc["images"][i] for i in cam_cal.rejected_views))
    timings["camera_calibration_s"] = time.perf_counter() - t
    t = time.perf_counter()
    plane_cal = _calibrate_plane(cap, prep, cam, cfg, warnings)
    timings["laser_calibration_s"] = time.perf_counter() - t
    t = time.perf_counter()
    motion = prep["motion"]
    ai, ac = calib["axis" if motion == "turntable" else "stage"]
    fit = calibrate_turntable_axis if motion == "turntable" else calibrate_stage
    axis_cal = fit(cam, [_read(cap.path(p)) for p in ac["images"]],
                   _readings(ac, "angles_deg" if motion == "turntable" else "positions_m",
                             jpath, ai), _target(ac, jpath, ai), names=ac["images"])
    what = "axis" if motion == "turntable" else "stage"
    _check_calibration(f"{what} calibration", axis_cal.rms_px, cfg.max_axis_rms_px, "px",
                       None, None, warnings)
    if axis_cal.rejected_views:
        warnings.append(f"{what} calibration: target not detected in "
                        + ", ".join(ac["images"][i] for i in axis_cal.rejected_views))
    timings["axis_calibration_s"] = time.perf_counter() - t
    return {"camera": cam_cal, "plane": plane_cal, "axis": axis_cal,
            "object_from_camera": _object_frame(axis_cal, motion, cam),
            "warnings": warnings, "timings": timings}


def _calibrate_plane(cap, prep, cam, cfg, warnings):
    jpath = prep["jpath"]
    li, lc = prep["calib"]["laser_plane"]
    roles = lc.get("image_roles", ["laser_off", "laser_on"])
    off_i, on_i = roles.index("laser_off"), roles.index("laser_on")
    pairs, pnames = [], []
    for j, pair in enumerate(lc["images"]):
        if not isinstance(pair, list) or len(pair) != 2:
            raise InputError("expected [laser_off, laser_on] image pairs", path=jpath,
                             field=f"calibration[{li}].images[{j}]")
        pairs.append((_read(cap.path(pair[off_i])),
                      _read(cap.path(pair[on_i]), prep["channel"])))
        pnames.append(pair[on_i])
    plane_cal = calibrate_laser_plane(cam, pairs, _target(lc, jpath, li),
                                      stripe=cfg.stripe_options(prep["bit_depth"]),
                                      names=pnames)
    plane = plane_cal.plane
    _check_calibration("laser-plane calibration", plane_cal.rms, cfg.max_plane_rms_m, "m",
                       np.asarray(plane_cal.per_view_rms),
                       [pnames[i] for i in plane_cal.used_views], warnings)
    if plane_cal.rejected_views:
        warnings.append("laser-plane calibration: board or stripe not found in "
                        + ", ".join(pnames[i] for i in plane_cal.rejected_views))
    angle = np.degrees(np.arcsin(min(abs(plane[2]), 1.0)))  # optical axis vs the plane
    if angle < 3.0:
        raise RuntimeError(f"laser-plane calibration: the fitted plane is {angle:.1f} deg from "
                           "the camera's optical axis (it nearly contains the camera): no "
                           "triangulation is possible; check the laser-plane captures "
                           + ", ".join(pnames))
    return plane_cal


def _extract(cap, prep, cfg) -> dict:
    """Stage ``extract``: the sub-pixel stripe of every frame, and the peak error model."""
    t = time.perf_counter()
    frames, jpath = prep["frames"], prep["jpath"]
    sopt = cfg.stripe_options(prep["bit_depth"])
    peak_model = PeakErrorAccumulator(cap.data.get("sensor") or _DEFAULT_SENSOR, sopt,
                                      speckle=cfg.speckle, speckle_grain=cfg.speckle_grain)
    cols, n_sat, size = None, np.zeros(len(frames), int), None
    for k, fr in enumerate(track(frames, "stripe extraction")):
        img = _read(cap.path(fr["image"]), prep["channel"])
        if size is None:
            size = img.shape[:2]
            cols = np.full((len(frames), size[0]), np.nan)
        if img.shape[:2] != size:
            raise InputError(f"image is {img.shape[1]}x{img.shape[0]}, the first frame is "
                             f"{size[1]}x{size[0]}", path=jpath, field=f"frames[{k}].image")
        c, s = extract_frames([img], sopt)
        cols[k], n_sat[k] = c[0], s[0]
        peak_model.add(img, cols[k])
    timings = {"stripe_extraction_s": time.perf_counter() - t}
    return {"cols": cols, "n_sat": n_sat, "size": size, "peak_model": peak_model,
            "warnings": _stripe_warnings(frames, cols, n_sat, cfg.min_stripe_fraction),
            "timings": timings}


def _stripe_warnings(frames, cols, n_sat, min_fraction) -> list[str]:
    per_frame = np.count_nonzero(np.isfinite(cols), axis=1)
    empty = [frames[k]["image"] for k in np.flatnonzero(per_frame == 0)]
    if len(empty) == len(frames):
        raise RuntimeError("no laser stripe found in any frame (laser off, too dark, or "
                           "thresholds too high)")
    warnings = []
    if empty:
        warnings.append(f"no stripe in {len(empty)} frames: " + ", ".join(empty[:20])
                        + (" ..." if len(empty) > 20 else ""))
    med = float(np.median(per_frame))
    sparse = [frames[k]["image"] for k in np.flatnonzero(
        (per_frame > 0) & (per_frame < min_fraction * med))]
    if sparse:
        warnings.append(f"stripe covers fewer than {min_fraction:.0%} of the median "
                        f"frame's {med:.0f} rows in {len(sparse)} frames: "
                        + ", ".join(sparse[:20]) + (" ..." if len(sparse) > 20 else ""))
    saturated = [frames[k]["image"] for k in np.flatnonzero(n_sat > 0.5 * np.maximum(
        per_frame, 1)) if per_frame[k] > 0]
    if saturated:
        warnings.append(f"stripe saturated in {len(saturated)} frames (peaks located by "
                        "their half-level midpoint): " + ", ".join(saturated[:20]))
    return warnings


def _triangulate(cap, prep, calib, stripes, cfg) -> dict:
    """Stage ``triangulate``: pixel rays meet the laser plane; every frame's points move into
    the object frame."""
    t = time.perf_counter()
    cam, plane, axis_cal = calib["camera"].camera, calib["plane"].plane, calib["axis"]
    cols = stripes["cols"]
    if tuple(stripes["size"]) != (cam.height, cam.width):
        raise InputError(f"the frames are {stripes['size'][1]}x{stripes['size'][0]}, the "
                         f"calibration images {cam.width}x{cam.height}", path=prep["jpath"],
                         field="frames")
    kk, rr = np.nonzero(np.isfinite(cols))
    uu = cols[kk, rr]
    sp = stripes["peak_model"].sigma_peak()[0][kk, rr]
    px = np.stack([uu, rr.astype(float)], axis=1)
    pc = intersect_rays_plane(pixel_rays(cam, px), plane)
    good = np.all(np.isfinite(pc), axis=1) & (pc[:, 2] > 0)
    if good.mean() < 0.5:
        raise RuntimeError(f"triangulation: {np.count_nonzero(~good)} of {len(good)} stripe "
                           "points fall behind the camera or parallel to the laser plane: the "
                           "laser-plane calibration does not match the scan")
    kk, rr, uu, px, pc, sp = kk[good], rr[good], uu[good], px[good], pc[good], sp[good]
    obj_from_cam, readings = calib["object_from_camera"], prep["readings"]
    P, V = np.empty_like(pc), np.empty_like(pc)
    for k in np.unique(kk):
        sel = kk == k
        if prep["motion"] == "turntable":
            M = rotation_about(axis_cal.direction, -np.radians(readings[k]), axis_cal.point)
        else:
            M = np.eye(4)
            M[:3, 3] = -readings[k] * axis_cal.scale * axis_cal.direction
        T = obj_from_cam @ M
        P[sel] = transform_points(T, pc[sel])
        V[sel] = T[:3, 3]  # the camera centre seen from the object at that reading
    if cfg.max_range > 0 and prep["motion"] == "turntable":
        keep = np.linalg.norm(P[:, :2], axis=1) < cfg.max_range
        P, V, kk, rr, uu, px, pc, sp = (a[keep] for a in (P, V, kk, rr, uu, px, pc, sp))
    return {"P": P, "V": V, "kk": kk, "rr": rr, "uu": uu, "px": px, "pc": pc, "sp": sp,
            "timings": {"triangulation_s": time.perf_counter() - t}}


def _mesh(points, viewpoints, meshing) -> dict:
    """Stage ``mesh``: outliers, normals toward the sensor, screened Poisson, trimming. The
    mesh is stored as arrays (Open3D meshes do not pickle)."""
    m = points_to_mesh(points, viewpoints, meshing)
    mesh = m.pop("mesh")
    m["mesh_arrays"] = {
        "vertices": np.asarray(mesh.vertices).copy(),
        "triangles": np.asarray(mesh.triangles).copy(),
        "vertex_normals": np.asarray(mesh.vertex_normals).copy()
        if mesh.has_vertex_normals() else None,
        "vertex_colors": np.asarray(mesh.vertex_colors).copy()
        if mesh.has_vertex_colors() else None}
    return m


def _with_mesh(m: dict) -> dict:
    """The stage's arrays as a mesh, in the canonical order (:func:`core.meshes.sorted_mesh`)
    that the report's samples and the written bytes then follow."""
    from core.meshes import make_mesh, sorted_mesh

    a = m["mesh_arrays"]
    mesh = make_mesh(a["vertices"], a["triangles"], vertex_normals=a["vertex_normals"],
                     vertex_colors=a["vertex_colors"], compute_normals=False)
    return {**m, "mesh": sorted_mesh(mesh, recompute_normals=True)}


def _report(cap, prep, calib, stripes, tri, m, cfg) -> dict:
    """Stage ``evaluate``: the error model and, with ground truth, the scores."""
    cam_cal, plane_cal, axis_cal = calib["camera"], calib["plane"], calib["axis"]
    cam, plane, mesh = cam_cal.camera, plane_cal.plane, m["mesh"]
    pc, px, sp = tri["pc"], tri["px"], tri["sp"]
    timings = {**calib["timings"], **stripes["timings"], **tri["timings"]}
    _, sig_noise, sig_tex = stripes["peak_model"].sigma_peak()
    sigma_peak_jitter = estimate_peak_sigma(stripes["cols"])
    sp = np.where(np.isfinite(sp), sp, np.nanmedian(sp) if np.isfinite(sp).any() else 0.0)
    sigma_peak = float(np.sqrt(np.mean(sp ** 2))) if len(sp) else float("nan")
    sz_peak = depth_sigma(cam, plane, px, sp)
    sz_plane = _plane_depth_sigma(cam, plane_cal, px)
    t = time.perf_counter()
    sz_intr = _intrinsics_depth_sigma(cam_cal, plane_cal, px, cfg.calibration_draws,
                                      np.random.default_rng(cfg.seed))
    timings["calibration_propagation_s"] = time.perf_counter() - t
    sz_cal = np.sqrt(sz_plane ** 2 + sz_intr ** 2)
    sz = np.sqrt(sz_peak ** 2 + sz_cal ** 2)
    tri_angle = _triangulation_angle(plane, pc)
    fin = np.isfinite(sig_noise)
    per_frame = np.count_nonzero(np.isfinite(stripes["cols"]), axis=1)
    motion = prep["motion"]
    report = {
        "kind": "laser",
        "capture": str(cap.root),
        "config": {**asdict(cfg), "meshing": asdict(cfg.meshing)},
        "counts": {"frames": len(prep["frames"]),
                   "frames_with_stripe": int(np.count_nonzero(per_frame)),
                   "stripe_points": int(len(tri["P"])),
                   "points_after_outliers": int(len(m["kept"])),
                   "mesh_vertices": len(mesh.vertices), "mesh_triangles": len(mesh.triangles)},
        "calibration": {"camera": cam_cal.to_dict(), "laser_plane": plane_cal.to_dict(),
                        motion if motion == "stage" else "axis": axis_cal.to_dict(),
                        "object_from_camera": calib["object_from_camera"].tolist()},
        "error_model": {
            "sigma_peak_px": sigma_peak,
            "sigma_peak_noise_px": float(np.sqrt(np.mean(sig_noise[fin] ** 2)))
            if fin.any() else None,
            "sigma_peak_texture_px": float(np.sqrt(np.mean(sig_tex[fin] ** 2)))
            if fin.any() else None,
            "log_albedo_gradient_sigma_per_px": stripes["peak_model"].sigma_g,
            "sigma_peak_jitter_px": sigma_peak_jitter,
            "sigma_z_peak_pred_rms_m": float(np.sqrt(np.mean(sz_peak ** 2))) if len(sz) else None,
            "sigma_z_plane_pred_rms_m": _rms(sz_plane),
            "sigma_z_intrinsics_pred_rms_m": _rms(sz_intr),
            "calibration_draws": cfg.calibration_draws,
            "sigma_z_calibration_pred_rms_m": float(np.sqrt(np.mean(sz_cal ** 2)))
            if len(sz) else None,
            "sigma_z_pred_rms_m": float(np.sqrt(np.mean(sz ** 2))) if len(sz) else None,
            "sigma_z_closed_form_m": closed_form_sigma_z(
                sigma_peak, float(np.median(pc[:, 2])), cam.fx, tri_angle)
            if len(pc) else None,
            "triangulation_angle_deg": float(np.degrees(tri_angle)),
            "median_depth_m": float(np.median(pc[:, 2])) if len(pc) else None,
        },
        "warnings": calib["warnings"] + stripes["warnings"],
        "timings": timings,
    }
    if cfg.evaluate and cap.ground_truth:
        from reconstruct.laser.evaluation import evaluate_laser

        t = time.perf_counter()
        report["evaluation"] = evaluate_laser(
            cap, cam_cal, plane, axis_cal, calib["object_from_camera"], mesh,
            {"frame": tri["kk"], "row": tri["rr"], "col": tri["uu"], "points_cam": pc,
             "sigma_z": sz, "sigma_z_peak": sz_peak, "sigma_z_plane": sz_plane,
             "sigma_z_intrinsics": sz_intr},
            tau=cfg.tau)
        report["timings"]["evaluation_s"] = time.perf_counter() - t
    return report


_DEFAULT_SENSOR = {"gain": 1.0, "full_well": 20000.0, "read_noise": 2.0, "bit_depth": 8,
                   "shot_noise": True}


def _check_calibration(what, rms, limit, unit, per_view, names, warnings):
    """RuntimeError when a calibration's RMS residual exceeds ``limit``; a warning naming
    the views whose own residual is over three times the median view's."""
    if not np.isfinite(rms) or rms > limit:
        raise RuntimeError(f"{what}: RMS residual {rms:.4g} {unit} exceeds the sanity limit "
                           f"{limit:g} {unit}; the calibration captures do not fit one model "
                           "(wrong target, moved rig, or a stripe off the target)")
    if per_view is not None and len(per_view) >= 3:
        pv = np.asarray(per_view, float)
        bad = np.flatnonzero(pv > 3 * np.median(pv) + 1e-12)
        if bad.size:
            warnings.append(f"{what}: large residual in " + ", ".join(
                f"{names[i]} ({pv[i]:.3g} {unit})" for i in bad))


def _plane_depth_sigma(cam, plane_cal, px) -> np.ndarray:
    """Jackknife standard deviation of each point's depth over the leave-one-pose-out
    laser planes (the plane's calibration uncertainty); zeros with fewer than 3 poses."""
    J = plane_cal.jackknife
    if J is None or len(J) < 3 or len(px) == 0:
        return np.zeros(len(px))
    rays = pixel_rays(cam, px)
    z = np.stack([intersect_rays_plane(rays, pl)[:, 2] for pl in J])
    k = len(J)
    return np.sqrt((k - 1) / k * np.sum((z - z.mean(axis=0)) ** 2, axis=0))


def _rms(a: np.ndarray) -> float | None:
    return float(np.sqrt(np.mean(a ** 2))) if len(a) else None


def _intrinsics_depth_sigma(cam_cal, plane_cal, px, draws: int,
                            rng: np.random.Generator) -> np.ndarray:
    """Standard deviation of each point's depth ``(n,)`` over cameras recalibrated with
    fresh corner noise (:func:`reconstruct.calibration.camera.bootstrap_cameras`), each
    with the laser plane refitted under it and the stripe pixels ``px (n, 2)``
    re-triangulated: the camera intrinsics' uncertainty carried through the whole chain
    (an offset principal point moves the board poses, hence the plane, and the rays
    together). Zeros when ``draws`` is 0."""
    from reconstruct.calibration.camera import bootstrap_cameras
    from reconstruct.laser.calibration import refit_laser_plane

    if draws == 0 or len(px) == 0 or not plane_cal.observations:
        return np.zeros(len(px))
    z = []
    for c in bootstrap_cameras(cam_cal, rng, draws=draws):
        z.append(intersect_rays_plane(pixel_rays(c, px), refit_laser_plane(c, plane_cal))[:, 2])
    z = np.stack(z)
    return np.nanstd(z, axis=0, ddof=1) if draws > 1 else np.zeros(len(px))


def _target(entry, jpath, i):
    try:
        return target_from_dict(entry["target"])
    except (KeyError, ValueError, TypeError) as exc:
        raise InputError(f"bad target: {exc}", path=jpath, field=f"calibration[{i}].target"
                         ) from None


def _readings(entry, key, jpath, i):
    v = entry.get(key)
    if not isinstance(v, list) or len(v) != len(entry["images"]):
        raise InputError(f"expected one reading per image ({len(entry['images'])})",
                         path=jpath, field=f"calibration[{i}].{key}")
    return v


def _object_frame(axis_cal, motion, cam) -> np.ndarray:
    """``object_from_cam``: turntable frame (z = axis, origin on it, x toward the camera)."""
    if motion != "turntable":
        return np.eye(4)
    a = axis_cal.direction
    up = -np.array([0.0, 1.0, 0.0])  # image up
    if a @ up < 0:
        a = -a  # keep z up; the rotation sense is handled with the signed direction
    p = axis_cal.point
    # origin: the axis point nearest the camera's optical axis
    w0 = p
    b = a @ np.array([0, 0, 1.0])
    d = a @ w0
    e = np.array([0, 0, 1.0]) @ w0
    den = 1 - b * b
    s = (b * e - d) / den if den > 1e-9 else 0.0
    o = p + s * a
    x = -o - ((-o) @ a) * a  # toward the camera centre (the origin of the camera frame)
    x /= np.linalg.norm(x)
    y = np.cross(a, x)
    R = np.stack([x, y, a])  # rows: object axes in camera coordinates
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = -R @ o
    return T


def _triangulation_angle(plane, points_cam) -> float:
    """Median angle between the camera's rays and the laser plane (radians)."""
    if len(points_cam) == 0:
        return float("nan")
    d = points_cam / np.linalg.norm(points_cam, axis=1, keepdims=True)
    return float(np.median(np.arcsin(np.clip(np.abs(d @ plane[:3]), 0, 1))))
