"""The pair pipeline: a rectified disparity, depth and points from a user's two images and
a ``stereo.yaml`` (see :mod:`reconstruct.calibration.io`), scored against a ground-truth
disparity when one is given."""

from __future__ import annotations

import logging
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from core.files import atomic_dir, json_data, write_json
from core.io.image import read_image
from core.io.mesh import write_points
from core.validate import InputError
from reconstruct.calibration.camera import to_gray
from reconstruct.calibration.rectify import rectify, rectify_pair
from reconstruct.evaluation.disparity import disparity_metrics
from reconstruct.result import ReconstructionResult
from reconstruct.stereo.matching import depth_to_points, disparity_to_depth, match
from reconstruct.stereo.options import StereoOptions

__all__ = ["run_pair", "read_disparity"]

_log = logging.getLogger(__name__)


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
             = None, disparity_gt=None, disparity_gt_scale: float | None = None
             ) -> ReconstructionResult:
    """Disparity, depth and points of a user's own pair (see :mod:`reconstruct.calibration.io`).

    Writes ``disparity.npy`` (rectified left, NaN = none), ``depth.npy`` (z in the
    rectified left camera), ``points.ply`` (rectified left camera frame),
    ``left_rect.png``/``right_rect.png`` and ``report.json`` (with Middlebury metrics
    when ``disparity_gt`` — a ``.npy``, ``.pfm`` or ``.png`` in the rectified left frame,
    read by :func:`read_disparity` — is given).
    """

    from reconstruct.calibration.io import read_stereo_yaml

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
        from core.io.image import write_image

        write_image(tmp / "left_rect.png", lr)
        write_image(tmp / "right_rect.png", rr)
        write_json(tmp / "report.json", report)
    return ReconstructionResult(out, json_data(report))
