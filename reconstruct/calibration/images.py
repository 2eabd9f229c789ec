"""Calibration from a user's own photos of a board: one camera, or a stereo pair.

The real-capture entry to the project's calibration: image files in, a calibration and
a report out, which :mod:`reconstruct.calibration.io` writes as the YAML that
``scanamp reconstruct stereo --calibration`` and ``scanamp reconstruct sfm --camera``
take. Detection, Zhang's method and ``cv2.stereoCalibrate`` are the ones the virtual
captures use (:mod:`reconstruct.calibration.camera`, :mod:`reconstruct.calibration.stereo`).

The stereo report also measures the rectification on the board corners themselves:
after rectifying with the calibration, a corner seen by both cameras must fall on the
same row, so the row difference of the corners (``epipolar_rms_px``) is the pair's
epipolar error, the number that decides whether SGBM can match along rows.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from core.config import Config, option
from core.io.image import read_image
from core.validate import InputError
from reconstruct.calibration.camera import DIST_MODELS, CameraCalibration, calibrate_camera, to_gray
from reconstruct.calibration.rectify import Rectification, StereoCalibration, rectify
from reconstruct.calibration.stereo import calibrate_pair, detect_pair_views

log = logging.getLogger(__name__)

__all__ = ["calibrate_camera_images", "calibrate_stereo_images", "epipolar_errors",
           "sorted_images"]


def _gray(path: Path) -> np.ndarray:
    return to_gray(read_image(path))


def _names(paths) -> list[str]:
    return [Path(p).name for p in paths]


@dataclass
class CameraCalibrationOptions(Config):
    """Options of ``scanamp calibrate camera``."""

    dist_model: str = option("k1k2p1p2", choices=DIST_MODELS,
                             help="distortion terms estimated (k1k2: radial only; k1k2p1p2: "
                                  "radial + tangential; full: + k3)")


@dataclass
class StereoCalibrationOptions(Config):
    """Options of ``scanamp calibrate stereo`` (radial only: a pair has fewer views to
    spend on each camera's distortion)."""

    dist_model: str = option("k1k2", choices=DIST_MODELS,
                             help="distortion terms estimated (k1k2: radial only; k1k2p1p2: "
                                  "radial + tangential; full: + k3)")


def calibrate_camera_images(paths, target, *,
                            dist_model: str = CameraCalibrationOptions.dist_model,
                            min_views: int = 3) -> tuple[CameraCalibration, dict]:
    """Calibrate one camera from image files of ``target``.

    Returns the calibration and a report: ``rms_px``, each used image's RMS, the images
    where the board was not found, and OpenCV's standard deviations of the intrinsics.
    InputError (naming the file) for an unreadable image or one of another size.
    """
    paths = [Path(p) for p in paths]
    if not paths:
        raise InputError("no images given")
    images, size = [], None
    for p in paths:
        img = _gray(p)
        if size is not None and img.shape != size:
            raise InputError(f"image size {img.shape[1]}x{img.shape[0]} differs from the first "
                             f"image's {size[1]}x{size[0]}", path=p)
        size = img.shape
        images.append(img)
    names = _names(paths)
    try:
        cal = calibrate_camera(images, target, dist_model=dist_model, min_views=min_views,
                               names=names)
    except RuntimeError as exc:
        raise InputError(f"{exc}{_board_hint(target)}", path=paths[0].parent) from None
    report = {
        "images": len(paths), "used": [names[i] for i in cal.used_views],
        "undetected": [names[i] for i in cal.rejected_views],
        "rms_px": float(cal.rms),
        "per_view_rms_px": {names[i]: float(e) for i, e in zip(cal.used_views,
                                                               cal.per_view_errors, strict=True)},
        "std_intrinsics": dict(zip(("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"),
                                   map(float, cal.std_intrinsics[:9]), strict=True)),
        "dist_model": dist_model,
    }
    return cal, report


def _board_hint(target) -> str:
    if getattr(target, "cols", None) is not None:
        return (f" (a chessboard is counted in squares: {target.cols}x{target.rows} squares "
                f"have {target.cols - 1}x{target.rows - 1} inner corners)")
    return ""


def calibrate_stereo_images(left_paths, right_paths, target, *,
                            dist_model: str = StereoCalibrationOptions.dist_model,
                            ) -> tuple[StereoCalibration, dict]:
    """Calibrate a stereo pair from image files of ``target``, paired in order.

    Returns the calibration (``T`` in the unit of the board's square length) and a
    report: per-camera and stereo RMS, the images where the board was not found, the
    baseline, and the epipolar error after rectification (:func:`epipolar_errors`).
    """
    left = [Path(p) for p in left_paths]
    right = [Path(p) for p in right_paths]
    if len(left) != len(right):
        raise InputError(f"{len(left)} left images but {len(right)} right images (they are "
                         "paired in sorted order)", path=(right or left or [Path(".")])[0].parent)
    if len(left) < 3:
        raise InputError(f"expected at least 3 image pairs, got {len(left)}",
                         path=(left or [Path(".")])[0].parent)
    views = detect_pair_views(target, ((lp, _gray(lp), rp, _gray(rp))
                                       for lp, rp in zip(left, right, strict=True)))
    missed = [Path(m).name for m in views.missed]
    if missed:
        log.warning("board not detected in %d of %d images: %s", len(missed), 2 * len(left),
                    ", ".join(missed[:6]) + (" ..." if len(missed) > 6 else ""))
    if len(views.common) < 3:
        raise InputError(f"board detected in both images of only {len(views.common)} pairs "
                         f"(need 3){_board_hint(target)}", path=left[0].parent)
    calib, rep = calibrate_pair(views.obj1, views.img1, views.obj2, views.img2, views.common,
                                views.image_size, dist_model=dist_model)
    rect = rectify(calib)
    epi = epipolar_errors(rect, views.common)
    report = {
        "pairs": len(left), "pairs_used": len(views.common), "undetected": missed,
        "rms_left_px": float(rep["rms_1"]), "rms_right_px": float(rep["rms_2"]),
        "rms_stereo_px": float(rep["rms_stereo"]),
        "baseline": float(np.linalg.norm(calib.T)),
        "epipolar_rms_px": float(np.sqrt(np.mean(epi ** 2))),
        "epipolar_max_px": float(np.max(np.abs(epi))),
        "rectified_focal_px": rect.focal, "dist_model": dist_model,
    }
    return calib, report


def epipolar_errors(rect: Rectification, common) -> np.ndarray:
    """Row differences (pixels) of corners seen by both cameras, after rectification.

    ``common`` holds ``(object, left_pixels, right_pixels)`` per view, as in
    :class:`reconstruct.calibration.stereo.PairViews`. 0 for a perfect calibration.
    """
    import cv2

    c = rect.calibration
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10)

    def rectified(px, K, D, R, P):
        return cv2.undistortPointsIter(np.asarray(px, np.float64).reshape(-1, 1, 2), K, D, R, P,
                                       crit).reshape(-1, 2)

    out = []
    for _, pl, pr in common:
        ql = rectified(pl, c.K1, c.D1, rect.R1, rect.P1)
        qr = rectified(pr, c.K2, c.D2, rect.R2, rect.P2)
        out.append(ql[:, 1] - qr[:, 1])
    return np.concatenate(out) if out else np.zeros(0)


def sorted_images(pattern_or_dir: str | os.PathLike) -> list[Path]:
    """The image files a glob pattern or a folder names, sorted by name."""
    import glob

    p = Path(pattern_or_dir)
    exts = {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp"}
    if p.is_dir():
        files = [f for f in p.iterdir() if f.suffix.lower() in exts]
        if not files:
            raise InputError(f"holds no image file ({', '.join(sorted(exts))})", path=p)
    else:
        files = [Path(f) for f in glob.glob(str(pattern_or_dir))]
        if not files:
            raise InputError("matches no image file", path=p)
    return sorted(files)
