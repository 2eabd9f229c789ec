"""``scanamp calibrate camera IMAGES... --board SPEC --out camera.yaml``: a real camera's
intrinsics from photos of a chessboard or ChArUco board."""

from __future__ import annotations

import argparse

from reconstruct.calibration.images import CameraCalibrationOptions
from scanamp.cli._calibrate_common import add_board_arguments, report_path

GROUP = "calibrate"
NAME = "camera"
OUTPUT = "file"
CONFIG = CameraCalibrationOptions
HELP = "intrinsics and distortion of a real camera from photos of a board"


def companions(args, config=None):
    return [report_path(args.out)]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("images", nargs="+", help="image files, a folder, or a quoted glob")
    add_board_arguments(p, out_name="camera.yaml",
                        out_help="cv2.FileStorage YAML (the keys of OpenCV's calibration "
                                 "sample)")


def run(args: argparse.Namespace, config: CameraCalibrationOptions) -> int:
    import logging

    from acquire.targets import target_from_spec
    from core.files import write_json
    from reconstruct.calibration.images import calibrate_camera_images, sorted_images
    from reconstruct.calibration.io import write_camera_yaml
    from reconstruct.camera_files import colmap_params_from_camera

    log = logging.getLogger("scanamp")
    target = target_from_spec(args.board)
    paths = [p for item in args.images for p in sorted_images(item)]
    cal, report = calibrate_camera_images(paths, target, dist_model=config.dist_model)
    model, params = colmap_params_from_camera(cal.camera, "OPENCV")
    report["colmap_camera"] = f"{model}:{params.replace(' ', '')}"
    write_camera_yaml(args.out, cal.camera, rms=cal.rms)
    write_json(report_path(args.out), report)
    c = cal.camera
    log.info("board found in %d of %d images; RMS reprojection %.3f px",
             len(report["used"]), report["images"], cal.rms)
    log.info("fx %.2f  fy %.2f  cx %.2f  cy %.2f  dist %s", c.fx, c.fy, c.cx, c.cy,
             " ".join(f"{v:.4g}" for v in c.dist))
    log.info("for scanamp reconstruct sfm: --camera %s (or --camera %s)",
             report["colmap_camera"], args.out)
    log.info("wrote %s", args.out)
    return 0
