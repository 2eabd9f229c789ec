"""``scanamp calibrate stereo --left GLOB --right GLOB --board SPEC --out stereo.yaml``:
a real stereo pair's calibration from photo pairs of a board."""

from __future__ import annotations

import argparse

from reconstruct.calibration.images import StereoCalibrationOptions
from scanamp.cli._calibrate_common import add_board_arguments, report_path

GROUP = "calibrate"
NAME = "stereo"
OUTPUT = "file"
CONFIG = StereoCalibrationOptions
HELP = "calibration of a real stereo pair from photo pairs of a board (writes stereo.yaml)"


def companions(args, config=None):
    return [report_path(args.out)]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--left", required=True, help="left images: a folder or a quoted glob")
    p.add_argument("--right", required=True,
                   help="right images, paired with the left ones in sorted order")
    add_board_arguments(p, out_name="stereo.yaml",
                        out_help="the YAML that scanamp reconstruct stereo --calibration reads")


def run(args: argparse.Namespace, config: StereoCalibrationOptions) -> int:
    import logging

    from acquire.targets import target_from_spec
    from core.files import write_json
    from reconstruct.calibration.images import calibrate_stereo_images, sorted_images
    from reconstruct.calibration.io import write_stereo_yaml

    log = logging.getLogger("scanamp")
    target = target_from_spec(args.board)
    calib, report = calibrate_stereo_images(sorted_images(args.left), sorted_images(args.right),
                                            target, dist_model=config.dist_model)
    write_stereo_yaml(args.out, calib)
    write_json(report_path(args.out), report)
    log.info("board in both images of %d of %d pairs; RMS left %.3f px, right %.3f px, "
             "stereo %.3f px", report["pairs_used"], report["pairs"], report["rms_left_px"],
             report["rms_right_px"], report["rms_stereo_px"])
    log.info("baseline %.4g (board units); epipolar error after rectification: RMS %.3f px, "
             "max %.3f px", report["baseline"], report["epipolar_rms_px"],
             report["epipolar_max_px"])
    log.info("wrote %s", args.out)
    return 0
